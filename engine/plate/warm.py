"""Warm eigen-solve of one DOF block from the previous solve's modes, with a certificate.

Inside a fit, consecutive solves are at nearby constants (LM steps, the global stage's
refinement, the budget, the gap). ARPACK's shift-invert Lanczos starts from scratch each
time: ~119 single LU solves, ~360 M products and ARPACK's own reorthogonalisation for the
demo plate's 56 modes. Here the previous solve's vectors V (wanted modes and spares) start
a block Krylov space: Y = (K - sigma M)^-1 M V, then the residuals' solves
S = (K - sigma M)^-1 R are added while needed (at most ``ROUNDS`` blocks in all), with
Rayleigh-Ritz on the span. No product with K is formed: K Y = M V + sigma M Y and
K S = R + sigma M S.

The answer is returned only when certified (else None, and the caller runs ARPACK):

* counting -- with C(c) the constitutive matrix K is linear and positive in, alpha =
  min eig(C_new, C_old) gives K_new >= alpha K_old (same M, no added stiffness), so the
  (n+1)-th eigenvalue is >= alpha L, L a lower bound of the previous one's (n+1)-th
  (Courant-Fischer). Kahan's theorem on the Ritz residuals (in the (K - sigma M)^-1
  norm) finds n distinct eigenvalues within eps of the n wanted Ritz values; when all
  lie below alpha L, they are exactly the n lowest: no mode missed, none doubled.
* accuracy -- per cluster of Ritz values (relative spread < CLUSTER), the quadratic
  residual bound ||E_cluster||^2 / gap on theta = 1/(lambda - sigma), the gap taken to
  the other certified values and to alpha L. Returned when every wanted value's bound is
  <= ``tol`` relative. Eigenvectors of a degenerate cluster are any basis of its space.

Units: eigenvalues lambda = omega^2, rad^2/s^2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.linalg import cholesky, eigh, solve_triangular

__all__ = ["COUNTS", "WarmStart", "constitutive", "stiffening_bounds", "warm_eig", "ROUNDS", "TOL"]

#: block solves at most (Y, then one per residual check); after that, ARPACK
ROUNDS = 4
#: certified relative bound on every returned eigenvalue (measured <= 7e-11 from ARPACK's path)
TOL = 1e-10
#: Ritz vectors kept beyond the wanted ones for the next start (uncertified; they speed up
#: the top wanted modes' convergence)
KEEP = 16
#: larger relative changes of the stiffness (beta / alpha - 1) go to ARPACK untried: steps of
#: ~1e-2 in every constant never certified within ROUNDS (bench/bench_warm_solve.py)
STEP_MAX = 5e-3
#: after the first residual check, worse than this (relative) -> ARPACK at once: the bound
#: falls ~20x per added block (demo plate), so ~3 more blocks would be needed, as dear as ARPACK
GIVE_UP = 1e-7
#: warm solves returned / tried and not certified / the same solve returned again by the model
#: (read by bench/_count.py, never reset here)
COUNTS = {"warm": 0, "failed": 0, "again": 0}
#: relative spread of Ritz values treated as one cluster (degenerate pairs)
CLUSTER = 1e-3


@dataclass(frozen=True)
class WarmStart:
    """What one block solve leaves for the next: M-orthonormal vectors (block DOFs, wanted
    modes and spares), their eigenvalues (upper bounds), ``lower``: a lower bound of the
    (n_want + 1)-th eigenvalue, the coefficients solved, the block mass object."""

    vectors: np.ndarray
    lam: np.ndarray
    n_want: int
    lower: float
    c: np.ndarray
    mass: object


def constitutive(c: np.ndarray, coupled: bool) -> np.ndarray:
    """The matrix K is linear and positive semi-definite in: [[A, B], [B, D]] (+) H when
    ``coupled``, else D (+) H (the bending block of a symmetric layup); from the 21
    coefficients (COEF_NAMES order). Thickness fields scale A, B, D, H by s, s^2, s^3, s:
    a congruence, so the order between two such matrices carries over to K."""
    sym = lambda v: v[[0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(3, 3)  # noqa: E731
    H = c[[18, 19, 19, 20]].reshape(2, 2)
    if coupled:
        A, B, D = sym(c[0:6]), sym(c[6:12]), sym(c[12:18])
        C = np.zeros((8, 8))
        C[:3, :3], C[:3, 3:6], C[3:6, :3], C[3:6, 3:6] = A, B, B.T, D
    else:
        C = np.zeros((5, 5))
        C[:3, :3] = sym(c[12:18])
    C[-2:, -2:] = H
    return C


def stiffening_bounds(c_new: np.ndarray, c_old: np.ndarray, coupled: bool) -> tuple[float, float]:
    """(alpha, beta): alpha K_old <= K_new <= beta K_old (0, inf when not positive)."""
    try:
        w = eigh(constitutive(c_new, coupled), constitutive(c_old, coupled), eigvals_only=True)
    except np.linalg.LinAlgError:
        return 0.0, np.inf
    return (float(w[0]), float(w[-1])) if w[0] > 0 else (0.0, np.inf)


def _ritz(G: np.ndarray, H: np.ndarray, drop: float = 1e-10):
    """Rayleigh-Ritz from the Gram matrices G = B'MB, H = B'KB of a basis B: (lam ascending,
    X with B X M-orthonormal). Nearly dependent directions dropped (eigh of the scaled G),
    then a Cholesky pass mends the rounding of that orthonormalisation."""
    s = 1.0 / np.sqrt(np.diag(G))
    w, U = eigh(G * s[:, None] * s[None, :])
    keep = w > drop * w[-1]
    T = (U[:, keep] / np.sqrt(w[keep])) * s[:, None]
    G2 = T.T @ G @ T
    T = T @ solve_triangular(cholesky((G2 + G2.T) / 2), np.eye(T.shape[1]))
    H2 = T.T @ H @ T
    lam, C = eigh((H2 + H2.T) / 2)
    return lam, T @ C


def warm_eig(start: WarmStart, lu, M: sp.spmatrix, sigma: float, c: np.ndarray, coupled: bool,
             n_want: int, tol: float = TOL, rounds: int = ROUNDS):
    """(lam (n_want,), vectors (n_block, n_want), next WarmStart) or None when not certified.

    ``lu``: SuperLU of K - sigma M for the new coefficients ``c``; ``M``: the block mass
    (the very object ``start.mass``); ``coupled``: the block holds all five fields."""
    if M is not start.mass or n_want != start.n_want or start.lower <= 0:
        return None
    alpha, beta = stiffening_bounds(c, start.c, coupled)
    lower = alpha * start.lower            # <= the new (n_want + 1)-th eigenvalue
    if not lower > (1.0 + 1e-6) * beta * start.lam[n_want - 1] or beta > (1.0 + STEP_MAX) * alpha:
        return None                        # the top wanted mode could cross, or too far: not tried
    theta_out = 1.0 / (lower - sigma)      # every other eigenvalue's theta is below this
    MV = M @ start.vectors
    B = lu.solve(MV)
    MB = M @ B
    KB = MV + sigma * MB
    G, H = B.T @ MB, B.T @ KB
    prev = np.inf
    for r in range(rounds - 1):
        lam, X = _ritz((G + G.T) / 2, (H + H.T) / 2)
        if lam.size < n_want:
            return None
        Xw = X[:, :n_want]
        MP, lw = MB @ Xw, lam[:n_want]
        R = KB @ Xw - MP * lw
        S = lu.solve(R)
        mu = lw - sigma
        theta = 1.0 / mu
        # residuals of the symmetric problem (K - sigma M)^-1/2 M (K - sigma M)^-1/2:
        # e_i = (K - sigma M)^-1/2 r_i / mu_i^1.5, so E'E = D R'S D with D = mu^-1.5
        d = mu ** -1.5
        EE = (R.T @ S) * d[:, None] * d[None, :]
        EE = (EE + EE.T) / 2
        # clusters of Ritz values (theta descending as lam ascends); per cluster, Kahan:
        # as many distinct eigenvalues within eps_g of its values; disjoint intervals ->
        # all distinct; all below alpha L (theta above theta_out) -> the n_want lowest
        brk = np.flatnonzero(theta[:-1] - theta[1:] > CLUSTER * theta[1:]) + 1
        groups = np.split(np.arange(n_want), brk)
        e2 = np.array([float(np.linalg.eigvalsh(EE[np.ix_(g, g)])[-1]) if g.size > 1 else float(EE[g[0], g[0]])
                       for g in groups]).clip(0.0)
        eps = np.sqrt(e2)
        hi = np.array([theta[g[0]] for g in groups]) + eps
        lo = np.array([theta[g[-1]] for g in groups]) - eps
        ok = lo[-1] > theta_out and bool(np.all(lo[:-1] > hi[1:]))
        bound = np.full(n_want, np.inf)
        if ok:   # quadratic residual bound per cluster, gap to the other intervals
            for j, g in enumerate(groups):
                gap = theta[g[-1]] - theta_out
                if j > 0:
                    gap = min(gap, lo[j - 1] - theta[g[0]])
                if j < len(groups) - 1:
                    gap = min(gap, theta[g[-1]] - hi[j + 1])
                bound[g] = e2[j] / gap / theta[g] if gap > 0 else np.inf
        if ok and np.all(bound <= tol):
            k = min(X.shape[1], n_want + KEEP)
            vec = B @ X[:, :k]
            nxt = WarmStart(vec, lam[:k], n_want, lower, np.array(c, float), M)
            return lw, vec[:, :n_want], nxt
        worst = float(bound.max())
        if r == rounds - 2 or (r == 0 and worst > GIVE_UP):
            return None
        if r > 0 and worst * (worst / prev) ** (rounds - 2 - r) > tol:
            return None                    # at this round's rate the last block would not do
        prev = worst
        todo = bound > tol
        St, Rt = S[:, todo], R[:, todo]
        MS = M @ St
        KS = Rt + sigma * MS
        G = np.block([[G, B.T @ MS], [St.T @ MB, St.T @ MS]])
        H = np.block([[H, B.T @ KS], [St.T @ KB, St.T @ KS]])
        B, MB, KB = np.hstack([B, St]), np.hstack([MB, MS]), np.hstack([KB, KS])
    return None
