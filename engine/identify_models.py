"""Data blocks for :mod:`engine.fit` built on the forward models.

* :func:`modal_block` -- natural frequencies from ``engine.plate_fe`` with
  analytic sensitivities (d omega^2/dp -> d f/dp = (d omega^2/dp) / (8 pi^2 f)),
  mode pairing by MAC when measured mode shapes are given, otherwise by order
  with a mode-switching check (MAC tracking of the predicted shapes).
* :func:`wave_block` -- group velocities from ``engine.safe`` (Jacobian by
  forward differences in the estimator).

Units SI: Hz, m/s, Pa. Parameters use the contract names (``E1 E2 nu12 G12
G13 G23 density`` or ``E G nu density``).
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from .fit import DataBlock, IdentificationError
from .laminate import Laminate

__all__ = ["mac", "pair_by_mac", "ModalForward", "modal_block", "wave_block"]


def mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between rows of ``a`` (m, p) and rows of ``b`` (n, p)."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    num = np.abs(a @ b.T) ** 2
    den = np.outer(np.einsum("ij,ij->i", a, a), np.einsum("ij,ij->i", b, b))
    return num / np.where(den > 0, den, np.inf)


def pair_by_mac(measured: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predicted mode index for each measured mode (one-to-one, maximal total MAC).

    Returns ``(index, mac_value)`` arrays of length ``len(measured)``.
    """
    M = mac(measured, predicted)
    rows, cols = linear_sum_assignment(-M)
    idx = np.empty(M.shape[0], int)
    idx[rows] = cols
    return idx, M[np.arange(M.shape[0]), idx]


class ModalForward:
    """Predicted natural frequencies paired with the measured ones.

    ``model`` is an ``engine.plate_fe.PlateModel`` (with any point masses or
    springs already added). With ``points``/``shapes`` (measured mode shapes,
    ``shapes[i][j]`` = mode i at point j) every prediction solves
    ``n_measured + n_extra`` modes and pairs them by MAC; otherwise mode i is
    paired with predicted mode i and :attr:`warnings` records likely mode
    switching (the predicted shapes no longer match, by MAC, those at the
    first evaluation in the same order).
    """

    def __init__(self, model, n_measured: int, *, points=None, shapes=None,
                 material: str | None = None, n_extra: int = 4, min_mac: float = 0.6):
        self.model, self.n, self.material = model, int(n_measured), material
        self.points = None if points is None else np.asarray(points, float)
        self.shapes = None if shapes is None else np.asarray(shapes, float)
        if self.shapes is not None:
            if self.points is None or self.shapes.shape != (self.n, len(self.points)):
                raise IdentificationError(
                    f"mode_shapes: expected values of shape ({self.n}, n_points) with points (n_points, 2)")
        self.n_solve = self.n + (n_extra if self.shapes is not None else 0)
        self.min_mac = min_mac
        self._cache: tuple | None = None
        self._ref_shapes: np.ndarray | None = None
        self.warnings: list[str] = []
        self.pairing: np.ndarray = np.arange(self.n)
        self.mac_values: np.ndarray | None = None

    def solve(self, params: Mapping[str, float]):
        """(``Modes`` of the model at ``params``, predicted mode index of each measured mode)."""
        key = tuple(sorted((k, float(v)) for k, v in params.items()))
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1], self._cache[2]
        modes = self.model.solve(self.n_solve, params=dict(params), material=self.material)
        if self.shapes is not None:
            pred = self.model.shapes_at(modes, self.points)
            idx, mv = pair_by_mac(self.shapes, pred)
            self.pairing, self.mac_values = idx, mv
            low = np.flatnonzero(mv < self.min_mac)
            if low.size:
                msg = (f"modal: weak MAC pairing for measured mode(s) {low.tolist()} "
                       f"(MAC {np.round(mv[low], 2).tolist()})")
                if msg not in self.warnings:
                    self.warnings.append(msg)
        else:
            idx = np.arange(self.n)
            phi = modes.shapes[:, :self.n].T
            if self._ref_shapes is None:
                self._ref_shapes = phi
            else:
                best = np.argmax(mac(phi, self._ref_shapes), axis=1)
                moved = np.flatnonzero(best != idx)
                if moved.size:
                    msg = ("modal: likely mode switching: predicted mode(s) "
                           f"{moved.tolist()} now resemble start mode(s) {best[moved].tolist()}; "
                           "pairing by order may be wrong (supply mode shapes for MAC pairing)")
                    if msg not in self.warnings:
                        self.warnings.append(msg)
        self._cache = (key, modes, idx)
        return modes, idx

    def reset_tracking(self) -> None:
        """Forget the warnings and the reference shapes of the mode-switching check
        (the next solve becomes the reference), e.g. before a new fit."""
        self.warnings.clear()
        self._ref_shapes = None

    def predict(self, params: Mapping[str, float]) -> np.ndarray:
        modes, idx = self.solve(params)
        return modes.frequencies_hz[idx]

    def jacobian(self, params: Mapping[str, float], names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        modes, idx = self.solve(params)
        dlam = self.model.eigen_sensitivities(modes, list(names), params=dict(params),
                                              material=self.material)[idx]
        f = modes.frequencies_hz[idx]
        return f, dlam / (8.0 * np.pi ** 2 * f)[:, None]


def modal_block(model, frequencies_hz, sigma_hz, *, points=None, shapes=None,
                material: str | None = None, name: str = "modal", n_extra: int = 4
                ) -> tuple[DataBlock, ModalForward]:
    """Natural-frequency data block (Hz) and its forward model (for warnings/pairing)."""
    f = np.asarray(frequencies_hz, float)
    fwd = ModalForward(model, len(f), points=points, shapes=shapes, material=material, n_extra=n_extra)
    return DataBlock(name, f, sigma_hz, fwd.predict, fwd.jacobian, kind="modal"), fwd


def wave_block(laminate: Laminate, frequency_hz, group_velocity_m_s, sigma_m_s, *,
               mode: str = "A0", direction_deg: float = 0.0, material: str | None = None,
               name: str | None = None, group_velocity=None) -> DataBlock:
    """Group-velocity data block (m/s) predicted by the SAFE model of ``laminate``.

    ``group_velocity`` defaults to ``engine.safe.group_velocity``.
    """
    if group_velocity is None:
        from .safe import group_velocity  # noqa: PLC0415 (late: SAFE is optional for modal work)
    f = np.asarray(frequency_hz, float)

    def predict(params: Mapping[str, float]) -> np.ndarray:
        lam = laminate.with_params(dict(params), material) if params else laminate
        for m in lam.materials.values():
            m.check()
        return np.asarray(group_velocity(lam, f, mode=mode, direction_deg=direction_deg), float)

    return DataBlock(name or f"waves:{mode}@{direction_deg:g}deg", group_velocity_m_s, sigma_m_s,
                     predict, None, kind="waves")
