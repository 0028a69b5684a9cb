"""Joint refit of the constants and one candidate effect.

Levenberg-Marquardt on the nonlinear whitened residuals, from the nominal
constants and the linear estimate of the effect, with the constants'
Jacobian frozen at the nominal point (the true constants lie within tens of
per cent of nominal) and the effect's column re-evaluated by a secant at
every iterate. Covariance from the final Gauss-Newton matrix. The iterations
are the project's own (kept in this step; ``scipy.optimize.least_squares``
is the candidate replacement).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..forward import EFFECTS
from .residuals import GapError, GapFit
from .where import held_out

__all__ = ["Refit", "RefitError", "refit"]


class RefitError(GapError):
    """The refit could not start (model undefined at its starting point)."""


@dataclass(frozen=True)
class Refit:
    """Result of a joint refit: effect magnitude (+- std, effect unit), chi^2 and
    whitened residual after it, fitted constants, held-out gap."""

    iterations: int
    converged: bool
    magnitude: float
    std: float
    chi2: float
    residual: np.ndarray
    constants: dict[str, float]
    held_out_after: float


def _unpack(x, names):
    return {n: float(v) for n, v in zip(names, x)}


def refit(name: str, magnitude_linear: float, F: GapFit, Jnom: np.ndarray, w: np.ndarray,
          theta_nom: np.ndarray, folds: Sequence[np.ndarray], gn_iter: int) -> Refit:
    """Joint fit of the constants and effect ``name`` (see module docstring).

    ``Jnom``: whitened Jacobian of the constants (log) at nominal; ``w``: prior
    sqrt-weights about ``theta_nom`` (log nominal constants); ``gn_iter``:
    maximum iterations. Raises :class:`RefitError` if the model is undefined
    at the start.
    """
    spec = EFFECTS[name]
    names = F.names
    k = len(names)
    h = 0.1 * spec.typical
    a = float(np.clip(magnitude_linear, spec.lo, spec.hi))
    theta = theta_nom.copy()

    def resid(th, a_):
        return F.residual(_unpack(np.exp(th), names), {name: a_})

    def col(th, a_, r_):
        step = h if a_ + h <= spec.hi else -h
        return (resid(th, a_ + step) - r_) / step

    try:
        r = resid(theta, a)
        s = col(theta, a, r)
    except ValueError as exc:
        raise RefitError(f"refit failed: {exc}") from None
    cost = float(r @ r)
    mu = 1e-3
    it = 0
    converged = False
    for it in range(1, gn_iter + 1):
        A = np.vstack([np.column_stack([Jnom, s]), np.column_stack([np.diag(w), np.zeros(k)])])
        b = np.concatenate([r, w * (theta - theta_nom)])
        M, g = A.T @ A, A.T @ b
        D = np.diag(np.maximum(np.diag(M), 1e-12 * np.max(np.diag(M))))
        ok = False
        for _ in range(10):
            try:
                d = -np.linalg.solve(M + mu * D, g)
            except np.linalg.LinAlgError:
                mu *= 10
                continue
            th_new = theta + np.clip(d[:k], -0.5, 0.5)
            a_new = float(np.clip(a + d[k], spec.lo, spec.hi))
            try:
                r_new = resid(th_new, a_new)
            except ValueError:
                mu *= 10
                continue
            c_new = float(r_new @ r_new + np.sum((w * (th_new - theta_nom)) ** 2))
            if c_new < cost + float(np.sum((w * (theta - theta_nom)) ** 2)) or c_new == 0:
                ok = True
                break
            mu *= 4
        if not ok:
            converged = True   # no decrease possible: at the minimum (to the frozen Jacobian)
            break
        gain = cost + float(np.sum((w * (theta - theta_nom)) ** 2)) - c_new
        theta, a, r = th_new, a_new, r_new
        cost = float(r @ r)
        mu = max(mu / 3, 1e-9)
        s = col(theta, a, r)
        if gain < 1e-3 * max(1.0, cost):
            converged = True
            break
    Jf = np.column_stack([Jnom, s])
    A = Jf.T @ Jf + np.diag(np.concatenate([w ** 2, [0.0]]))
    try:
        std = float(math.sqrt(max(np.linalg.inv(A)[k, k], 0.0)))
    except np.linalg.LinAlgError:
        std = float("inf")
    return Refit(iterations=it, converged=converged, magnitude=float(a), std=std, chi2=float(r @ r),
                 residual=r, constants=_unpack(np.exp(theta), names),
                 held_out_after=held_out(r, Jf, w, theta - theta_nom, folds))
