"""Guided-wave group velocities predicted by the SAFE model of the laminate.

* :func:`wave_block` -- the group-velocity :class:`~engine.fit.DataBlock` of
  the estimators (analytic Jacobian: ``engine.safe.group_velocity_jacobian``);
* :func:`ply_derivatives` -- derivatives of the plies' stiffness and density in the constants.
* :class:`SafeWaves` -- group and phase velocities of one laminate for given
  constants and a relative thickness error, memoised per input (the gap's
  forward model evaluates the same points many times).

Units SI: Hz, m/s, Pa.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..fit import DataBlock
from ..laminate import Laminate, stiffness_3d
from ..safe import dispersion, group_velocity as safe_group_velocity, group_velocity_jacobian, mode_solution
from .memo import method_lru

__all__ = ["wave_block", "SafeWaves", "ply_derivatives"]


def wave_block(laminate: Laminate, frequency_hz, group_velocity_m_s, sigma_m_s, *,
               mode: str = "A0", direction_deg: float = 0.0, material: str | None = None,
               name: str | None = None, group_velocity=None) -> DataBlock:
    """Group-velocity data block (m/s) predicted by the SAFE model of ``laminate``.

    ``group_velocity`` defaults to ``engine.safe.group_velocity``; then the block's Jacobian is
    analytic (``engine.safe.group_velocity_jacobian``: one SAFE solve per evaluation instead of
    1 + n_params for the estimator's forward differences). A custom ``group_velocity`` keeps
    the differences.
    """
    analytic = group_velocity is None
    if group_velocity is None:
        group_velocity = safe_group_velocity
    f = np.asarray(frequency_hz, float)
    last: dict = {}       # the last constants' mode solution: the estimator asks for the Jacobian
                          # where it has just predicted (one SAFE solve, not two)

    def at(params: Mapping[str, float]) -> Laminate:
        lam = laminate.with_params(dict(params), material) if params else laminate
        for m in lam.materials.values():
            m.check()
        return lam

    def solved(params: Mapping[str, float]):
        key = tuple(sorted(dict(params).items()))
        if key not in last:
            lam = at(params)
            sol = mode_solution(lam, f, mode, direction_deg)
            last.clear()
            last[key] = (lam, sol)
        return last[key]

    def predict(params: Mapping[str, float]) -> np.ndarray:
        if analytic:
            return np.array(solved(params)[1].group_velocity_m_s, float)     # a copy: the memo keeps its own
        return np.asarray(group_velocity(at(params), f, mode=mode, direction_deg=direction_deg), float)

    def jacobian(params: Mapping[str, float], names) -> tuple[np.ndarray, np.ndarray]:
        lam, sol = solved(params)
        cg, jac = group_velocity_jacobian(lam, f, ply_derivatives(laminate, params, names, material),
                                          mode=mode, direction_deg=direction_deg, solution=sol)
        if not (np.all(np.isfinite(cg)) and np.all(np.isfinite(jac))):
            # as the estimator's own check of predictions: unphysical here, shorten the step
            raise ValueError(f"waves {mode}@{direction_deg:g}deg: no root at some frequencies")
        return np.asarray(cg, float).copy(), jac

    return DataBlock(name or f"waves:{mode}@{direction_deg:g}deg", group_velocity_m_s, sigma_m_s,
                     predict, jacobian if analytic else None, kind="waves")


#: relative step of the central difference of a ply's 3D stiffness in one constant: C(p) is a
#: rational function of the constants (the inverse of the compliance), so the truncation is
#: ~(1e-6)^2 and the round-off ~1e-16 / 1e-6 = 1e-10 relative
_REL_STEP = 1e-6


def ply_derivatives(laminate: Laminate, params: Mapping[str, float], names, material: str | None = None
                    ) -> list[tuple[list[np.ndarray], list[float]]]:
    """Per name: (d C / dp for each ply (6x6, material axes, Pa per unit), d rho / dp per ply) of
    ``laminate.with_params(params, material)``, by central differences of the material's own
    ``with_params`` (what ``Laminate.with_params`` calls: every parameterisation -- isotropic E
    with nu or G held, a derived nu23 -- is the one the predictions use)."""
    mats = laminate.materials
    if material is None:
        if len(mats) != 1:
            raise KeyError(f"laminate has materials {sorted(mats)}; name the one to update")
        material = next(iter(mats))
    base = mats[material]
    on = [p.material.name == material for p in laminate.plies]
    zero = np.zeros((6, 6))
    out = []
    for n in names:
        p0 = float(params[n])
        h = _REL_STEP * abs(p0) or _REL_STEP
        hi = base.with_params(**{**params, n: p0 + h})
        lo = base.with_params(**{**params, n: p0 - h})
        dC = (stiffness_3d(hi) - stiffness_3d(lo)) / (2.0 * h)
        drho = (hi.density - lo.density) / (2.0 * h)
        out.append(([dC if o else zero for o in on], [drho if o else 0.0 for o in on]))
    return out


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
