"""Joint refit of the constants and one candidate effect (``scipy.optimize.least_squares``).

Unknowns: the log-constants theta of the start estimate's parameters and the
effect magnitude a (bounded to its plausible range). Residuals: the whitened
feature residuals, plus the prior rows w (theta - theta_prior) when the start
estimate had a prior. Trust-region reflective (``trf``) from the start
estimate and the linear estimate of the effect, the constants kept within a
factor 3 of the start (``THETA_BOX``); Jacobian: the constants'
columns from :meth:`GapFit.jacobian` at every iterate (analytic modal
sensitivities; the wave rows, finite differences of SAFE, frozen at the
start), the effect's column by a forward difference of 0.1 x its typical
magnitude (towards the inside of the range). ``converged`` is scipy's own
termination status (>0: ftol/xtol/gtol met; 0: evaluation budget spent). Covariance (the
effect's std and every constant's) from the final Gauss-Newton matrix.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import least_squares

from ..forward import EFFECTS
from .residuals import GapError, GapFit
from .where import held_out

__all__ = ["Refit", "RefitError", "refit", "THETA_BOX"]

#: the constants move at most by this factor's log from the start estimate during a refit
THETA_BOX = math.log(3.0)
#: whitened residual returned where the constants are inadmissible (trust region backs off)
INADMISSIBLE = 1e3


class RefitError(GapError):
    """The refit could not start (model undefined at its starting point)."""


@dataclass(frozen=True)
class Refit:
    """Result of a joint refit: effect magnitude (+- std, effect unit), chi^2 and
    whitened residual after it, fitted constants, held-out gap; ``iterations``
    is the number of residual evaluations, ``converged`` scipy's status > 0;
    ``selection``: per peak the predicted mode it was paired with when the refit re-paired
    the peaks under the effect (:mod:`engine.gap.repair`; None: the start's pairing),
    ``penalty`` the pairing penalty that re-pairing added (chi^2 units, >= 0)."""

    iterations: int
    converged: bool
    magnitude: float
    std: float
    chi2: float
    residual: np.ndarray
    constants: dict[str, float]
    held_out_after: float
    selection: tuple | None = None
    penalty: float = 0.0
    #: std of each fitted constant (SI) from the same Gauss-Newton covariance
    constants_std: dict[str, float] | None = None


def _unpack(x, names):
    return {n: float(v) for n, v in zip(names, x)}


def refit(name: str, magnitude_linear: float, F: GapFit, theta0: np.ndarray, w: np.ndarray,
          theta_prior: np.ndarray, folds: Sequence[np.ndarray], max_nfev: int = 30) -> Refit:
    """Joint fit of the constants and effect ``name`` (see module docstring).

    ``theta0``: log-constants at the start estimate; ``w``: prior sqrt-weights
    about ``theta_prior`` (zeros: no prior). Raises :class:`RefitError` if the
    model is undefined at the start.
    """
    spec = EFFECTS[name]
    names = F.names
    k = len(names)
    h = 0.1 * spec.typical
    has_prior = bool(np.any(w > 0))
    a0 = float(np.clip(magnitude_linear, spec.lo, spec.hi))
    if a0 == spec.lo == 0.0 and spec.hi > 0:
        a0 = 0.1 * spec.typical      # start inside the range (a bound is a stationary point for 2nd-order effects)

    memo: dict = {}
    started = False

    def feat(x):                      # whitened feature residual, memoised (jac reuses resid's)
        key = x.tobytes()
        if key not in memo:
            memo.clear()
            try:
                memo[key] = F.residual(_unpack(np.exp(x[:k]), names), {name: float(x[k])})
            except ValueError:        # inadmissible constants (PhysicsError): a wall the trust region backs off
                if not started:
                    raise
                memo[key] = np.full(len(F.y), INADMISSIBLE)
        return memo[key]

    def resid(x):
        r = feat(x)
        return np.concatenate([r, w * (x[:k] - theta_prior)]) if has_prior else r

    def jac(x):
        p, a = _unpack(np.exp(x[:k]), names), float(x[k])
        r = feat(x)
        step = h if a + h <= spec.hi else -h
        col = (F.residual(p, {name: a + step}) - r) / step
        Jc = F.jacobian(p, {name: a}, waves=False)
        if Jw0 is not None:
            Jc = np.vstack([Jc, Jw0])
        J = np.column_stack([Jc, col])
        if has_prior:
            J = np.vstack([J, np.column_stack([np.diag(w), np.zeros(k)])])
        return J

    x0 = np.concatenate([theta0, [a0]])
    try:
        feat(x0)
    except ValueError as exc:
        raise RefitError(f"refit failed: {exc}") from None
    started = True
    nm = F.fw.n_modal
    # the wave rows of the constants' Jacobian (finite differences of SAFE) frozen at the start
    Jw0 = F.jacobian(_unpack(np.exp(theta0), names), {name: a0})[nm:] if len(F.y) > nm else None
    lo = np.concatenate([theta0 - THETA_BOX, [spec.lo]])
    hi = np.concatenate([theta0 + THETA_BOX, [spec.hi]])
    try:
        res = least_squares(resid, x0, jac=jac, bounds=(lo, hi), method="trf",
                            x_scale=np.concatenate([np.full(k, 0.05), [spec.typical]]),
                            max_nfev=max_nfev, ftol=1e-3, xtol=1e-5, gtol=1e-6)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise RefitError(f"refit failed: {exc}") from None
    x = res.x
    n = len(F.y)
    r = res.fun[:n]
    Jf = res.jac[:n]
    A = Jf.T @ Jf + np.diag(np.concatenate([w ** 2, [0.0]]))
    try:
        var = np.maximum(np.diag(np.linalg.pinv(A)), 0.0)
        std = float(math.sqrt(var[k]))
    except np.linalg.LinAlgError:
        var, std = np.full(k + 1, np.inf), float("inf")
    consts = _unpack(np.exp(x[:k]), names)
    return Refit(iterations=int(res.nfev), converged=bool(res.status > 0), magnitude=float(x[k]), std=std,
                 chi2=float(r @ r), residual=r, constants=consts,
                 held_out_after=held_out(r, Jf, w, x[:k] - theta_prior, folds),
                 constants_std={n_: float(consts[n_] * math.sqrt(v)) for n_, v in zip(names, var[:k])})
