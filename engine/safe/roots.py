"""Roots of the branch series (``branches.Branches``) at given frequencies: step 3 of
``branches``' numerics for the branches whose series converged.

Units: k in rad/m, omega in rad/s, lambda = omega^2 in rad^2/s^2.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as npcheb

from .branches import Branches, hermite_root

__all__ = ["roots_from_series"]


def _chop(c: np.ndarray, rel: float = 1e-16) -> np.ndarray:
    """Drop trailing Chebyshev coefficients below rel * max (axis 0)."""
    a = np.abs(c) if c.ndim == 1 else np.max(np.abs(c), axis=tuple(range(1, c.ndim)))
    big = np.nonzero(a > rel * a.max())[0]
    return c[: big[-1] + 1] if big.size else c[:1]


def _columns(series: list) -> np.ndarray:
    """1-D Chebyshev series as the columns of one (n, m) array, zero-padded at the top.

    ``chebval`` of a padded column equals that of the series itself to the bit (a zero top
    coefficient leaves Clenshaw's recurrence unchanged), so one call evaluates them all."""
    out = np.zeros((max(len(c) for c in series), len(series)))
    for i, c in enumerate(series):
        out[:len(c), i] = c
    return out


def roots_from_series(br: Branches, omega: np.ndarray, j, n_dense: int = 256,
                       n_iter: int = 12):
    """Largest-root k of lambda_j(k) = omega^2 for each omega, with lambda_j'(k). NaN if none.

    ``j``: one branch (returns two (m,) arrays) or a sequence of branches (two (len(j), m)
    arrays). All branches, the series of lambda and of its derivative, are evaluated in one
    ``chebval`` per step (its Clenshaw loop over the coefficients is Python: 38 calls were
    34 ms of ``labid dispersion``'s 0.15 s of SAFE work; the roots are bit for bit those of
    one call per series and branch, tests/unit/engine/test_safe_series.py)."""
    one = np.ndim(j) == 0
    js = [int(j)] if one else [int(b) for b in j]
    nb = len(js)
    kmax = br.kmax
    cs = [_chop(br.lam[:, b]) for b in js]
    dcs = [npcheb.chebder(c) * (-2.0 / kmax) if len(c) > 1 else np.zeros(1) for c in cs]
    cd = _columns(cs + dcs)                        # lambda_b then lambda_b' columns
    kd = np.linspace(0.0, kmax, n_dense)
    xd = 1.0 - 2.0 * kd / kmax
    ld = npcheb.chebval(xd, cd)                    # (2 nb, n_dense)
    L, D = ld[:nb], ld[nb:]
    w2 = omega ** 2
    suffix_min = np.minimum.accumulate(L[:, ::-1], axis=1)[:, ::-1]
    n = np.array([np.searchsorted(s, w2, side="right") - 1 for s in suffix_min])   # last node with L <= w2
    n = n.reshape(nb, len(w2))
    has = (n >= 0) & (n < n_dense - 1) & (omega > 0)
    n = np.clip(n, 0, n_dense - 2)
    lo, hi = kd[n], kd[n + 1]
    b = np.arange(nb)[:, None]
    k = hermite_root(lo, hi, L[b, n], L[b, n + 1], D[b, n], D[b, n + 1], w2, n_iter=4)
    act = has.copy()
    noise = 1e-14 * np.max(np.abs(L), axis=1)[:, None]
    for _ in range(n_iter):
        if not act.any():
            break
        x = np.clip(1.0 - 2.0 * k / kmax, -1.0, 1.0)
        fd = npcheb.chebval(np.concatenate([x, x]).T, cd, tensor=False).T    # (2 nb, m)
        f = fd[:nb] - w2
        d = fd[nb:]
        with np.errstate(invalid="ignore"):
            kn = k - f / np.where(d > 0, d, np.inf)
        # stay in the bracket of the dense grid (the start is already close)
        kn = np.clip(kn, lo, hi)
        done = (np.abs(kn - k) <= 1e-12 * kn) | (np.abs(f) <= noise)
        k = np.where(act, kn, k)
        act &= ~done
    x = np.clip(1.0 - 2.0 * k / kmax, -1.0, 1.0)
    dl = npcheb.chebval(x.T, _columns([_chop(br.dlam[:, b]) for b in js]), tensor=False).T
    k = np.where(has, k, np.nan)
    dl = np.where(has, dl, np.nan)
    return (k[0], dl[0]) if one else (k, dl)
