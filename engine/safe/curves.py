"""Dispersion curves of a laminate: every guided mode, or one mode's group velocity.

Units: SI (Hz, rad/m, m/s); angles in degrees. Model: :mod:`engine.safe.model`;
labels: :mod:`engine.safe.labels`; numerics: :mod:`engine.safe.branches`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..laminate import Laminate
from .branches import cheb_branches, reduce_class, solve_branches
from .roots import roots_from_series
from .labels import FUND_ORDER, branch_table, fundamental_rows
from .model import TWO_PI, SafeError, SafeModel, projected_derivatives, safe_model

__all__ = ["ModeCurve", "Dispersion", "dispersion", "dispersion_from_model", "group_velocity",
           "group_velocity_jacobian", "ModeSolution", "mode_solution"]


@dataclass(frozen=True)
class ModeCurve:
    """One guided mode on a frequency grid; NaN where the mode does not exist."""

    label: str
    frequency_hz: np.ndarray
    wavenumber_rad_m: np.ndarray
    phase_velocity_m_s: np.ndarray
    group_velocity_m_s: np.ndarray
    cutoff_hz: float = 0.0


@dataclass(frozen=True)
class Dispersion:
    """Dispersion curves of a laminate along one direction."""

    frequency_hz: np.ndarray
    direction_deg: float
    modes: tuple[ModeCurve, ...]

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(m.label for m in self.modes)

    def mode(self, label: str) -> ModeCurve:
        for m in self.modes:
            if m.label == label:
                return m
        raise KeyError(f"mode {label!r} not found; available: {', '.join(self.labels)}")



def _check_freq(frequency_hz) -> np.ndarray:
    f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)):
        raise SafeError(f"frequency grid: expected a non-empty 1D array of finite values in Hz, got shape {f.shape}")
    if not np.any(f > 0):
        raise SafeError("frequency grid: expected at least one positive frequency in Hz")
    return f


def _model_for(laminate, fmax, direction_deg, order, elements_per_ply) -> SafeModel:
    return safe_model(laminate, direction_deg, order=order, elements_per_ply=elements_per_ply,
                      fmax_hz=fmax)


def _solve_rows(model: SafeModel, w: np.ndarray, labels: tuple[str, ...] | None):
    """(rows, results): each row's label -> (k, c_g, cut-off Hz, reduced model, class index,
    branch index) on the angular frequencies ``w`` (rad/s)."""
    wmax = float(np.max(w))
    if labels is not None and set(labels) <= set(FUND_ORDER):
        rows = [r for r in fundamental_rows(model) if r["label"] in labels]
    else:
        rows = branch_table(model, wmax)
    if labels is not None:
        missing = set(labels) - {r["label"] for r in rows}
        if missing:
            raise SafeError(f"mode(s) {sorted(missing)} do not exist below {wmax / TWO_PI:g} Hz; "
                            f"expected one of {[r['label'] for r in rows]}")
        rows = [r for r in rows if r["label"] in labels]
    by_class: dict[int, list] = {}
    for r in rows:
        by_class.setdefault(r["ci"], []).append(r)
    results = {}
    for ci, rs in by_class.items():
        nb = max(r["j"] for r in rs) + 1
        red = reduce_class(model.classes[ci], wmax, n_branches=nb if labels is not None else None)
        if red is None:
            continue
        br = cheb_branches(red, nb)
        slow = [r for r in rs if not br.converged[r["j"]]]
        if slow:    # series not converged (sharp veering): eigen-solves per frequency, one call
            js = np.repeat([r["j"] for r in slow], len(w))
            k_s, cg_s, _ = solve_branches(red, np.tile(w, len(slow)), js, grid=br.nodes)
            for i, r in enumerate(slow):
                sl = slice(i * len(w), (i + 1) * len(w))
                results[r["label"]] = (k_s[sl], cg_s[sl], r["cutoff"], red, ci, r["j"])
        fast = [r for r in rs if br.converged[r["j"]]]
        if fast:    # every converged branch of the class in one pass over its series
            ks, dls = roots_from_series(br, w, [r["j"] for r in fast])
            for r, k, dl in zip(fast, ks, dls):
                with np.errstate(invalid="ignore", divide="ignore"):
                    cg = dl / (2.0 * w)
                results[r["label"]] = (k, cg, r["cutoff"], red, ci, r["j"])
    return rows, results


def dispersion_from_model(model: SafeModel, frequency_hz, *, labels: tuple[str, ...] | None = None
                          ) -> Dispersion:
    """Dispersion curves of an assembled model on any frequency grid (Hz)."""
    f = _check_freq(frequency_hz)
    w = TWO_PI * f
    rows, results = _solve_rows(model, w, labels)
    modes = []
    for r in rows:
        if r["label"] not in results:
            continue
        k, cg, cut = results[r["label"]][:3]
        with np.errstate(divide="ignore", invalid="ignore"):
            cp = np.where(k > 0, w / k, np.nan)
        if not np.any(np.isfinite(k)) and cut >= np.max(f):
            continue
        modes.append(ModeCurve(r["label"], f.copy(), k, cp, cg, float(cut)))
    return Dispersion(f.copy(), float(model.direction_deg), tuple(modes))


def dispersion(laminate: Laminate, frequency_hz, direction_deg: float = 0.0, *,
               order: int | None = None, elements_per_ply: int | None = None) -> Dispersion:
    """Every guided mode below max(frequency_hz) on the given grid (Hz).

    Phase velocity w/k and group velocity from the eigenvector; NaN where a
    mode does not exist. Labels and tracking: see the module docstring.
    """
    f = _check_freq(frequency_hz)
    model = _model_for(laminate, float(np.max(f)), direction_deg, order, elements_per_ply)
    return dispersion_from_model(model, f)


def group_velocity(laminate: Laminate, frequency_hz, mode: str = "A0",
                   direction_deg: float = 0.0, *, order: int | None = None,
                   elements_per_ply: int | None = None) -> np.ndarray:
    """Group velocity (m/s) of one mode on a frequency grid (fast path).

    Only the class of the requested mode is solved. Smooth in the elastic
    constants: fixed discretisation for a given fmax, Newton-converged roots.
    """
    f = _check_freq(frequency_hz)
    model = _model_for(laminate, float(np.max(f)), direction_deg, order, elements_per_ply)
    return dispersion_from_model(model, f, labels=(mode,)).mode(mode).group_velocity_m_s


@dataclass(frozen=True, eq=False)
class ModeSolution:
    """One mode's roots on a frequency grid with what its derivatives need (the assembled
    model, the reduced class model, class and branch index). ``group_velocity_m_s`` is
    :func:`group_velocity`'s, bit for bit."""

    frequency_hz: np.ndarray
    wavenumber_rad_m: np.ndarray
    group_velocity_m_s: np.ndarray
    model: SafeModel
    reduced: object
    class_index: int
    branch: int


def mode_solution(laminate: Laminate, frequency_hz, mode: str = "A0", direction_deg: float = 0.0, *,
                  order: int | None = None, elements_per_ply: int | None = None) -> ModeSolution:
    """Solve one mode (the :func:`group_velocity` path) and keep what its Jacobian needs."""
    f = _check_freq(frequency_hz)
    model = _model_for(laminate, float(np.max(f)), direction_deg, order, elements_per_ply)
    _, results = _solve_rows(model, TWO_PI * f, (mode,))
    if mode not in results:
        raise SafeError(f"mode {mode!r}: no branch below {np.max(f):g} Hz")
    k, cg, _, red, ci, j = results[mode]
    return ModeSolution(f, k, cg, model, red, ci, j)


def group_velocity_jacobian(laminate: Laminate, frequency_hz, derivatives: Sequence[tuple],
                            mode: str = "A0", direction_deg: float = 0.0, *,
                            order: int | None = None, elements_per_ply: int | None = None,
                            solution: ModeSolution | None = None):
    """(c_g (n,), dc_g/dp (n, len(derivatives))) of ``mode`` on the frequencies (Hz).

    ``derivatives``: per parameter p, ``(dC, drho)``: for each ply the derivative of its 3D
    stiffness in material axes (6x6, Pa per unit of p) and of its density. c_g is exactly
    :func:`group_velocity`'s.

    Method (at a root (k, w) of branch j, lambda(k, p) = w^2, lambda an eigenvalue of the
    reduced class model, Rayleigh-Ritz basis T held fixed): dk/dp = -lambda_p / lambda_k and
    dc_g/dp = (lambda_kk dk/dp + lambda_kp) / (2 w), by first-order perturbation theory on the
    reduced model's full eigen-decomposition (y M-normalised, G = dA/dp - lambda dm,
    P_m = y_m^T A_k y):
    lambda_p = y^T G y, lambda_kk = 2 y^T a2 y + 2 sum_{m!=j} P_m^2 / (lambda - lambda_m),
    lambda_kp = y^T dA_k/dp y + 2 sum_{m!=j} (y_m^T G y) P_m / (lambda - lambda_m) - lambda_k y^T dm y.
    dA/dp, dm: the assembled matrix derivatives (linear in the ply stiffness and density)
    projected on T. One SAFE solve, one reduced eigen-solve per frequency and one assembly per
    parameter instead of a SAFE solve per parameter; equal to central differences of
    :func:`group_velocity` to ~1e-7 relative (tests/unit/engine/test_safe_sensitivity.py).
    ``solution``: this laminate's :func:`mode_solution` on these frequencies, if at hand.
    """
    sol = solution if solution is not None else mode_solution(
        laminate, frequency_hz, mode, direction_deg, order=order, elements_per_ply=elements_per_ply)
    f, k, cg = sol.frequency_hz, sol.wavenumber_rad_m, sol.group_velocity_m_s
    model, red, ci, j = sol.model, sol.reduced, sol.class_index, sol.branch
    w = TWO_PI * f
    jac = np.full((len(f), len(derivatives)), np.nan)
    ok = np.isfinite(k) & np.isfinite(cg)
    if not ok.any() or not len(derivatives):
        return cg, jac
    kk, ww = k[ok], w[ok]
    lam, Y = np.linalg.eigh(red.a0[None] + kk[:, None, None] * red.a1[None]
                            + (kk * kk)[:, None, None] * red.a2[None])
    y = Y[:, :, j]                                          # (n, r)
    lj = lam[:, j]
    Ak_y = y @ red.a1 + 2 * kk[:, None] * (y @ red.a2)      # A_k y (a1, a2 symmetric)
    P = np.einsum("nrm,nr->nm", Y, Ak_y)                    # y_m^T A_k y
    lk = P[:, j]
    gap = lj[:, None] - lam
    gap[:, j] = np.inf
    with np.errstate(divide="ignore"):
        inv = 1.0 / gap
    lkk = 2 * np.einsum("nr,rs,ns->n", y, red.a2, y) + 2 * np.sum(P * P * inv, axis=1)
    T = model.classes[ci].to_phys @ red.basis               # (ndof, r), M-orthonormal
    d0, d1, d2, dm = projected_derivatives(model, laminate, derivatives, T)
    for i in range(len(derivatives)):
        Gy = (y @ d0[i] + kk[:, None] * (y @ d1[i]) + (kk * kk)[:, None] * (y @ d2[i])
              - lj[:, None] * (y @ dm[i]))                   # G y (symmetric matrices)
        g = np.einsum("nrm,nr->nm", Y, Gy)                  # y_m^T G y
        lp = g[:, j]
        ymy = np.sum((y @ dm[i]) * y, axis=1)
        lkp = (np.sum((y @ d1[i] + 2 * kk[:, None] * (y @ d2[i])) * y, axis=1)
               + 2 * np.sum(g * P * inv, axis=1) - lk * ymy)
        dk = -lp / lk
        jac[ok, i] = (lkk * dk + lkp) / (2.0 * ww)
    return cg, jac
