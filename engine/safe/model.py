"""SAFE model of a layered anisotropic plate: 1D spectral elements through the
thickness, the assembled matrices K0, K1~, K2, M and their uncoupled DOF classes.

Units: SI (m, s, Pa, kg/m^3, Hz, rad/m, m/s); angles in degrees.

Model
-----
Displacement ``u(x, z, t) = N(z) q exp(i(k x - w t))`` with propagation along
the local x axis (the laminate is turned by ``-direction_deg`` about z, so each
ply uses ``rotate_z(C, ply.angle_deg - direction_deg)``). Through the thickness
the plate is meshed by 1D spectral elements (Lagrange polynomials on
Gauss-Lobatto-Legendre nodes), at least one element per ply, with the three
displacement components (u, v, w) at each node. The weak form gives::

    [K0 + i k K1 + k^2 K2 - w^2 M] q = p

with K0, K2, M real symmetric and K1 real antisymmetric, all linear in the ply
stiffnesses (a complex viscoelastic C would only make them complex symmetric).
Because every ply is monoclinic about z (any rotation about z keeps it so),
K1 couples (u, v) to w only; scaling ``w = i w~`` makes the problem real
symmetric for real k::

    [K0 + k K1~ + k^2 K2] q~ = w^2 M q~

so at a given k the frequencies are a symmetric-definite eigenproblem and
the group velocity follows from the eigenvector (Hellmann-Feynman)::

    c_g = dw/dk = q~^T (K1~ + 2 k K2) q~ / (2 w q~^T M q~).

The split into uncoupled classes (mirror symmetry, Lamb / SH) is described in
:mod:`engine.safe.labels`, which names the branches of each class.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre as npleg

from ..laminate import Laminate, stiffness_3d

__all__ = ["TWO_PI", "SafeError", "DofClass", "SafeModel", "safe_model", "default_discretisation",
           "ply_stiffness", "bond_matrix", "class_bases", "coupling", "projected_derivatives"]

TWO_PI = 2.0 * np.pi


class SafeError(ValueError):
    """Invalid request to the SAFE engine (bad frequency grid, unknown mode...)."""


# ---------------------------------------------------------------------------
# 1D spectral element
@lru_cache(maxsize=64)
def _reference_element(p: int):
    """GLL nodes and reference matrices on [-1, 1] for order p.

    Returns (xi, Mref, Sref, Gref): Mref_ij = int N_i N_j, Sref_ij = int N_i' N_j',
    Gref_ij = int N_i' N_j (derivatives w.r.t. xi).
    """
    if p < 1:
        raise SafeError(f"element order {p}: expected >= 1")
    inner = npleg.Legendre.basis(p).deriv().roots() if p > 1 else np.array([])
    xi = np.concatenate([[-1.0], np.sort(np.real(inner)), [1.0]])
    xq, wq = npleg.leggauss(p + 2)
    coef = np.linalg.inv(npleg.legvander(xi, p))       # Legendre coefficients of each N_j
    N = npleg.legvander(xq, p) @ coef                   # (nq, n)
    dcoef = np.stack([npleg.legder(coef[:, j]) for j in range(p + 1)], axis=1)
    dN = npleg.legvander(xq, p - 1) @ dcoef if p > 1 else np.tile(dcoef, (len(xq), 1))
    Mref = (N * wq[:, None]).T @ N
    Sref = (dN * wq[:, None]).T @ dN
    Gref = (dN * wq[:, None]).T @ N
    return xi, Mref, Sref, Gref


# strain = Lx du/dx + Lz du/dz, Voigt (11, 22, 33, 23, 13, 12), u = (u, v, w)
_LX = np.zeros((6, 3)); _LX[0, 0] = 1.0; _LX[4, 2] = 1.0; _LX[5, 1] = 1.0
_LZ = np.zeros((6, 3)); _LZ[2, 2] = 1.0; _LZ[3, 1] = 1.0; _LZ[4, 0] = 1.0


def bond_matrix(angle_deg: float) -> np.ndarray:
    """6x6 Bond stress matrix of a rotation by +angle about z (Voigt 11,22,33,23,13,12).

    ``bond_matrix(t) @ C @ bond_matrix(t).T`` equals ``laminate.rotate_z(C, t)``. Cached per
    angle (read-only array): ~50 us of Python loops, called per ply by every SAFE assembly.
    """
    return _bond_matrix(float(angle_deg))


@lru_cache(maxsize=256)
def _bond_matrix(angle_deg: float) -> np.ndarray:
    t = np.deg2rad(angle_deg)
    c, s = np.cos(t), np.sin(t)
    a = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    p = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
    M = np.empty((6, 6))
    for I, (i, j) in enumerate(p):
        for J, (k, l) in enumerate(p):
            M[I, J] = a[i, k] * a[j, l] if J < 3 else a[i, k] * a[j, l] + a[i, l] * a[j, k]
    M.flags.writeable = False
    return M


def ply_stiffness(laminate: Laminate, direction_deg: float) -> list[np.ndarray]:
    """3D stiffness of each ply in propagation axes (x along direction_deg), Pa."""
    cache: dict = {}
    out = []
    for ply in laminate.plies:
        key = (id(ply.material), ply.angle_deg)
        if key not in cache:
            B = bond_matrix(ply.angle_deg - direction_deg)
            cache[key] = B @ stiffness_3d(ply.material) @ B.T
        out.append(cache[key])
    return out


def default_discretisation(laminate: Laminate, fmax_hz: float) -> tuple[int, int]:
    """(order, elements_per_ply) resolving fmax_hz to ~1e-8 relative in c_g.

    The through-thickness wavenumber is bounded by w/c_s,min (slowest bulk
    shear speed of any ply, times 1.2 for the Rayleigh-like A0 limit); a GLL
    element of length h_e and order p resolves q h_e with error ~ (q h_e / 2p)^(2p)
    (calibrated on the exact Lamb roots; order >= 4, elements of q h_e <= 12).
    """
    q = 0.0
    h_ply = 0.0
    for ply, C in zip(laminate.plies, ply_stiffness(laminate, 0.0)):
        g = min(C[3, 3], C[4, 4], C[5, 5])
        cs = np.sqrt(g / ply.material.density)
        q = max(q, 1.2 * TWO_PI * max(fmax_hz, 1.0) / cs)
        h_ply = max(h_ply, ply.thickness)
    qh = q * h_ply                   # rad across the thickest ply
    n_el = max(1, int(np.ceil(qh / 12.0)))
    qe = qh / n_el
    p = 4
    while p < 24 and (qe / (2.0 * p)) ** (2 * p) > 1e-12:
        p += 1
    return p, n_el


# ---------------------------------------------------------------------------
# model assembly
@dataclass(frozen=True)
class DofClass:
    """One uncoupled DOF class, in Cholesky-reduced standard form (M = I)."""

    kind: str                 # 'S','A','SHs','SHa','sym','anti','lamb','sh','all'
    n_rigid: int
    A0: np.ndarray
    A1: np.ndarray
    A2: np.ndarray
    to_phys: np.ndarray       # (ndof, n_c): phi_full = to_phys @ psi  (M-normalised if |psi| = 1)


@dataclass(frozen=True, eq=False)
class SafeModel:
    """Assembled SAFE matrices of a laminate along one direction (real, scaled w~)."""

    direction_deg: float
    order: int
    elements_per_ply: int
    z_nodes: np.ndarray
    K0: np.ndarray
    K1: np.ndarray            # K1~ (real symmetric)
    K2: np.ndarray
    M: np.ndarray
    classes: tuple[DofClass, ...]
    thickness: float
    info: dict = field(default_factory=dict)

    @property
    def ndof(self) -> int:
        return self.K0.shape[0]


def _kron(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    n, m = A.shape[0], B.shape[0]
    return (A[:, None, :, None] * B[None, :, None, :]).reshape(n * m, n * m)


def _assemble(laminate: Laminate, direction_deg: float, order: int, epp: int, Cs=None, rhos=None):
    """z nodes, K0, K1~, K2, M; ``Cs`` (per ply, propagation axes) and ``rhos`` replace the plies'
    stiffness and density (the matrices are linear in both: derivatives assemble the same way)."""
    if Cs is None:
        Cs = ply_stiffness(laminate, direction_deg)
    if rhos is None:
        rhos = [ply.material.density for ply in laminate.plies]
    xi, Mref, Sref, Gref = _reference_element(order)
    n_el = len(laminate.plies) * epp
    n_nodes = n_el * order + 1
    ndof = 3 * n_nodes
    K0 = np.zeros((ndof, ndof)); K1 = np.zeros_like(K0); K2 = np.zeros_like(K0); M = np.zeros_like(K0)
    z = np.empty(n_nodes)
    zi = laminate.z_interfaces
    I3 = np.eye(3)
    e = 0
    for ip, (ply, C) in enumerate(zip(laminate.plies, Cs)):
        Cxx = _LX.T @ C @ _LX; Czz = _LZ.T @ C @ _LZ; Czx = _LZ.T @ C @ _LX
        he = ply.thickness / epp
        J = he / 2.0
        k0 = _kron(Sref / J, Czz)
        k2 = _kron(J * Mref, Cxx)
        k1 = _kron(Gref, Czx) - _kron(Gref.T, Czx.T)
        m = _kron(rhos[ip] * J * Mref, I3)
        for s in range(epp):
            z0 = zi[ip] + s * he
            n0 = e * order
            z[n0:n0 + order + 1] = z0 + (xi + 1.0) * J
            sl = slice(3 * n0, 3 * (n0 + order + 1))
            K0[sl, sl] += k0; K1[sl, sl] += k1; K2[sl, sl] += k2; M[sl, sl] += m
            e += 1
    # w -> i w~ : K~1 = Re(T^H (i K1) T), T = diag(1, 1, i)
    t = np.tile(np.array([1.0, 1.0, 1j]), n_nodes)
    K1t = (np.conj(t)[:, None] * (1j * K1) * t[None, :])
    if np.max(np.abs(K1t.imag)) > 1e-12 * max(np.max(np.abs(K1t.real)), 1e-300):
        raise SafeError("ply stiffness is not monoclinic about z; SAFE scaling w -> i w fails")
    return z, K0, K1t.real.copy(), K2, M


def projected_derivatives(model: SafeModel, laminate: Laminate, derivatives, T: np.ndarray
                          ) -> tuple[np.ndarray, ...]:
    """T^T d(K0, K1~, K2, M)/dp T of ``model`` (assembled from ``laminate``), each (P, r, r).

    ``derivatives``: per parameter p, (dC per ply (6x6, material axes, Pa per unit p), d rho per
    ply); ``T`` (ndof, r). The matrices are linear in the ply stiffness and density, so each
    derivative is the assembly of dC and d rho; projected element by element, all parameters at
    once (assembling a full ndof x ndof matrix per parameter cost 3 ms each, ~20x this)."""
    P = len(derivatives)
    order, epp = model.order, model.elements_per_ply
    _, Mref, Sref, Gref = _reference_element(order)
    n = 3 * (order + 1)
    r = T.shape[1]
    out = np.zeros((4, P, r, r))
    mref3 = _kron(Mref, np.eye(3))
    w_rows = (np.arange(n) % 3 == 2)[:, None]          # K1~ = Dw K1 Dip - Dip K1 Dw (w -> i w~)

    def kr(A, Bp):     # kron(A, B_p) for each p
        return (A[None, :, None, :, None] * Bp[:, None, :, None, :]).reshape(P, n, n)

    for ip, ply in enumerate(laminate.plies):
        dC = np.array([d[0][ip] for d in derivatives], float).reshape(P, 6, 6)
        drho = np.array([d[1][ip] for d in derivatives], float)
        if not (dC.any() or drho.any()):
            continue
        B = bond_matrix(ply.angle_deg - model.direction_deg)
        C = B @ dC @ B.T
        Cxx = _LX.T @ C @ _LX; Czz = _LZ.T @ C @ _LZ; Czx = _LZ.T @ C @ _LX
        J = ply.thickness / epp / 2.0
        k0, k2 = kr(Sref / J, Czz), kr(J * Mref, Cxx)
        k1 = kr(Gref, Czx) - kr(Gref.T, Czx.transpose(0, 2, 1))
        m = (J * drho)[:, None, None] * mref3[None]
        for s_ in range(epp):
            n0 = 3 * (ip * epp + s_) * order
            Te = T[n0:n0 + n]
            Tw, Tip = np.where(w_rows, Te, 0.0), np.where(w_rows, 0.0, Te)
            out[0] += Te.T @ k0 @ Te
            out[1] += Tw.T @ k1 @ Tip - Tip.T @ k1 @ Tw
            out[2] += Te.T @ k2 @ Te
            out[3] += Te.T @ m @ Te
    return out[0], out[1], out[2], out[3]


def coupling(X: np.ndarray, Qa: np.ndarray, Qb: np.ndarray) -> float:
    return float(np.max(np.abs(Qa.T @ X @ Qb)) / max(np.max(np.abs(X)), 1e-300))


def _structure(laminate: Laminate, Cs: list, z: np.ndarray, tol: float = 1e-12) -> tuple[bool, bool]:
    """(mirror_symmetric, sh_decoupled) from the ply data.

    SH/Lamb separate iff every ply has C16 = C36 = C45 = 0 in propagation axes
    (the only terms of K0, K1, K2 coupling v with u, w; C26 never enters).
    Symmetric and antisymmetric modes separate iff the mesh is mirror symmetric
    and mirrored plies have the same stiffness and density.
    """
    scale = max(float(np.max(np.abs(C))) for C in Cs)
    sh = all(max(abs(C[0, 5]), abs(C[2, 5]), abs(C[3, 4])) < tol * scale for C in Cs)
    h = z[-1] - z[0]
    plies = laminate.plies
    n = len(plies)
    # np.max(|a - b|) <= atol is np.allclose(a, b, rtol=0, atol) without its ~0.2 ms per call
    parity = bool(np.allclose(z, -z[::-1], atol=1e-9 * h)) and all(
        float(np.max(np.abs(Cs[i] - Cs[n - 1 - i]))) <= tol * scale
        and plies[i].material.density == plies[n - 1 - i].material.density
        for i in range(n // 2))
    return parity, sh


def class_bases(z: np.ndarray, parity: bool, sh: bool) -> list:
    """Uncoupled DOF classes as (kind, Q, n_rigid), Q with orthonormal columns,
    for through-thickness nodes ``z`` (only their number matters; cached)."""
    return list(_class_bases(len(z), parity, sh))


@lru_cache(maxsize=64)
def _class_bases(n: int, parity: bool, sh: bool):
    """class_bases for n nodes (cached: the arrays are shared, do not modify them)."""
    comps = {"u": 0, "v": 1, "w": 2}

    r2 = 1.0 / np.sqrt(2.0)
    lo = np.arange(n // 2)
    hi = n - 1 - lo
    mid = n // 2 if n % 2 else None

    def cols(comp_names, parity=None):
        """Basis columns for components; parity: dict comp -> +1/-1 (mirror) or None."""
        blocks = []
        for c in comp_names:
            ci = comps[c]
            if parity is None:
                Q = np.zeros((3 * n, n)); Q[3 * np.arange(n) + ci, np.arange(n)] = 1.0
            else:
                eps = parity[c]
                m = len(lo) + (1 if (mid is not None and eps > 0) else 0)
                Q = np.zeros((3 * n, m))
                Q[3 * lo + ci, np.arange(len(lo))] = r2
                Q[3 * hi + ci, np.arange(len(lo))] = eps * r2
                if m > len(lo):
                    Q[3 * mid + ci, -1] = 1.0
            blocks.append(Q)
        return np.concatenate(blocks, axis=1)

    sym = {"u": 1, "v": 1, "w": -1}
    anti = {"u": -1, "v": -1, "w": 1}
    if parity and sh:
        return [("S", cols("uw", sym), 1), ("A", cols("uw", anti), 1),
                ("SHs", cols("v", sym), 1), ("SHa", cols("v", anti), 0)]
    if parity:
        return [("sym", cols("uvw", sym), 2), ("anti", cols("uvw", anti), 1)]
    if sh:
        return [("lamb", cols("uw"), 2), ("sh", cols("v"), 1)]
    return [("all", np.eye(3 * n), 3)]


def safe_model(laminate: Laminate, direction_deg: float = 0.0, *, order: int | None = None,
               elements_per_ply: int | None = None, fmax_hz: float = 1e6) -> SafeModel:
    """Assemble the SAFE model (K0, K1~, K2, M and the uncoupled classes).

    ``order``/``elements_per_ply`` default to :func:`default_discretisation`
    for ``fmax_hz``.
    """
    p0, e0 = default_discretisation(laminate, fmax_hz)
    order = p0 if order is None else int(order)
    epp = e0 if elements_per_ply is None else int(elements_per_ply)
    if order < 1 or epp < 1:
        raise SafeError(f"order={order}, elements_per_ply={epp}: expected integers >= 1")
    Cs = ply_stiffness(laminate, float(direction_deg))
    z, K0, K1, K2, M = _assemble(laminate, float(direction_deg), order, epp, Cs)
    parity, sh = _structure(laminate, Cs, z)
    found = class_bases(z, parity, sh)
    classes = []
    for kind, Q, n_rigid in found:
        Mc = Q.T @ M @ Q
        L = np.linalg.cholesky(Mc)
        Li = np.linalg.solve(L, np.eye(L.shape[0]))   # L^-1 (numpy: no scipy import on this path)

        def std(X):
            Y = Li @ (Q.T @ X @ Q) @ Li.T
            return 0.5 * (Y + Y.T)
        classes.append(DofClass(kind, n_rigid, std(K0), std(K1), std(K2), Q @ Li.T))
    return SafeModel(float(direction_deg), order, epp, z, K0, K1, K2, M, tuple(classes),
                     laminate.thickness, {"mirror_symmetric": parity, "sh_decoupled": sh})
