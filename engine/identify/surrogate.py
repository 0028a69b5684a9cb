"""A cheap global stage for modal data: Rayleigh-Ritz frequencies over a box of constants.

The plate's stiffness matrix is linear in the ply stiffness components q = (Q11, Q12,
Q22, Q66, G13, G23) (``engine.plate.Q_NAMES``; springs add a constant part), and its
mass matrix does not depend on the elastic constants. Projected on a basis V of modes
solved at a few parameter sets (the start and the start with each searched constant
raised by ``SPREAD``), K_r(p) = V^T K(p) V is the same linear combination
of seven small matrices, recovered exactly from K_r at seven parameter sets. One
prediction is then a dense eigenproblem of a few hundred unknowns (milliseconds)
instead of a sparse solve (0.2-0.4 s): :func:`global_search` ranks a space-filling set
of candidates in a box of +-``BOX_REL`` around the start by their penalised pairing
cost (:func:`engine.forward.pairing.assign`), so that a local fit from the best one
starts near the right optimum and with the right pairing, not from a datasheet value
30 % off.

Units SI: Pa, Hz.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..laminate import PhysicsError
from ..plate.stiffness import q_vector
from ..forward.pairing import assign
from .sobol import sobol

__all__ = ["RitzSurrogate", "global_search", "SPREAD", "BOX_REL", "N_CANDIDATES"]

#: relative change of each searched constant at which basis modes are solved
SPREAD = 0.3
#: the searched box: start x / (1 + BOX_REL) .. start x (1 + BOX_REL), log-uniform
BOX_REL = 0.5
#: candidates ranked (scrambled Sobol points)
N_CANDIDATES = 128


class RitzSurrogate:
    """Rayleigh-Ritz frequencies of ``model`` (a ``PlateModel``) near ``start``.

    ``start``: every elastic constant of the material (contract names, no density);
    ``names``: the constants the basis spans (each raised by SPREAD);
    ``n_modes``: modes solved per basis point and returned per prediction;
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
        vecs = []
        for p in pts:
            try:
                vecs.append(model.solve(self.n, params=p, material=material).shapes if solve is None
                            else solve(p).shapes)
            except (PhysicsError, ValueError):
                continue
        V = np.hstack(vecs)
        K0, M = model.matrices(dict(start), material)
        Mr = V.T @ (M @ V)
        w, U = np.linalg.eigh(0.5 * (Mr + Mr.T))
        keep = w > 1e-12 * w.max()
        T = V @ (U[:, keep] / np.sqrt(w[keep]))        # M-orthonormal basis
        self.T = T
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

    def _q(self, params: Mapping[str, float]) -> np.ndarray:
        lam = self.model.laminate.with_params(dict(params), self.material)
        mats = lam.materials
        mat = mats[self.material] if self.material else next(iter(mats.values()))
        return q_vector(mat)

    def frequencies_hz(self, params: Mapping[str, float]) -> np.ndarray:
        """The ``n_modes`` lowest elastic Ritz frequencies (Hz) at ``params``."""
        q = np.concatenate([[1.0], self._q(params) / 1e9])
        Kr = np.tensordot(q, self.parts, axes=1)
        # the basis holds elastic modes only: no rigid-body (zero) eigenvalue to remove. All
        # eigenvalues (LAPACK syevd) take 1.8 ms against 5.1 ms for the lowest n alone (syevr)
        # on the demo's 211-vector basis; the same values to 3e-15
        lam = np.linalg.eigvalsh(0.5 * (Kr + Kr.T))[:self.n]
        return np.sqrt(np.maximum(lam, 0.0)) / (2.0 * np.pi)


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
