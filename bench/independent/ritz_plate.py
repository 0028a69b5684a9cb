"""Rayleigh-Ritz free plate: first-order shear (Mindlin) laminate, Legendre bases, quadrature fields.

A second plate model that shares no code with ``engine.plate`` (no element, mesh, assembly
or laminate routine of the engine): the bench's independent generator of natural
frequencies and mode shapes (``bench/blind_independent.py``), checked against exact and
published values (NAFEMS FV12, Leissa's free square plate) and against the engine at a
fine mesh in ``tests/unit/bench/test_ritz_plate.py``.

Kinematics (z from the mid-plane): u = u0 + z phx, v = v0 + z phy, w = w0. Each of the
five fields is a sum of products p_i(xi) p_j(eta), i, j = 0..order, of orthonormal Legendre
polynomials over the plate (xi = 2x/L - 1, eta = 2y/W - 1): no constraint, so the free edges
are natural and the six rigid-body motions are exact members of the basis. Energies:

  U = 1/2 int [e0' A e0 + 2 e0' B k + k' D k + g' H g] dA (+ springs),
  T = 1/2 int [I0 (u0^2 + v0^2 + w0^2) + 2 I1 (u0 phx + v0 phy) + I2 (phx^2 + phy^2)] dA (+ masses),

e0 = (u0,x + z0,x w0,x, v0,y + z0,y w0,y, u0,y + v0,x + z0,x w0,y + z0,y w0,x) (the linear
Marguerre terms of a shallow initial shape z0(x, y); zero for a flat plate),
k = (phx,x, phy,y, phx,y + phy,x), g = (w0,x + phx, w0,y + phy). A, B, D, H (shear factor
5/6) and the inertias are integrated through the plies here (each ply's plane-stress
stiffness rotated as a fourth-order tensor), and over the plate by tensor Gauss quadrature
(composite where a field has corners), so fields come for free:

* thickness field s(x, y): every ply scaled, A, H, I0 ~ s; B, I1 ~ s^2; D, I2 ~ s^3;
* density field r(x, y): I0, I1, I2 ~ r;
* stiffness field c(x, y): A, B, D, H ~ c (a soft patch: c = 1 - loss inside a square);
* point masses (x, y, m) on u0, v0, w0 and grounded transverse springs (x, y, k) on w0.

The generalised eigenproblem K a = omega^2 M a is solved densely (scipy.linalg.eigh); the
rigid-body modes (six, or with springs the three lifted suspension modes plus three at
zero) are recognised by their mass-weighted content in the rigid-body space (> 1/2) and
dropped, as a lab does not list them. Convergence: Ritz frequencies fall monotonically
with the order; :func:`converged_order` finds the order at which the wanted modes move by
less than a tolerance. Units SI (m, kg, s, Pa, Hz); angles in degrees.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
from numpy.polynomial import legendre as npleg
from scipy.linalg import cho_factor, cho_solve
from scipy.sparse.linalg import LinearOperator, eigsh

__all__ = ["Ply", "plies_from_table", "laminate_matrices", "RitzPlate", "RitzModes", "converged_order"]

Field = Callable[[np.ndarray, np.ndarray], np.ndarray]

#: field index of each unknown: u0, v0, w0, phx, phy
U, V, W, PX, PY = range(5)


@dataclass(frozen=True)
class Ply:
    """One ply: constants (E1, E2, nu12, G12, G13, G23 Pa; or isotropic E with nu or G), density
    kg/m^3, fibre angle deg (from x towards y), thickness m."""

    constants: Mapping[str, float]
    density: float
    angle_deg: float
    thickness: float


def plies_from_table(table: Mapping, constants: Mapping[str, float] | None = None,
                     angle_offset: float = 0.0, top_offset: float = 0.0) -> tuple[list[Ply], float, float]:
    """(plies bottom first, length, width) of a specimen table (labid's TOML layout: ``plate``,
    ``materials.NAME``, ``layup`` with ``angles_deg`` and ``ply_thickness``), read here
    directly; ``constants`` replace the material's, ``angle_offset`` turns every ply and
    ``top_offset`` the last one more (deg)."""
    lay = table["layup"]
    mat = dict(table["materials"][lay["material"]])
    mat.update(constants or {})
    rho = float(mat.pop("density"))
    angles = list(lay["angles_deg"])
    t = lay["ply_thickness"]
    ts = list(t) if isinstance(t, (list, tuple)) else [float(t)] * len(angles)
    plies = [Ply(mat, rho, float(a) + angle_offset + (top_offset if i == len(angles) - 1 else 0.0), float(ti))
             for i, (a, ti) in enumerate(zip(angles, ts))]
    return plies, float(table["plate"]["length"]), float(table["plate"]["width"])


def _ply_tensors(p: Ply) -> tuple[np.ndarray, np.ndarray]:
    """(Qbar 3x3 in (x, y, xy) with engineering shear, Gbar 2x2 in (xz, yz)) of a ply."""
    c = p.constants
    if "E" in c:                                    # isotropic
        E = float(c["E"])
        G = float(c["G"]) if "G" in c else E / (2.0 * (1.0 + float(c["nu"])))
        nu = E / (2.0 * G) - 1.0
        E1 = E2 = E
        nu12, G12, G13, G23 = nu, G, G, G
    else:
        E1, E2, nu12 = float(c["E1"]), float(c["E2"]), float(c["nu12"])
        G12, G13, G23 = float(c["G12"]), float(c["G13"]), float(c["G23"])
    # plane-stress compliance in material axes (1, 2, 12), inverted
    S = np.array([[1.0 / E1, -nu12 / E1, 0.0], [-nu12 / E1, 1.0 / E2, 0.0], [0.0, 0.0, 1.0 / G12]])
    Q = np.linalg.inv(S)
    C = np.zeros((2, 2, 2, 2))                      # the same stiffness as a 2D fourth-order tensor
    voigt = {(0, 0): 0, (1, 1): 1, (0, 1): 2, (1, 0): 2}
    for (i, j), a in voigt.items():
        for (k, m), b in voigt.items():
            C[i, j, k, m] = Q[a, b]
    th = np.deg2rad(p.angle_deg)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])   # columns: material axes 1, 2
    Cr = np.einsum("ia,jb,kc,ld,abcd->ijkl", R, R, R, R, C)
    Qb = np.array([[Cr[i, j, k, m] for (k, m) in ((0, 0), (1, 1), (0, 1))] for (i, j) in ((0, 0), (1, 1), (0, 1))])
    Gb = R @ np.diag([G13, G23]) @ R.T
    return Qb, Gb


def laminate_matrices(plies: Sequence[Ply], shear_factor: float = 5.0 / 6.0) -> dict[str, np.ndarray]:
    """A, B, D (3x3; N/m, N, N m), H (2x2, N/m, shear factor included) and I0, I1, I2
    (kg/m^2, kg/m, kg) of the plies (bottom first, mid-plane at z = 0)."""
    z = np.concatenate([[0.0], np.cumsum([p.thickness for p in plies])])
    z -= z[-1] / 2.0
    out = {k: np.zeros((3, 3)) for k in "ABD"}
    out["H"] = np.zeros((2, 2))
    inert = np.zeros(3)
    for p, z0, z1 in zip(plies, z[:-1], z[1:]):
        Qb, Gb = _ply_tensors(p)
        m = [(z1 ** (k + 1) - z0 ** (k + 1)) / (k + 1) for k in range(3)]
        out["A"] += Qb * m[0]
        out["B"] += Qb * m[1]
        out["D"] += Qb * m[2]
        out["H"] += shear_factor * Gb * m[0]
        inert += p.density * np.array(m)
    out["I"] = inert
    return out


#: decay lengths of the edge-layer functions, in plate thicknesses (see :class:`Basis1D`)
LAYERS = (0.5, 2.0)


class Basis1D:
    """One direction's Ritz functions on [0, length], orthonormalised in L2.

    Legendre polynomials of degree 0..``order`` (the rigid-body motions and the smooth part)
    plus, for every decay length d in ``layers`` (m), exp(-x/d) and exp(-(length - x)/d): a
    free edge of a Mindlin plate carries a boundary layer a few thicknesses wide that global
    polynomials resolve only slowly (measured, CFRP 0.33 m x 1.6 mm: mode 1 still falls by
    2e-4 per two orders at order 20 without them). Functions that the others already span
    (Gram eigenvalue < 1e-11 of the largest) are dropped.
    """

    def __init__(self, length: float, order: int, layers: Sequence[float] = ()):
        self.length, self.order, self.layers = float(length), int(order), tuple(float(d) for d in layers)
        x, w = graded_rule(self.length, self.order, self.layers, (), fine=True)
        P, _ = self._raw(x)
        G = P.T @ (w[:, None] * P)
        ev, vec = np.linalg.eigh(G)
        keep = ev > 1e-11 * ev.max()
        self.T = vec[:, keep] / np.sqrt(ev[keep])
        self.size = int(keep.sum())

    def _raw(self, x) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, float)
        L, n = self.length, self.order
        xi = 2.0 * x / L - 1.0
        P = npleg.legvander(xi, n)
        D = np.zeros((n + 1, n + 1))
        for k in range(n + 1):
            d = npleg.legder(np.eye(n + 1)[k])
            D[:d.size, k] = d
        dP = (P @ D) * (2.0 / L)
        vals, ders = [P], [dP]
        for d in self.layers:
            a, b = np.exp(-x / d), np.exp(-(L - x) / d)
            vals.append(np.column_stack([a, b]))
            ders.append(np.column_stack([-a / d, b / d]))
        return np.hstack(vals), np.hstack(ders)

    def at(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(values, d/dx) of the orthonormal functions at points x (m): (n_points, size) each."""
        P, dP = self._raw(np.atleast_1d(x))
        return P @ self.T, dP @ self.T


def graded_rule(length: float, order: int, layers: Sequence[float] = (), breaks: Sequence[float] = (),
                fine: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre points and weights on [0, length]: panels graded towards both
    edges from the shortest decay length in ``layers`` (x3 per panel up to a third of the
    length), split at ``breaks`` (a field's kinks or jumps); order + 4 points in a panel longer
    than a tenth of the length, 8 in the shorter ones (``fine``: twice as many everywhere)."""
    edges = [0.0, length, *np.asarray(breaks, float)]
    if layers:
        e = min(layers)
        while e < length / 3.0:
            edges += [e, length - e]
            e *= 3.0
    if not layers or len(edges) <= 3:
        edges += [length / 3.0, 2.0 * length / 3.0]
    edges = np.unique(np.clip(edges, 0.0, length))
    x, w = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a <= 1e-12 * length:
            continue
        nq = order + 4 if b - a > length / 10.0 else 8
        g, wg = npleg.leggauss(2 * nq if fine else nq)
        x.append(a + (g + 1.0) * (b - a) / 2.0)
        w.append(wg * (b - a) / 2.0)
    return np.concatenate(x), np.concatenate(w)


@dataclass(frozen=True)
class RitzModes:
    """Elastic modes, ascending: frequencies (Hz), eigenvectors (n_dof, n; M-normalised), and
    the suspension frequencies (Hz) of the rigid-body modes that were dropped."""

    frequencies_hz: np.ndarray
    vectors: np.ndarray
    rigid_hz: np.ndarray


@dataclass
class RitzPlate:
    """Free rectangular Mindlin plate by Rayleigh-Ritz (see module docstring).

    ``plies``: bottom first; ``order``: highest Legendre degree per direction (plus the
    edge-layer functions of :class:`Basis1D`, decay lengths ``LAYERS`` x the thickness);
    ``breaks_x``/``breaks_y``: quadrature panel edges where a field has a kink or a jump;
    ``curvature``: (kx, ky) of a shallow initial shape z0 = -(kx (x - L/2)^2 + ky (y - W/2)^2)/2
    (1/m; anticlastic when ky = -kx).
    """

    plies: Sequence[Ply]
    length: float
    width: float
    order: int = 12
    thickness_field: Field | None = None
    density_field: Field | None = None
    stiffness_field: Field | None = None
    masses: Sequence[tuple[float, float, float]] = ()
    springs: Sequence[tuple[float, float, float]] = ()
    curvature: tuple[float, float] = (0.0, 0.0)
    breaks_x: Sequence[float] = ()
    breaks_y: Sequence[float] = ()
    shear_factor: float = 5.0 / 6.0
    layers: Sequence[float] = LAYERS
    _cache: dict = field(default_factory=dict, init=False, repr=False)

    def _bases(self) -> tuple[Basis1D, Basis1D]:
        if "bases" not in self._cache:
            h = sum(p.thickness for p in self.plies)
            lay = tuple(f * h for f in self.layers)
            self._cache["bases"] = (Basis1D(self.length, self.order, lay), Basis1D(self.width, self.order, lay))
        return self._cache["bases"]

    @property
    def n_basis(self) -> int:
        bx, by = self._bases()
        return bx.size * by.size

    def basis_at(self, x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(value, d/dx, d/dy) of every 2D basis function at points (x, y): each (n_points, n_basis)."""
        bx, by = self._bases()
        Px, dPx = bx.at(x)
        Py, dPy = by.at(y)
        prod = lambda a, b: (a[:, :, None] * b[:, None, :]).reshape(len(a), -1)   # noqa: E731
        return prod(Px, Py), prod(dPx, Py), prod(Px, dPy)

    def _grid(self) -> tuple:
        """1D rules and basis tables: (x, wx, (Px, dPx)), (y, wy, (Py, dPy))."""
        if "grid" not in self._cache:
            bx, by = self._bases()
            x, wx = graded_rule(self.length, self.order, bx.layers, self.breaks_x)
            y, wy = graded_rule(self.width, self.order, by.layers, self.breaks_y)
            self._cache["grid"] = ((x, wx, bx.at(x)), (y, wy, by.at(y)))
        return self._cache["grid"]

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """Stiffness K (N/m) and mass M (kg) in the Ritz coefficients (5 blocks of n_basis)."""
        if "KM" in self._cache:
            return self._cache["KM"]
        lam = laminate_matrices(self.plies, self.shear_factor)
        (x, wx, _), (y, wy, _) = self._grid()
        X, Y = np.meshgrid(x, y, indexing="ij")
        w = np.outer(wx, wy)
        one = np.ones_like(X)
        s = one if self.thickness_field is None else np.asarray(self.thickness_field(X, Y), float) * one
        c = one if self.stiffness_field is None else np.asarray(self.stiffness_field(X, Y), float) * one
        r = one if self.density_field is None else np.asarray(self.density_field(X, Y), float) * one
        # strains = (T0 + z0,x Tx + z0,y Ty) g, g the generalised gradients (field, op): index
        # 3 * field + op (op 0 value, 1 d/dx, 2 d/dy); strains e0 (3), k (3), g (2)
        T0, Tx, Ty = np.zeros((3, 8, 15))
        T0[0, 3 * U + 1] = T0[1, 3 * V + 2] = T0[2, 3 * U + 2] = T0[2, 3 * V + 1] = 1.0
        T0[3, 3 * PX + 1] = T0[4, 3 * PY + 2] = T0[5, 3 * PX + 2] = T0[5, 3 * PY + 1] = 1.0
        T0[6, 3 * W + 1] = T0[6, 3 * PX] = T0[7, 3 * W + 2] = T0[7, 3 * PY] = 1.0
        Tx[0, 3 * W + 1] = Tx[2, 3 * W + 2] = 1.0          # times z0,x
        Ty[1, 3 * W + 2] = Ty[2, 3 * W + 1] = 1.0          # times z0,y
        kx, ky = self.curvature
        maps = [(T0, one)] + ([(Tx, -kx * (X - self.length / 2.0))] if kx else []) \
            + ([(Ty, -ky * (Y - self.width / 2.0))] if ky else [])
        blocks = []
        for part, power, rows, cols in (("A", 1, slice(0, 3), slice(0, 3)), ("B", 2, slice(0, 3), slice(3, 6)),
                                        ("D", 3, slice(3, 6), slice(3, 6)), ("H", 1, slice(6, 8), slice(6, 8))):
            Ct = np.zeros((8, 8))
            Ct[rows, cols] = lam[part]
            if part == "B":
                Ct[cols, rows] = lam[part].T
            blocks.append((Ct, c * s ** power))
        # energy density g' E g, E = sum of scalar fields times constant 15 x 15 matrices
        F, mats = [], []
        for Ct, ft in blocks:
            for Tu, gu in maps:
                for Tv, gv in maps:
                    F.append(ft * gu * gv * w)
                    mats.append(Tu.T @ Ct @ Tv)
        K = self._assemble(np.tensordot(np.array(F), np.array(mats), axes=(0, 0)))
        I0, I1, I2 = lam["I"]
        F, mats = [], []
        for pairs, val in ((((U, U), (V, V), (W, W)), I0 * s), (((PX, PX), (PY, PY)), I2 * s ** 3),
                           (((U, PX), (V, PY)), I1 * s ** 2)):
            m = np.zeros((15, 15))
            for a, b in pairs:
                m[3 * a, 3 * b] = m[3 * b, 3 * a] = 1.0
            F.append(val * r * w)
            mats.append(m)
        M = self._assemble(np.tensordot(np.array(F), np.array(mats), axes=(0, 0)))
        nb = self.n_basis
        for x0, y0, m in self.masses:
            phi = self.basis_at(x0, y0)[0][0]
            for f in (U, V, W):
                M[f * nb:(f + 1) * nb, f * nb:(f + 1) * nb] += m * np.outer(phi, phi)
        for x0, y0, k in self.springs:
            phi = self.basis_at(x0, y0)[0][0]
            K[W * nb:(W + 1) * nb, W * nb:(W + 1) * nb] += k * np.outer(phi, phi)
        self._cache["KM"] = (K, M)
        return K, M

    def _assemble(self, E: np.ndarray) -> np.ndarray:
        """sum over the grid of G_a' E_ab G_b for every nonzero pair of generalised gradients
        (E symmetric: the pair (a, b) gives X, its mirror X'), by sum factorisation over the
        tensor grid: first y, then x."""
        (_, _, (Px, dPx)), (_, _, (Py, dPy)) = self._grid()
        opx, opy = (Px, dPx, Px), (Py, Py, dPy)
        nbx, nby = Px.shape[1], Py.shape[1]
        nb = nbx * nby
        K = np.zeros((5 * nb, 5 * nb))
        nz = np.any(E != 0.0, axis=(0, 1))
        for a in range(15):
            for b in range(a, 15):
                if not nz[a, b]:
                    continue
                e = E[:, :, a, b]
                Ay, By, Ax, Bx = opy[a % 3], opy[b % 3], opx[a % 3], opx[b % 3]
                Ty = np.matmul((e[:, :, None] * Ay[None]).transpose(0, 2, 1), By)       # (nqx, j, l)
                AB = (Ax[:, :, None] * Bx[:, None, :]).reshape(len(Ax), -1)            # (nqx, i k)
                X = (AB.T @ Ty.reshape(len(Ax), -1)).reshape(nbx, nbx, nby, nby)
                X = X.transpose(0, 2, 1, 3).reshape(nb, nb)                            # (i j, k l)
                fa, fb = a // 3, b // 3
                K[fa * nb:(fa + 1) * nb, fb * nb:(fb + 1) * nb] += X
                if a != b:
                    K[fb * nb:(fb + 1) * nb, fa * nb:(fa + 1) * nb] += X.T
        return K

    def rigid_vectors(self) -> np.ndarray:
        """(n_dof, 6) Ritz coefficients of the rigid-body motions: translations x, y, z, rotation
        about z, and the two tilts (w = x - L/2 with phx = -1; w = y - W/2 with phy = -1); from
        1D least-squares fits of 1 and of the centred coordinate (exact: Legendre degree <= 1)."""
        nb = self.n_basis
        coef = []
        for b, length in zip(self._bases(), (self.length, self.width)):
            t = np.linspace(0.0, length, 4 * b.size)
            P = b.at(t)[0]
            coef.append((np.linalg.lstsq(P, np.ones_like(t), rcond=None)[0],
                         np.linalg.lstsq(P, t - length / 2.0, rcond=None)[0]))
        (ox, xx), (oy, yy) = coef
        one, xc, yc = np.kron(ox, oy), np.kron(xx, oy), np.kron(ox, yy)
        R = np.zeros((5 * nb, 6))
        R[U * nb:(U + 1) * nb, 0] = one
        R[V * nb:(V + 1) * nb, 1] = one
        R[W * nb:(W + 1) * nb, 2] = one
        R[U * nb:(U + 1) * nb, 3], R[V * nb:(V + 1) * nb, 3] = -yc, xc
        R[W * nb:(W + 1) * nb, 4], R[PX * nb:(PX + 1) * nb, 4] = xc, -one
        R[W * nb:(W + 1) * nb, 5], R[PY * nb:(PY + 1) * nb, 5] = yc, -one
        return R

    def solve(self, n_modes: int = 10) -> RitzModes:
        """The ``n_modes`` lowest elastic modes (rigid-body and suspension modes dropped)."""
        K, M = self.matrices()
        n = min(n_modes + 10, K.shape[0] - 1)
        # shift-invert Lanczos about a small negative shift: K - sigma M is positive definite
        # (Cholesky); 2-3x faster than LAPACK's subset solver (gvx) on these dense matrices
        lam_ = laminate_matrices(self.plies, self.shear_factor)
        est = (2.0 * np.pi / max(self.length, self.width)) ** 4 * np.max(np.diag(lam_["D"])) / lam_["I"][0]
        sigma = -1e-2 * est          # omega^2 of a bending wave one plate length long, a hundredth
        cf = cho_factor(K - sigma * M)
        op = LinearOperator(K.shape, matvec=lambda v: cho_solve(cf, v), dtype=float)
        lam, vec = eigsh(K, k=n, M=M, sigma=sigma, OPinv=op)
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
        R = self.rigid_vectors()
        MR = M @ R
        P = MR.T @ vec
        content = np.einsum("ik,ik->k", P, np.linalg.solve(R.T @ MR, P))
        rigid = content > 0.5
        if rigid.sum() != 6:
            raise ValueError(f"found {int(rigid.sum())} rigid-body modes, expected 6 (springs too stiff?)")
        el = ~rigid
        hz = np.sqrt(np.maximum(lam, 0.0)) / (2.0 * np.pi)
        if el.sum() < n_modes:
            raise ValueError("too few elastic modes: raise the order")
        return RitzModes(hz[el][:n_modes], vec[:, el][:, :n_modes], hz[rigid])

    def deflection_at(self, modes: RitzModes, points) -> np.ndarray:
        """(n_modes, n_points) w0 of each mode at (x, y) points (same scaling as the vectors)."""
        pts = np.asarray(points, float).reshape(-1, 2)
        nb = self.n_basis
        phi = self.basis_at(pts[:, 0], pts[:, 1])[0]
        return (phi @ modes.vectors[W * nb:(W + 1) * nb]).T


def converged_order(make: Callable[[int], RitzPlate], n_modes: int, tol: float = 2e-5,
                    orders: Sequence[int] = (10, 12, 14, 16, 18, 20, 22)) -> tuple[int, np.ndarray, float]:
    """(order, frequencies Hz, largest relative change) of the first order whose ``n_modes``
    lowest frequencies moved by less than ``tol`` from the previous order's (Ritz frequencies
    fall monotonically with the order); the last order when none did."""
    prev = None
    for o in orders:
        f = make(o).solve(n_modes).frequencies_hz
        if prev is not None:
            change = float(np.max(np.abs(prev / f - 1.0)))
            if change < tol:
                return o, f, change
        prev = f
    return orders[-1], prev, change
