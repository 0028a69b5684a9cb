"""Branches of a reduced SAFE class model as Chebyshev series in k, and their roots.

Numerics
--------
Per uncoupled class, in Cholesky-reduced standard form (M = I):

1. Rayleigh-Ritz basis: the eigenvectors of the lowest branches at a few
   Chebyshev wavenumbers on [0, k_max] (k_max: where the lowest branch
   reaches the top frequency). The Ritz frequencies converge quadratically
   in the basis error; checked against full Newton solves in the tests.
2. Each branch w_j(k)^2 and its eigenvector slope phi^T K'(k) phi are
   sampled on nested Chebyshev-Lobatto nodes (33 ... 257) until the
   Chebyshev tail is below 1e-11; within a class branches never cross, so
   sorting gives the branch index.
3. Each requested frequency: Newton on the Chebyshev series of w_j(k)^2
   (largest root), group velocity = interpolated eigenvector slope / (2 w).
   Branches whose series does not converge (sharp veerings) fall back to one
   reduced eigen-solve per frequency with a second-order (perturbation
   theory) Newton step.

Accuracy is limited by round-off at very low frequency (eigenvalues w^2 are
small next to the largest of the model): ~1e-7 relative in c_g at 1 kHz for
the 1.6 mm CFRP, 1e-8 and better above 5 kHz. A complex (viscoelastic) C
would make K0, K1~, K2 complex symmetric: steps 1-3 would then need a
non-Hermitian eigensolver (not implemented).

Why a hand-written branch series (measured, kept on purpose)
------------------------------------------------------------
A plain solve (the 2N complex companion linearisation in k, ``scipy.linalg.eig``
at every frequency) of the 12-ply CFRP to 200 kHz costs 6000-8400x the series
(bench/bench_safe.py, bench/RESULTS.md "engine.safe", section 1) and agrees with
it to 7.5e-7 in k and 2.4e-6 in c_g (round-off at 1 kHz; < 1e-9 above 60 kHz).
``tests/test_safe.py::test_reduced_solver_matches_full_newton`` and
``test_many_modes_with_veering_match_full_newton`` pin the agreement with
:func:`solve_full` (Newton on the full, unreduced class model per frequency).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import chebyshev as npcheb

from .model import DofClass

__all__ = ["Reduced", "Branches", "reduce_class", "solve_branches", "cheb_branches", "hermite_root",
           "dense_table", "invert_table", "solve_full", "dct1"]


# ---------------------------------------------------------------------------
# eigen-solves
def _eig_at(cls: DofClass, k: float, n: int | None = None, vectors: bool = True):
    """The n lowest eigenpairs (all if None) of the class at wavenumber k.

    numpy's full ``eigh`` (LAPACK syevd) and a slice, not scipy's subset driver: importing
    scipy.linalg is ~0.25 s CPU of ``labid dispersion``'s ~0.6 s, and the curves move by
    round-off only (bench/RESULTS.md, issue 29 session 26: against the exact Rayleigh-Lamb
    roots errors of the same size, within a factor 3 either way at the round-off floor)."""
    A = cls.A0 + k * cls.A1 + (k * k) * cls.A2
    if not vectors:
        lam = np.linalg.eigvalsh(A)
        return lam if n is None else lam[:n]
    lam, vec = np.linalg.eigh(A)
    return (lam, vec) if n is None else (lam[:n], vec[:, :n])


def _kmax(cls: DofClass, wmax: float, branch: int = 0) -> float:
    """Wavenumber where the lowest class branch reaches wmax.

    Secant iteration on log(lambda) versus log(k) (lambda ~ k^p, 2 <= p <= 4),
    eigenvalues only; a fixed number of steps after convergence keeps kmax a
    smooth function of the elastic constants (identification differentiates
    through it).
    """
    def loglam(k):
        lam = np.linalg.eigvalsh(cls.A0 + k * cls.A1 + k * k * cls.A2)[branch]
        return np.log(max(lam, 1e-300))

    target = 2.0 * np.log(wmax)
    x0 = np.log(wmax / np.sqrt(max(np.max(np.diag(cls.A2)), 1e-30)))
    y0 = loglam(np.exp(x0))
    for _ in range(60):     # low wmax, flexural branch: start above the round-off of lambda
        if y0 > target - 12.0:
            break
        x0 += 1.0
        y0 = loglam(np.exp(x0))
    x1 = x0 + (target - y0) / 3.0
    y1 = loglam(np.exp(x1))
    n_done = 0
    for _ in range(40):
        p = (y1 - y0) / (x1 - x0) if x1 != x0 else 3.0
        p = min(max(p, 0.5), 6.0)
        x2 = x1 + (target - y1) / p
        x2 = min(max(x2, x1 - 2.0), x1 + 2.0)
        x0, y0 = x1, y1
        x1, y1 = x2, loglam(np.exp(x2))
        close = abs(x1 - x0) < 1e-3
        n_done = n_done + 1 if close or n_done else 0
        if n_done >= 2:
            break
    return float(np.exp(x1))


def _cheb(n: int, a: float, b: float) -> np.ndarray:
    x = -np.cos(np.pi * np.arange(n) / (n - 1))
    return a + (b - a) * (x + 1.0) / 2.0


@dataclass(frozen=True)
class Reduced:
    """Rayleigh-Ritz reduced class model: a0 + k a1 + k^2 a2, identity mass."""

    a0: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    basis: np.ndarray         # (n_c, r) orthonormal, psi = basis @ y
    kmax: float
    n_branches: int


def reduce_class(cls: DofClass, wmax: float, n_k: int | None = None, extra: int | None = None, small_k=(),
            n_branches: int | None = None) -> Reduced | None:
    """Reduced model of one class capturing every branch below wmax (or the first n_branches).

    Basis: the n_cut + extra lowest eigenvectors at n_k Chebyshev wavenumbers; by
    default (6, 1) for up to 3 branches and (8, 2) beyond (veering higher modes
    need a richer basis: 2e-6 -> 2e-8 in c_g for CFRP up to 2 MHz).
    """
    if n_branches is not None and n_branches <= cls.n_rigid:
        n_cut = n_branches                   # zero cut-off branches only: no count needed
    else:
        lam0 = np.linalg.eigvalsh(cls.A0)
        lam0[:cls.n_rigid] = 0.0
        n_cut = int(np.sum(lam0 < (1.05 * wmax) ** 2))
    if n_branches is not None:
        n_cut = min(max(n_cut, 0), n_branches)
        if n_cut == 0:
            return None
    if n_cut == 0:
        return None
    if n_k is None:
        n_k = 6 if n_cut <= 3 else 8
    if extra is None:
        extra = 1 if n_cut <= 3 else 2
    n_keep = min(n_cut + extra, cls.A0.shape[0])
    kmax = 1.1 * _kmax(cls, wmax, 0)
    vecs = []
    for k in np.concatenate([_cheb(n_k, 0.0, kmax), kmax * np.array(small_k)]):
        _, v = _eig_at(cls, k, n_keep)
        vecs.append(v)
    V = np.concatenate(vecs, axis=1)
    U, s, _ = np.linalg.svd(V, full_matrices=False)
    B = U[:, s > 1e-10 * s[0]]
    sym = lambda X: 0.5 * (X + X.T)
    return Reduced(sym(B.T @ cls.A0 @ B), sym(B.T @ cls.A1 @ B), sym(B.T @ cls.A2 @ B),
                    B, kmax, n_cut)


#: wavenumbers per ``eigh`` call (``_eig_chunks``)
CHUNK = 32


def _eig_chunks(red: Reduced, k: np.ndarray):
    """(slice, values, vectors) of a0 + k a1 + k^2 a2, ``CHUNK`` wavenumbers at a time.

    The same LAPACK call per matrix as one batched ``eigh`` (bit for bit the same pairs), but
    the temporaries stay < 1 MB and are reused: the 257 x 56 x 56 arrays of one call were
    fresh memory, ~2,000 more page faults (~5-10 ms of system time) in ``labid dispersion``'s
    process (issue 29, session 26)."""
    for s in range(0, len(k), CHUNK):
        kk = k[s:s + CHUNK]
        A = np.multiply.outer(kk, red.a1)          # a0 + k a1 + k^2 a2: the same sums, in place
        A += red.a0
        A += np.multiply.outer(kk * kk, red.a2)
        w, v = np.linalg.eigh(A)
        yield slice(s, s + len(kk)), w, v


def _batched_eig(red: Reduced, k: np.ndarray):
    """Every eigenpair at each k: (K, r) values, (K, r, r) vectors."""
    r = red.a0.shape[0]
    lam, vec = np.empty((len(k), r)), np.empty((len(k), r, r))
    for sl, w, v in _eig_chunks(red, k):
        lam[sl], vec[sl] = w, v
    return lam, vec


def hermite_root(k0, k1, l0, l1, d0, d1, target, n_iter: int = 8):
    """Root in [k0, k1] of the cubic Hermite interpolant of lambda(k) = target."""
    h = k1 - k0
    t = np.clip((target - l0) / np.where(l1 != l0, l1 - l0, 1.0), 0.0, 1.0)
    for _ in range(n_iter):
        t2, t3 = t * t, t * t * t
        p = (2 * t3 - 3 * t2 + 1) * l0 + (t3 - 2 * t2 + t) * h * d0 + (-2 * t3 + 3 * t2) * l1 + (t3 - t2) * h * d1
        dp = (6 * t2 - 6 * t) * l0 + (3 * t2 - 4 * t + 1) * h * d0 + (-6 * t2 + 6 * t) * l1 + (3 * t2 - 2 * t) * h * d1
        t = np.clip(t - (p - target) / np.where(dp > 0, dp, np.inf), 0.0, 1.0)
    return k0 + t * h


def _eig_derivatives(red: Reduced, k: np.ndarray, j: np.ndarray):
    """Eigenpair j at each k with lambda, lambda', lambda'' (perturbation theory) and vector."""
    lam, vec = _batched_eig(red, k)
    a = np.arange(len(k))
    y = vec[a, :, j]
    Ay = y @ red.a1 + 2 * k[:, None] * (y @ red.a2)       # a1, a2 symmetric
    P = np.einsum("pij,pi->pj", vec, Ay)             # Y^T A' y
    lj = lam[a, j]
    d1 = P[a, j]
    gap = lj[:, None] - lam
    gap[a, j] = np.inf
    with np.errstate(divide="ignore"):
        d2 = 2 * np.einsum("pi,ij,pj->p", y, red.a2, y) + 2 * np.sum(P * P / gap, axis=1)
    return lj, d1, d2, y


def solve_branches(red: Reduced, omega: np.ndarray, branches: np.ndarray, n_grid: int = 64,
                    tol: float = 1e-9, max_iter: int = 6, grid: tuple | None = None):
    """Wavenumber of branch j at each omega (largest root). Returns k, cg, y (reduced vectors).

    ``omega`` and ``branches`` are paired 1D arrays. A Hermite (value +
    eigenvector slope) interpolant on a k-grid gives the start; each pair then
    needs one eigen-solve: a second-order step with lambda'' from perturbation
    theory, repeated only where the step is not negligible. NaN where the
    branch does not reach omega. ``grid`` = (k ascending, lambda, slope), the
    branches' samples at hand (``Branches.nodes``), replaces the n_grid-point
    grid's eigen-solves (the start only: the roots move by round-off).
    """
    if grid is not None:
        kg, lam, dl = grid
    else:
        kg = np.linspace(0.0, red.kmax, n_grid)
        lam, vec = _batched_eig(red, kg)
        Ap = red.a1[None] + 2 * kg[:, None, None] * red.a2[None]
        dl = np.sum(vec * (Ap @ vec), axis=1)     # matmul: the 3-operand einsum cost ~10x more
    w2 = omega ** 2
    k = np.full(omega.shape, np.nan)
    for j in sorted(set(branches.tolist())):     # not np.unique: it imports numpy.ma (~0.07 s CPU)
        sel = np.nonzero(branches == j)[0]
        L, D = lam[:, j], dl[:, j]
        cross = (L[None, :-1] <= w2[sel, None]) & (L[None, 1:] > w2[sel, None])
        has = cross.any(axis=1) & (omega[sel] > 0)
        n = cross.shape[1] - 1 - np.argmax(cross[:, ::-1], axis=1)    # last crossing: largest root
        kk = hermite_root(kg[n], kg[n + 1], L[n], L[n + 1], D[n], D[n + 1], w2[sel])
        k[sel] = np.where(has, kk, np.nan)
    idx = np.nonzero(np.isfinite(k))[0]
    kk, jj, ww = k[idx], branches[idx], w2[idx]
    cg = np.full(len(idx), np.nan)
    y = np.zeros((len(idx), red.a0.shape[0]))
    ok = np.zeros(len(idx), bool)
    act = np.arange(len(idx))
    scale = float(np.abs(np.linalg.eigvalsh(red.a0 + red.kmax * red.a1 + red.kmax ** 2 * red.a2)).max())
    for _ in range(max_iter):
        if len(act) == 0:
            break
        lj, d1, d2, ya = _eig_derivatives(red, kk[act], jj[act])
        c = lj - ww[act]
        disc = d1 * d1 - 2.0 * d2 * c
        with np.errstate(invalid="ignore", divide="ignore"):
            q = -0.5 * (d1 + np.sqrt(np.maximum(disc, 0.0)))
            delta = np.where((disc > 0) & (d1 > 0) & (np.abs(d2 * c) < 0.25 * d1 * d1), c / q, -c / d1)
        delta = np.where(np.isfinite(delta), delta, 0.0)
        knew = kk[act] + delta
        y[act] = ya
        cg[act] = (d1 + d2 * delta) / (2.0 * np.sqrt(ww[act]))
        noise = 1e-13 * scale
        small = (np.abs(delta) <= tol * kk[act]) | (np.abs(c) <= noise + 1e-13 * ww[act])
        resid_ok = np.abs(c) <= 1e-6 * ww[act] + noise
        kk[act] = np.where(knew > 0, knew, 0.5 * kk[act])
        ok[act[small & resid_ok]] = True
        act = act[~(small & resid_ok)]
    kout = np.full(omega.shape, np.nan); cgo = np.full(omega.shape, np.nan)
    kout[idx] = np.where(ok, kk, np.nan)
    cgo[idx] = np.where(ok, cg, np.nan)
    yout = np.full((len(omega), red.a0.shape[0]), np.nan)
    yout[idx] = y
    return kout, cgo, yout


# ---------------------------------------------------------------------------
# Chebyshev representation of the branches of a reduced class model
@dataclass(frozen=True)
class Branches:
    """Chebyshev series in k on [0, kmax] of lambda_j = w_j^2 and of its
    eigenvector slope lambda_j' = y^T A'(k) y, for branches j < nb; plus any
    extra eigenvector-derived series (``extra``: name -> (n+1, nb) coeffs)."""

    kmax: float
    lam: np.ndarray           # (n+1, nb) Chebyshev coefficients
    dlam: np.ndarray          # (n+1, nb)
    converged: np.ndarray     # (nb,) bool: tail below tolerance
    extra: dict
    nodes: tuple | None = None   # (k ascending, lambda, slope) at the sampled nodes (eigenvector runs)


def dct1(v: np.ndarray) -> np.ndarray:
    """The DCT-I along axis 0, unnormalised (``scipy.fft.dct(v, type=1, axis=0)``): the real FFT
    of the even extension [v_0 .. v_n .. v_1] (numpy's FFT: scipy.fft and the scipy.special it
    imports cost the dispersion command ~0.07 s CPU at start-up; equal to 1e-15, test_safe.py)."""
    return np.fft.rfft(np.concatenate([v, v[-2:0:-1]], axis=0), axis=0).real


def _dct1_coeffs(v: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients from values at Lobatto points x_i = cos(pi i / n), axis 0."""
    n = v.shape[0] - 1
    a = dct1(v) / n
    a[0] /= 2.0
    a[-1] /= 2.0
    return a


def cheb_branches(red: Reduced, nb: int, n0: int = 32, n_max: int = 256, tol: float = 1e-11,
                   probes: np.ndarray | None = None, n_vec: int | None = None, n_rigid: int = 1,
                   inplane_rows: tuple[int, ...] = ()) -> Branches:
    """Sample branches 0..nb-1 at nested Chebyshev-Lobatto points until the tail converges.

    ``probes`` (m, r): rows p such that the sign-free products (p . y)(q . y) of
    every pair are also interpolated (the transient's surface amplitudes).
    ``n_vec``: if given, lambda is sampled with eigenvalues only (cheaper) and
    the eigenvector series (products) use a fixed grid of n_vec + 1 nodes; the
    slope series is then the derivative of the lambda series. ``n_rigid``: the class's
    zero-frequency branches; with more than one, the products of the ``inplane_rows`` probes
    (in-plane components) take their k = 0 node from k > 0 (below).
    """
    kmax = red.kmax
    n = n0
    x = np.cos(np.pi * np.arange(n + 1) / n)
    ks = kmax * (1.0 - x) / 2.0            # x = 1 -> k = 0
    vals = _sample(red, ks, nb, None if n_vec else probes, values_only=bool(n_vec))
    while True:
        lam_c = _dct1_coeffs(vals[0])
        scale = np.max(np.abs(lam_c), axis=0)
        tail = np.max(np.abs(lam_c[-3:]), axis=0) / scale
        conv = tail < tol
        if conv.all() or 2 * n > n_max:
            break
        # nested refinement: new points at odd indices of the 2n grid
        x_new = np.cos(np.pi * (2 * np.arange(n) + 1) / (2 * n))
        new = _sample(red, kmax * (1.0 - x_new) / 2.0, nb, None if n_vec else probes,
                      values_only=bool(n_vec))
        merged = []
        for old, nw in zip(vals, new):
            m = np.empty((2 * n + 1,) + old.shape[1:])
            m[0::2] = old
            m[1::2] = nw
            merged.append(m)
        vals = merged
        n *= 2
    coeffs = [_dct1_coeffs(v) for v in vals]
    extra = {}
    if n_vec:
        dl = np.zeros_like(coeffs[0])
        dl[:-1] = npcheb.chebder(coeffs[0]) * (-2.0 / kmax)
        if probes is not None:
            xv = np.cos(np.pi * np.arange(n_vec + 1) / n_vec)
            kv = kmax * (1.0 - xv) / 2.0
            pv = _sample(red, kv, nb, probes)
            if n_rigid > 1 and inplane_rows:
                # at k = 0 the in-plane translations share lambda = 0: the eigenvectors there are
                # any mix of u and v, and that one node leaked S0's surface u into SH0's u u
                # product series (-22..-42 dB at 20-300 kHz along 0 deg of the bench's [0/+-45]2s;
                # the exact vectors at k > 0 and the independent Legendre model: < -55 dB; issue
                # 24, session 25). Those products take the vectors at half the next node's k
                # (a change of O((k / kmax)^2) < 1e-6); u w and w w are ~0 for both translations
                # and keep k = 0 (a normal force's transfer is unchanged)
                m = probes.shape[0]
                cols = [p * m + q for p in inplane_rows for q in inplane_rows]
                pv[2][0, cols] = _sample(red, np.array([0.5 * kv[1]]), nb, probes)[2][0, cols]
            extra = {"prod": _dct1_coeffs(pv[2])}
        return Branches(kmax, coeffs[0], dl, conv, extra)
    if probes is not None:
        extra = {"prod": coeffs[2]}
    return Branches(kmax, coeffs[0], coeffs[1], conv, extra, (_lobatto_k(kmax, n), vals[0], vals[1]))


def _lobatto_k(kmax: float, n: int) -> np.ndarray:
    """The n + 1 Chebyshev-Lobatto wavenumbers of a series on [0, kmax], ascending."""
    return kmax * (1.0 - np.cos(np.pi * np.arange(n + 1) / n)) / 2.0


def _sample(red: Reduced, ks: np.ndarray, nb: int, probes=None, values_only: bool = False):
    if values_only:
        A = red.a0[None] + ks[:, None, None] * red.a1[None] + (ks * ks)[:, None, None] * red.a2[None]
        return [np.linalg.eigvalsh(A)[:, :nb]]
    parts = []
    for sl, lam, vec in _eig_chunks(red, ks):       # per chunk: only nb columns are kept
        y = vec[:, :, :nb]                                   # (K, r, nb)
        k = ks[sl]
        Ay = red.a1 @ y + 2 * k[:, None, None] * (red.a2 @ y)   # matmul, not einsum: ~7x faster
        out = [lam[:, :nb], np.einsum("kib,kib->kb", y, Ay)]
        if probes is not None:
            pv = np.einsum("mr,krb->kmb", probes, y)         # (K, m, nb)
            out.append(np.einsum("kmb,knb->kmnb", pv, pv).reshape(len(k), -1, nb))
        parts.append(out)
    return [np.concatenate(p) for p in zip(*parts)]


def dense_table(br: Branches, j: int, n: int = 4096):
    """Branch j on n+1 Chebyshev-Lobatto wavenumbers (ascending) via one DCT per series.

    Returns (k, lam, dlam, extra) where extra has the surface products if present.
    """
    def vals(c):
        c = c[:n + 1]
        b = np.zeros((n + 1,) + c.shape[1:])
        b[:c.shape[0]] = c
        b[1:n] *= 0.5
        return dct1(b)

    x = np.cos(np.pi * np.arange(n + 1) / n)
    k = br.kmax * (1.0 - x) / 2.0
    extra = {name: vals(c[..., j]) for name, c in br.extra.items()}
    return k, vals(br.lam[:, j]), vals(br.dlam[:, j]), extra


def invert_table(k, lam, dlam, omega):
    """Largest root of lam(k) = omega^2 from a dense table (cubic Hermite in each interval).

    Returns (k_root, interval index i, fraction t) with NaN where there is no root.
    """
    suffix_min = np.minimum.accumulate(lam[::-1])[::-1]
    w2 = omega ** 2
    i = np.searchsorted(suffix_min, w2, side="right") - 1       # last i with lam_i <= w2
    has = (i >= 0) & (i < len(k) - 1) & (omega > 0)
    i = np.clip(i, 0, len(k) - 2)
    kr = hermite_root(k[i], k[i + 1], lam[i], lam[i + 1], dlam[i], dlam[i + 1], w2, n_iter=3)
    t = (kr - k[i]) / (k[i + 1] - k[i])
    return np.where(has, kr, np.nan), i, t



def solve_full(cls: DofClass, omega: float, j: int, k: float, tol: float = 1e-12):
    """Reference: Newton on branch j of the full (unreduced) class model from start k.

    Slow; used by tests and benchmarks to check the reduced solver.
    """
    for _ in range(50):
        lam, vec = _eig_at(cls, k, j + 1)
        psi = vec[:, j]
        d = psi @ (cls.A1 + 2 * k * cls.A2) @ psi
        step = (lam[j] - omega ** 2) / d
        k -= step
        if abs(step) < tol * k:
            break
    lam, vec = _eig_at(cls, k, j + 1)
    psi = vec[:, j]
    return k, psi @ (cls.A1 + 2 * k * cls.A2) @ psi / (2 * omega)
