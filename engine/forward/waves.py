"""Guided-wave group velocities predicted by the SAFE model of the laminate.

* :func:`wave_block` -- the group-velocity :class:`~engine.fit.DataBlock` of
  the estimators (Jacobian by forward differences in the estimator).
* :class:`SafeWaves` -- group and phase velocities of one laminate for given
  constants and a relative thickness error, memoised per input (the gap's
  forward model evaluates the same points many times).

Units SI: Hz, m/s, Pa.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..fit import DataBlock
from ..laminate import Laminate
from ..safe import dispersion, group_velocity as safe_group_velocity
from .memo import method_lru

__all__ = ["wave_block", "SafeWaves"]


def wave_block(laminate: Laminate, frequency_hz, group_velocity_m_s, sigma_m_s, *,
               mode: str = "A0", direction_deg: float = 0.0, material: str | None = None,
               name: str | None = None, group_velocity=None) -> DataBlock:
    """Group-velocity data block (m/s) predicted by the SAFE model of ``laminate``.

    ``group_velocity`` defaults to ``engine.safe.group_velocity``.
    """
    if group_velocity is None:
        group_velocity = safe_group_velocity
    f = np.asarray(frequency_hz, float)

    def predict(params: Mapping[str, float]) -> np.ndarray:
        lam = laminate.with_params(dict(params), material) if params else laminate
        for m in lam.materials.values():
            m.check()
        return np.asarray(group_velocity(lam, f, mode=mode, direction_deg=direction_deg), float)

    return DataBlock(name or f"waves:{mode}@{direction_deg:g}deg", group_velocity_m_s, sigma_m_s,
                     predict, None, kind="waves")


class SafeWaves:
    """Velocities of the wave modes of ``laminate`` (constants of ``material``) at
    constants ``params`` and relative thickness error ``thickness``.

    ``order`` is passed to the SAFE solver (None: its default). Results are
    memoised per exact input (``functools.lru_cache``).
    """

    def __init__(self, laminate: Laminate, material: str | None = None, order: int | None = None):
        self.laminate, self.material, self.order = laminate, material, order
        self._cg = method_lru(self._group_velocity, 256)
        self._cp = method_lru(self._phase_velocity, 64)

    def laminate_at(self, params: Mapping[str, float], thickness: float) -> Laminate:
        """The laminate with constants ``params`` (checked) and thickness scaled by 1 + ``thickness``."""
        lam = self.laminate.with_params(dict(params), self.material)
        for m in lam.materials.values():
            m.check()
        return lam.scaled_thickness(1.0 + thickness) if thickness else lam

    def group_velocity(self, params: Mapping[str, float], thickness: float, mode: str,
                       direction_deg: float, f: np.ndarray) -> np.ndarray:
        """Group velocity (m/s) of ``mode`` at frequencies ``f`` (Hz)."""
        return self._cg(tuple(sorted(params.items())), thickness, mode, direction_deg,
                        tuple(np.asarray(f, float).tolist()))

    def phase_velocity(self, params: Mapping[str, float], thickness: float, mode: str,
                       direction_deg: float, f: np.ndarray) -> np.ndarray:
        """Phase velocity (m/s) of ``mode`` at frequencies ``f`` (Hz)."""
        return self._cp(tuple(sorted(params.items())), thickness, mode, direction_deg,
                        tuple(np.asarray(f, float).tolist()))

    def _group_velocity(self, params: tuple, thickness: float, mode: str, direction_deg: float,
                        f: tuple) -> np.ndarray:
        return np.asarray(safe_group_velocity(self.laminate_at(dict(params), thickness), np.array(f),
                                              mode=mode, direction_deg=direction_deg, order=self.order),
                          float)

    def _phase_velocity(self, params: tuple, thickness: float, mode: str, direction_deg: float,
                        f: tuple) -> np.ndarray:
        d = dispersion(self.laminate_at(dict(params), thickness), np.array(f), direction_deg,
                       order=self.order)
        return np.asarray(d.mode(mode).phase_velocity_m_s, float)
