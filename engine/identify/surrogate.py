"""A cheap global stage for modal data: Rayleigh-Ritz frequencies over a box of constants.

The plate's stiffness matrix is linear in the ply stiffness components q = (Q11, Q12,
Q22, Q66, G13, G23) (``engine.plate.Q_NAMES``; springs add a constant part), and its
mass matrix does not depend on the elastic constants. Projected on a basis V (the modes
solved at the start, and for each searched constant raised by ``SPREAD`` one shift-invert
block (K(p) - sigma M)^-1 M V_start), K_r(p) = V^T K(p) V is the same linear combination
of seven small matrices, recovered exactly from K_r at seven parameter sets. One
prediction is then a dense eigenproblem of a few hundred unknowns (milliseconds)
instead of a sparse solve (0.2-0.4 s): :func:`global_search` ranks a space-filling set
of candidates in a box of +-``BOX_REL`` around the start by their penalised pairing
cost (:func:`engine.forward.pairing.assign`), so that a local fit from the best one
starts near the right optimum and with the right pairing, not from a datasheet value
30 % off; :func:`refine` then moves a candidate to the surrogate's own minimum over every
fitted elastic constant (analytic Ritz Jacobian), so that the FE fit starts near it.

Units SI: Pa, Hz.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..laminate import PhysicsError
from ..plate.sparse import symmetric_lu
from ..plate.stiffness import q_derivatives, q_vector
from ..forward.pairing import assign
from .sobol import sobol

__all__ = ["RitzSurrogate", "global_search", "refine", "SPREAD", "BOX_REL", "N_CANDIDATES",
           "REFINE_PRIOR", "REFINE_ROUNDS"]

#: relative change of each searched constant at which basis modes are solved
SPREAD = 0.3
#: the searched box: start x / (1 + BOX_REL) .. start x (1 + BOX_REL), log-uniform
BOX_REL = 0.5
#: candidates ranked (scrambled Sobol points)
N_CANDIDATES = 128
#: basis directions kept: eigenvalues of V'MV above this fraction of the largest
BASIS_DROP = 1e-12


class RitzSurrogate:
    """Rayleigh-Ritz frequencies of ``model`` (a ``PlateModel``) near ``start``.

    ``start``: every elastic constant of the material (contract names, no density);
    ``names``: the constants the basis spans (each raised by SPREAD);
    ``n_modes``: modes solved at the start (the columns of each block) and returned per prediction;
    ``solve``: optional ``params -> Modes`` of ``n_modes`` modes (e.g. a memoised
    ``ModalForward.modes_at``) used instead of ``model.solve``.
    """

    def __init__(self, model, start: Mapping[str, float], names: Sequence[str], n_modes: int,
                 material: str | None = None, solve=None):
        self.model, self.material, self.n = model, material, int(n_modes)
        self.start = dict(start)
        pts = [dict(start)]
        for n in names:
            p = dict(start)
            p[n] = start[n] * (1.0 + SPREAD)
            pts.append(p)
        first = (model.solve(self.n, params=pts[0], material=material) if solve is None else solve(pts[0]))
        _, M = model.matrices(dict(start), material)
        vecs = [first.shapes]
        # the other points need a span, not converged modes: one shift-invert block
        # (K(p) - sigma M)^-1 M V_start each (a factorisation and one solve of n columns)
        # instead of a Lanczos solve per point (~4x its CPU)
        # on the DOFs the start's modes move (a symmetric layup's bending modes leave the
        # membrane DOFs at 0 and K does not couple them: the same solve, ~3/5 of the size)
        live0 = np.flatnonzero(np.any(first.shapes != 0.0, axis=1))
        M0 = M[live0][:, live0]
        MV = M0 @ first.shapes[live0]
        sigma = -0.1 * float(first.omega2[0])
        for p in pts[1:]:
            try:
                K, _ = model.matrices(p, material)
                Y = np.zeros_like(first.shapes)
                Y[live0] = shift_invert(K[live0][:, live0], M0, sigma, MV)
                vecs.append(Y)
            except (PhysicsError, ValueError, RuntimeError):
                continue
        V = np.hstack(vecs)
        Mr = V.T @ (M @ V)
        w, U = np.linalg.eigh(0.5 * (Mr + Mr.T))
        keep = w > BASIS_DROP * w.max()
        # M-orthonormal basis; not kept (3,125 x ~211 on the demo plate, 5 MB): the surrogate
        # lives on through the fit for refine(), and keeping it raised identify's peak RSS 14 MiB
        T = V @ (U[:, keep] / np.sqrt(w[keep]))
        # the projection needs only the DOFs the basis moves: bending modes of a symmetric
        # layup leave the membrane DOFs exactly 0 (K restricted there: ~1/3 of the entries)
        live = np.flatnonzero(np.any(T != 0.0, axis=1))
        Tl = T[live]
        # K_r at the start and with each constant 10 % up (and down) -> constant part plus
        # one matrix per q component (least squares: exact, K is linear in q)
        factors = (1.1,) if len(start) >= 6 else (1.05, 0.95, 1.1, 0.9)   # isotropic: q not linear in (E, G)
        probes = [dict(start)] + [{**start, k: start[k] * f} for k in start for f in factors]
        rows, mats = [], []
        for p in probes:
            try:
                K, _ = model.matrices(p, material)
            except (PhysicsError, ValueError):   # a probe past the admissible edge: skipped
                continue
            rows.append(np.concatenate([[1.0], self._q(p) / 1e9]))
            mats.append(Tl.T @ (K[live][:, live] @ Tl))
        A = np.array(rows)
        coef, *_ = np.linalg.lstsq(A, np.array(mats).reshape(len(mats), -1), rcond=None)
        self.parts = coef.reshape(A.shape[1], T.shape[1], T.shape[1])

    def _mat(self, params: Mapping[str, float]):
        mats = self.model.laminate.with_params(dict(params), self.material).materials
        return mats[self.material] if self.material else next(iter(mats.values()))

    def _q(self, params: Mapping[str, float]) -> np.ndarray:
        return q_vector(self._mat(params))

    def frequencies_jacobian(self, params: Mapping[str, float], names: Sequence[str]
                             ) -> tuple[np.ndarray, np.ndarray]:
        """(the ``n_modes`` lowest Ritz frequencies (Hz), their derivatives (Hz per unit of
        each of ``names``, shape (n_modes, len(names)))): d(lambda)/dq_j = u' K_j u of the
        Ritz vectors u (K_r is linear in q), chained through ``q_derivatives``."""
        mat = self._mat(params)
        q = np.concatenate([[1.0], q_vector(mat) / 1e9])
        Kr = np.tensordot(q, self.parts, axes=1)
        lam, U = np.linalg.eigh(0.5 * (Kr + Kr.T))
        lam, U = lam[:self.n], U[:, :self.n]
        # u' K_j u for the 6 parts by one batched product (an einsum over the three indices
        # took 25-45 ms on the demo's 211-vector basis, this 2-4 ms)
        dlam_dq = ((self.parts[1:] @ U) * U[None]).sum(axis=1).T / 1e9     # (n, 6) per Pa of q
        dlam = dlam_dq @ q_derivatives(mat, list(names))[:6]
        f = np.sqrt(np.maximum(lam, 0.0)) / (2.0 * np.pi)
        return f, dlam / (8.0 * np.pi ** 2 * np.maximum(f, 1e-300))[:, None]

    def frequencies_hz(self, params: Mapping[str, float]) -> np.ndarray:
        """The ``n_modes`` lowest elastic Ritz frequencies (Hz) at ``params``."""
        q = np.concatenate([[1.0], self._q(params) / 1e9])
        Kr = np.tensordot(q, self.parts, axes=1)
        # the basis holds elastic modes only: no rigid-body (zero) eigenvalue to remove. All
        # eigenvalues (LAPACK syevd) take 1.8 ms against 5.1 ms for the lowest n alone (syevr)
        # on the demo's 211-vector basis; the same values to 3e-15
        lam = np.linalg.eigvalsh(0.5 * (Kr + Kr.T))[:self.n]
        return np.sqrt(np.maximum(lam, 0.0)) / (2.0 * np.pi)


def shift_invert(K, M, sigma: float, MV: np.ndarray) -> np.ndarray:
    """(K - sigma M)^-1 MV (sigma < 0: K - sigma M is positive definite), columns scaled to
    unit M-norm (the basis is M-orthonormalised on a relative threshold)."""
    Y = symmetric_lu(K - sigma * M).solve(MV)
    return Y / np.sqrt(np.maximum(np.einsum("ij,ij->j", Y, M @ Y), 1e-300))


def global_search(surrogate: RitzSurrogate, names: Sequence[str], measured_hz, sigma_hz, *,
                  visible=None, correction=None, tau: float = 0.01, n: int = N_CANDIDATES,
                  seed: int = 0, check=None) -> list[tuple[float, dict[str, float]]]:
    """Candidates (penalised pairing cost, constants), best first, over the box
    +-BOX_REL around the surrogate's start on ``names`` (the others at the start).
    ``correction``: per mode f_fine / f_model; ``check(params)`` may raise for
    inadmissible constants (skipped)."""
    start = surrogate.start
    k = len(names)
    u = sobol(k, n, seed)   # = scipy.stats.qmc.Sobol(k, scramble=True, seed=seed).random(n), without its import
    lo = np.log(1.0 / (1.0 + BOX_REL))
    out = []
    pts = [np.zeros(k)] + list(lo + u * (-2.0 * lo))
    for x in pts:
        p = dict(start)
        for nm, xi in zip(names, x):
            p[nm] = start[nm] * float(np.exp(xi))
        try:
            if check is not None:
                check(p)
            fp = surrogate.frequencies_hz(p)
        except (PhysicsError, ValueError, np.linalg.LinAlgError):
            continue
        if correction is not None:
            c = np.ones(fp.size)
            m = min(fp.size, len(correction))
            c[:m] = np.asarray(correction)[:m]
            fp = fp * c
        a = assign(measured_hz, sigma_hz, fp, None if visible is None else visible[:fp.size], tau)
        out.append((a.cost, p))
    out.sort(key=lambda t: t[0])
    return out


#: log-std of the prior centred on a candidate that a surrogate refinement stays under (the
#: firm stage of engine.fit.estimate's continuation: the poorly constrained constants stay put)
REFINE_PRIOR = 0.3
#: pairing rounds of a refinement (re-paired at each refined point, refitted while it changes)
REFINE_ROUNDS = 3


def refine(surrogate: RitzSurrogate, names: Sequence[str], start: Mapping[str, float], measured_hz,
           sigma_hz, *, visible=None, correction=None, tau: float = 0.01, box=None,
           check=None) -> dict[str, float] | None:
    """A candidate ``start`` moved to the minimum of the surrogate's paired misfit over
    ``names`` (log coordinates, prior REFINE_PRIOR on the log-change, bounds ``box`` {name:
    (low, high)}), re-paired up to REFINE_ROUNDS times; None when it fails (an inadmissible
    point, ``check`` raising, no pair). Why: from a global-stage candidate the local FE fit of
    six constants crawled along a curved valley (G12 against nu12 and G13): the demo's modal
    fit took 15 LM steps (one plate solve each) to go 782 -> 50 in cost; on the surrogate
    that crawl costs milliseconds per step (bench/RESULTS.md, issue 29 session 25)."""
    # here, not at the top: scipy.optimize costs ~0.15-0.3 s CPU to import, and a combined
    # (modal + waves) fit whose own start ranks first (the demo's) never refines
    # (bench/RESULTS.md, issue 29 session 27)
    from scipy.optimize import least_squares  # noqa: PLC0415

    names = [n for n in names if n in start]
    f = np.asarray(measured_hz, float)
    s = np.broadcast_to(np.asarray(sigma_hz, float), f.shape)
    p0 = np.array([start[n] for n in names], float)
    lo = np.full(p0.size, -np.inf)
    hi = np.full(p0.size, np.inf)
    for i, n in enumerate(names):
        a, b = (box or {}).get(n, (0.0, np.inf))
        lo[i] = np.log(a / p0[i]) + 1e-9 if a > 0 else -np.inf
        hi[i] = np.log(b / p0[i]) - 1e-9 if np.isfinite(b) else np.inf
    w = 1.0 / REFINE_PRIOR

    def params(x):
        return {**start, **{n: float(v) for n, v in zip(names, p0 * np.exp(x))}}

    def corr(m):
        c = np.ones(m)
        if correction is not None:
            k = min(m, len(correction))
            c[:k] = np.asarray(correction)[:k]
        return c

    x = np.zeros(p0.size)
    index = None
    try:
        for _ in range(REFINE_ROUNDS):
            fp = surrogate.frequencies_hz(params(x))
            a = assign(f, s, fp * corr(fp.size), None if visible is None else visible[:fp.size], tau)
            if index is not None and np.array_equal(a.index, index):
                break
            index = a.index
            ok = index >= 0
            if not ok.any():
                return None
            j = index[ok]

            def res(x_):
                fp_ = surrogate.frequencies_hz(params(x_))
                return np.concatenate([(fp_[j] * corr(fp_.size)[j] - f[ok]) / s[ok], w * x_])

            def jac(x_):
                fp_, d = surrogate.frequencies_jacobian(params(x_), names)
                rows = d[j] * corr(fp_.size)[j][:, None] / s[ok][:, None] * (p0 * np.exp(x_))[None, :]
                return np.vstack([rows, w * np.eye(x_.size)])

            x = least_squares(res, np.clip(x, lo, hi), jac=jac, bounds=(lo, hi), method="trf",
                              x_scale="jac", xtol=1e-8, ftol=1e-8, max_nfev=100).x
        p = params(x)
        if check is not None:
            check(p)
    except (PhysicsError, ValueError, np.linalg.LinAlgError):
        return None
    return p
