"""Free-free Mindlin (first-order shear) laminated plate, finite elements.

Paper section 2 (Eqs. 1-14): displacements u = u0 + z bx, v = v0 + z by,
w = w0; generalised strains eps0 = (u0,x, v0,y, u0,y + v0,x), kappa =
(bx,x, by,y, bx,y + by,x), gamma = (bx + w0,x, by + w0,y); energy
U = 1/2 int(eps0'A eps0 + 2 eps0'B kappa + kappa'D kappa + gamma'H gamma) dS,
kinetic energy with I1, I2, I3 (Eq. 9). A, B, D, H come from
``engine.laminate.abdh`` (shear factor 5/6).

Discretisation: a tensor grid of nx x ny rectangular 16-node bicubic Lagrange
elements (uniform or graded towards the edges), 5 DOF per node (u0, v0, w0, bx, by; global DOF = 5 node + k), free edges.
Transverse shear uses assumed (substitute) strains to avoid shear locking:
gamma_xz is sampled at 3 (Gauss, along x) x 4 (Gauss, along y) tying points
and re-interpolated (quadratic in x, cubic in y), gamma_yz likewise with the
roles swapped. This matches the polynomial degree of w0,x (resp. w0,y), so
the Kirchhoff limit is reached without locking and, unlike plain 3x3 reduced
integration (which admits the checkerboard w = P3(xi) P3(eta) hourglass), it
keeps exactly six zero-energy (rigid-body) modes.

Units SI: m, kg, s, Pa; eigenvalues lambda = omega^2 in rad^2/s^2.

Linearity: every element matrix is a fixed linear combination of 21 unit
element matrices (the independent entries of A, B, D, H) for K and of 3 (I1,
I2, I3) for M; for a rectangle of size (hx, hy) each unit matrix is itself a
combination of 6 reference matrices with factors that are monomials in hx, hy.
A, B, D, H are linear in each material's reduced stiffnesses (Q11, Q12, Q22,
Q66, G13, G23) and I1, I2, I3 in its density. Re-solving for new constants
therefore only forms a 21-vector, one 80x80 matrix per element size and one
sparse scatter of fixed pattern: no re-assembly.

Meshes: uniform free-edge meshes converge only like O(h) because of the
Mindlin free-edge boundary layer (width ~ thickness); the default mesh adds one
row of elements 2 thicknesses wide along every edge (bench/RESULTS.md).

Eigen solver: shift-invert Lanczos (ARPACK eigsh) with a small negative shift,
SuperLU factorisation of K - sigma M. When B = 0 and I2 = 0 (symmetric
layups) the bending (w0, bx, by) and membrane (u0, v0) blocks are solved
apart. The six rigid-body modes are recognised by their mass-weighted
projection on the analytic rigid-body vectors and excluded; exactly six must
be found.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import eigh as sl_eigh

from .laminate import ABDH, Laminate, Material, transform_inplane, transform_shear

__all__ = ["Mesh", "Modes", "PlateModel", "natural_frequencies", "coefficients_from_abdh",
           "DEFAULT_ELEMENTS", "EDGE_LAYER", "COEF_NAMES", "FEError"]

#: Default mesh (CFRP convergence study, bench/RESULTS.md): DEFAULT_ELEMENTS
#: interior elements along the longer side plus an edge row of EDGE_LAYER
#: plate thicknesses; ten elastic modes of the 12-ply CFRP within 0.05 %.
DEFAULT_ELEMENTS = 6
EDGE_LAYER = 2.0

NODE_DOF = 5
_SPARE = 4
_NODES_1D = np.array([-1.0, -1.0 / 3.0, 1.0 / 3.0, 1.0])
_G4, _W4 = np.polynomial.legendre.leggauss(4)
_G3, _ = np.polynomial.legendre.leggauss(3)
_SYM3 = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
_SYM2 = ((0, 0), (0, 1), (1, 1))
#: names of the 21 stiffness coefficients (independent entries of A, B, D, H)
COEF_NAMES = tuple(f"{m}{i + 1}{j + 1}" for m in "ABD" for i, j in _SYM3) + tuple(
    f"H{i + 4}{j + 4}" for i, j in _SYM2)
#: per-material stiffness components K is linear in
Q_NAMES = ("Q11", "Q12", "Q22", "Q66", "G13", "G23")


class FEError(ValueError):
    """Bad mesh, point outside the plate, or a failed rigid-body-mode check."""


# ---------------------------------------------------------------- mesh --
def _edges(n: int, size: float, edges) -> np.ndarray:
    if edges is None:
        return np.linspace(0.0, size, n + 1)
    e = np.asarray(edges, dtype=float)
    if e.shape != (n + 1,) or not np.all(np.diff(e) > 0) or abs(e[0]) > 1e-12 * size \
            or abs(e[-1] - size) > 1e-9 * size:
        raise FEError(f"element edges {edges!r}: expected {n + 1} increasing values from 0 to {size} m")
    return e


@dataclass(frozen=True)
class Mesh:
    """Tensor grid of nx x ny rectangular 16-node elements on [0, length] x [0, width] (m).

    ``x_edges``/``y_edges`` (nx + 1 / ny + 1 element boundaries, m) give a
    graded mesh; None means uniform. Each element has 4 x 4 equally spaced
    nodes; nodes are numbered row by row (x fastest): node = iy * (3 nx + 1) + ix.
    """

    nx: int
    ny: int
    length: float
    width: float
    x_edges: tuple[float, ...] | None = None
    y_edges: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        for k in ("nx", "ny"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise FEError(f"mesh {k} = {v!r}: expected a positive integer")
        for k in ("length", "width"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v > 0):
                raise FEError(f"plate {k} = {v!r}: expected a positive value in m")
        for k, n, size in (("x_edges", self.nx, self.length), ("y_edges", self.ny, self.width)):
            e = getattr(self, k)
            if e is not None:
                object.__setattr__(self, k, tuple(float(v) for v in _edges(n, size, e)))

    @classmethod
    def default(cls, length: float, width: float, thickness: float | None = None,
                n: int | None = None) -> "Mesh":
        """The default mesh (CFRP convergence study, bench/RESULTS.md).

        n near-square interior elements along the longer side (default
        DEFAULT_ELEMENTS * sqrt(aspect ratio), at least 3 along the shorter);
        with ``thickness`` (m) one extra element row of width EDGE_LAYER *
        thickness (kept within 1/25 and 1/2 of an interior element) along
        every free edge, which resolves the Mindlin free-edge boundary layer
        (without it a uniform mesh converges only like O(h) there). Without
        ``thickness``: a uniform mesh.
        """
        big, small = max(length, width), min(length, width)
        if n is None:  # elongated plates: their 10 lowest modes have more waves along the length
            n = int(np.ceil(DEFAULT_ELEMENTS * np.sqrt(big / small) - 1e-9))
        if thickness is None:
            nx = max(2, int(round(n * length / big)))
            ny = max(2, int(round(n * width / big)))
            return cls(nx, ny, float(length), float(width))
        h_in = big / n  # interior element size
        # not thinner than h_in / 25: keeps K well conditioned on very thin plates,
        # where the (under-resolved) layer matters only at O(t/a) anyway
        edge = min(max(EDGE_LAYER * thickness, h_in / 25.0), 0.5 * min(length, width) / (n + 2))
        return cls.graded(length, width, n, [edge], n_min=3)

    @classmethod
    def graded(cls, length: float, width: float, n: int, edge: Sequence[float],
               n_min: int = 2) -> "Mesh":
        """n uniform interior elements along the longer side (at least n_min along
        the shorter) plus, at every edge, layers of widths ``edge`` (m, outermost first)."""
        big = max(length, width)
        out = []
        for size in (length, width):
            edge_ = np.asarray(edge, dtype=float)
            inner = size - 2.0 * edge_.sum()
            if inner <= 0:
                raise FEError(f"edge layers {list(edge)!r} m do not fit in {size} m")
            m = max(n_min, int(round(n * size / big)))
            widths = np.concatenate([edge_, np.full(m, inner / m), edge_[::-1]])
            out.append(np.concatenate([[0.0], np.cumsum(widths)]))
        out[0][-1], out[1][-1] = length, width
        return cls(len(out[0]) - 1, len(out[1]) - 1, float(length), float(width),
                   tuple(out[0]), tuple(out[1]))

    @property
    def xe(self) -> np.ndarray:
        """Element boundaries along x (nx + 1), m."""
        return _edges(self.nx, self.length, self.x_edges)

    @property
    def ye(self) -> np.ndarray:
        return _edges(self.ny, self.width, self.y_edges)

    @property
    def nnx(self) -> int:
        return 3 * self.nx + 1

    @property
    def nny(self) -> int:
        return 3 * self.ny + 1

    @property
    def n_nodes(self) -> int:
        return self.nnx * self.nny

    @property
    def n_dof(self) -> int:
        return NODE_DOF * self.n_nodes

    @property
    def n_elements(self) -> int:
        return self.nx * self.ny

    @staticmethod
    def _node_line(e: np.ndarray) -> np.ndarray:
        h = np.diff(e)
        return np.concatenate([(e[:-1, None] + h[:, None] * np.array([0.0, 1 / 3, 2 / 3])).ravel(), e[-1:]])

    @property
    def coords(self) -> np.ndarray:
        """(n_nodes, 2) node coordinates, m."""
        X, Y = np.meshgrid(self._node_line(self.xe), self._node_line(self.ye))
        return np.column_stack([X.ravel(), Y.ravel()])

    @property
    def element_sizes(self) -> np.ndarray:
        """(n_elements, 2) element sizes (hx, hy), m; element = ey * nx + ex."""
        HX, HY = np.meshgrid(np.diff(self.xe), np.diff(self.ye))
        return np.column_stack([HX.ravel(), HY.ravel()])

    @property
    def connectivity(self) -> np.ndarray:
        """(n_elements, 16) node numbers; local node = 4 j + i (i along x)."""
        ex, ey = np.meshgrid(np.arange(self.nx), np.arange(self.ny))
        ex, ey = ex.ravel(), ey.ravel()
        i = np.tile(np.arange(4), 4)
        j = np.repeat(np.arange(4), 4)
        return (3 * ey[:, None] + j[None, :]) * self.nnx + 3 * ex[:, None] + i[None, :]

    @property
    def element_dofs(self) -> np.ndarray:
        """(n_elements, 80) global DOFs; local DOF = 5 local_node + k."""
        c = self.connectivity
        return (NODE_DOF * c[:, :, None] + np.arange(NODE_DOF)).reshape(c.shape[0], -1)

    def locate(self, points, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Element index and local coordinates (xi, eta in [-1, 1]) of (x, y) points (m)."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        if p.ndim != 2 or p.shape[1] != 2:
            raise FEError(f"points of shape {p.shape}: expected (n, 2) x, y in m")
        x, y = p[:, 0], p[:, 1]
        tl, tw = tol * self.length, tol * self.width
        bad = (x < -tl) | (x > self.length + tl) | (y < -tw) | (y > self.width + tw) | ~np.isfinite(x + y)
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            raise FEError(f"point ({x[k]!r}, {y[k]!r}) lies outside the plate "
                          f"[0, {self.length}] x [0, {self.width}] m")
        xe, ye = self.xe, self.ye
        ex = np.clip(np.searchsorted(xe, x, side="right") - 1, 0, self.nx - 1)
        ey = np.clip(np.searchsorted(ye, y, side="right") - 1, 0, self.ny - 1)
        hx, hy = xe[ex + 1] - xe[ex], ye[ey + 1] - ye[ey]
        xi = np.clip(2.0 * (x - xe[ex]) / hx - 1.0, -1.0, 1.0)
        eta = np.clip(2.0 * (y - ye[ey]) / hy - 1.0, -1.0, 1.0)
        return ey * self.nx + ex, xi, eta


# -------------------------------------------------- shape functions ----
def _lagrange(nodes: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1D Lagrange basis on ``nodes`` at points t: values and derivatives (len(t), len(nodes))."""
    t = np.asarray(t, dtype=float)
    C = np.linalg.inv(np.vander(nodes, increasing=True))  # N_i(t) = sum_k t^k C[k, i]
    n = len(nodes)
    P = np.vander(t, n, increasing=True)
    dP = np.zeros_like(P)
    dP[:, 1:] = P[:, :-1] * np.arange(1, n)
    return P @ C, dP @ C


def _shape_2d(xi: np.ndarray, eta: np.ndarray):
    """16 bicubic shape functions and their xi, eta derivatives at points (npts, 16)."""
    Nx, dNx = _lagrange(_NODES_1D, xi)
    Ny, dNy = _lagrange(_NODES_1D, eta)
    n = len(np.atleast_1d(xi))
    N = (Ny[:, :, None] * Nx[:, None, :]).reshape(n, 16)
    Nxi = (Ny[:, :, None] * dNx[:, None, :]).reshape(n, 16)
    Neta = (dNy[:, :, None] * Nx[:, None, :]).reshape(n, 16)
    return N, Nxi, Neta


#: scale combinations (p, q) of the reference matrices, p, q in {0: no
#: derivative, x: d/dxi, y: d/deta}; element factor s_pq(hx, hy) below.
_COMBOS = ("00", "0x", "0y", "xx", "xy", "yy")


def _combo_scales(h: np.ndarray) -> np.ndarray:
    """(n, 6) factors s_pq = hx hy / 4 * f_p f_q with f_0 = 1, f_x = 2/hx, f_y = 2/hy."""
    hx, hy = h[:, 0], h[:, 1]
    return np.column_stack([hx * hy / 4.0, hy / 2.0, hx / 2.0, hy / hx, np.ones_like(hx), hx / hy])


def _reference_matrices() -> tuple[np.ndarray, np.ndarray]:
    """Reference element matrices: K (6 combos, 21 coefs, 80, 80), M (3 inertias, 80, 80).

    The unit stiffness of coefficient i of an element (hx, hy) is
    sum_pq s_pq(hx, hy) K[pq, i]; its unit mass is s_00 M.
    """
    XI, ETA = np.meshgrid(_G4, _G4, indexing="ij")
    xi, eta = XI.ravel(), ETA.ravel()
    w = np.outer(_W4, _W4).ravel()
    npt = len(xi)
    N, Nxi, Neta = _shape_2d(xi, eta)

    def field(k: int, vals: np.ndarray) -> np.ndarray:
        out = np.zeros((vals.shape[0], 16, NODE_DOF))
        out[:, :, k] = vals
        return out.reshape(vals.shape[0], 80)

    U, V, W, BX, BY = range(5)
    Z = np.zeros((npt, 80))
    # strain operators split by derivative direction: B = B_0 + f_x B_x + f_y B_y
    Bm = {"x": np.stack([field(U, Nxi), Z, field(V, Nxi)], 1),
          "y": np.stack([Z, field(V, Neta), field(U, Neta)], 1)}
    Bb = {"x": np.stack([field(BX, Nxi), Z, field(BY, Nxi)], 1),
          "y": np.stack([Z, field(BY, Neta), field(BX, Neta)], 1)}

    # assumed transverse shear strains (tying points, see module docstring)
    lx, _ = _lagrange(_G3, _G4)  # (4 integration pts, 3 tying pts)
    TX, TY = np.meshgrid(_G3, _G4, indexing="ij")  # xz: 3 along x, 4 along y
    Nt, Ntx, _ = _shape_2d(TX.ravel(), TY.ravel())
    to_int_x = lambda f: np.einsum("ak,kbd->abd", lx, f.reshape(3, 4, 80)).reshape(npt, 80)
    gxz0, gxzx = to_int_x(field(BX, Nt)), to_int_x(field(W, Ntx))
    TX, TY = np.meshgrid(_G4, _G3, indexing="ij")  # yz: 4 along x, 3 along y
    Nt, _, Nty = _shape_2d(TX.ravel(), TY.ravel())
    to_int_y = lambda f: np.einsum("bk,akd->abd", lx, f.reshape(4, 3, 80)).reshape(npt, 80)
    gyz0, gyzy = to_int_y(field(BY, Nt)), to_int_y(field(W, Nty))
    Bs = {"0": np.stack([gxz0, gyz0], 1), "x": np.stack([gxzx, Z], 1), "y": np.stack([Z, gyzy], 1)}

    def form(Bp, Bq, i, j):
        return np.einsum("p,pa,pb->ab", w, Bp[:, i], Bq[:, j])

    def unit(Bl, Br, p, q, i, j):
        """sum over the symmetric pair of unit-matrix entries and of (p, q)/(q, p)."""
        out = form(Bl[p], Br[q], i, j)
        if i != j:
            out = out + form(Bl[p], Br[q], j, i)
        if p != q:
            out = out + form(Bl[q], Br[p], i, j) + (form(Bl[q], Br[p], j, i) if i != j else 0.0)
        return out

    K = np.zeros((6, 21, 80, 80))
    for ci, combo in enumerate(_COMBOS):
        p, q = combo
        for c, (i, j) in enumerate(_SYM3):
            if "0" not in combo:
                K[ci, c] = unit(Bm, Bm, p, q, i, j)
                K[ci, 12 + c] = unit(Bb, Bb, p, q, i, j)
                mb = unit(Bm, Bb, p, q, i, j)
                K[ci, 6 + c] = mb + mb.T
        for c, (i, j) in enumerate(_SYM2):
            if p in Bs and q in Bs:
                K[ci, 18 + c] = unit(Bs, Bs, p, q, i, j)

    NN = np.einsum("p,pa,pb->ab", w, N, N)
    Me = np.zeros((3, 16, NODE_DOF, 16, NODE_DOF))
    for k in (U, V, W):
        Me[0, :, k, :, k] = NN
    for a, b in ((U, BX), (V, BY)):
        Me[1, :, a, :, b] = NN
        Me[1, :, b, :, a] = NN
    for k in (BX, BY):
        Me[2, :, k, :, k] = NN
    return K, Me.reshape(3, 80, 80)


# ------------------------------------------------- material linearity --
def _q_vector(mat: Material) -> np.ndarray:
    """(Q11, Q12, Q22, Q66, G13, G23) of paper Eq. 4, Pa."""
    nu21 = mat.nu12 * mat.E2 / mat.E1
    d = 1.0 - mat.nu12 * nu21
    return np.array([mat.E1 / d, mat.nu12 * mat.E2 / d, mat.E2 / d, mat.G12, mat.G13, mat.G23])


def _q_derivatives(mat: Material, names: Sequence[str]) -> np.ndarray:
    """d(q, density)/dp, shape (7, len(names)); q as in ``_q_vector``, chain rule through Eq. 4.

    Isotropic materials (parameters E, G, nu): with_params keeps G when E is
    changed (nu follows) and keeps E when nu is changed (G follows).
    """
    out = np.zeros((7, len(names)))
    if mat.isotropic:
        E, G = mat.E1, mat.G12
        nu = E / (2.0 * G) - 1.0
        s = 1.0 - nu * nu
        dQ11 = np.array([1.0 / s, 2.0 * E * nu / s**2])      # d/dE, d/dnu at fixed (E, nu)
        dQ12 = np.array([nu / s, E / s + nu * dQ11[1]])
        for c, p in enumerate(names):
            if p == "E":      # G fixed, nu = E/2G - 1
                dE, dnu, dG = 1.0, 1.0 / (2.0 * G), 0.0
            elif p == "G":    # E fixed
                dE, dnu, dG = 0.0, -E / (2.0 * G * G), 1.0
            elif p == "nu":   # E fixed, G = E / 2(1 + nu)
                dE, dnu, dG = 0.0, 1.0, -E / (2.0 * (1.0 + nu) ** 2)
            elif p == "density":
                out[6, c] = 1.0
                continue
            else:
                raise KeyError(f"unknown isotropic parameter {p!r}; expected E, G, nu or density")
            q11 = dQ11[0] * dE + dQ11[1] * dnu
            q12 = dQ12[0] * dE + dQ12[1] * dnu
            out[:6, c] = [q11, q12, q11, dG, dG, dG]
        return out
    E1, E2, nu = mat.E1, mat.E2, mat.nu12
    d = 1.0 - nu * nu * E2 / E1
    dd = {"E1": nu * nu * E2 / E1**2, "E2": -nu * nu / E1, "nu12": -2.0 * nu * E2 / E1}
    for c, p in enumerate(names):
        if p in dd:
            g = dd[p]
            dE1 = 1.0 if p == "E1" else 0.0
            dE2 = 1.0 if p == "E2" else 0.0
            dnu = 1.0 if p == "nu12" else 0.0
            out[0, c] = dE1 / d - E1 * g / d**2
            out[1, c] = (dnu * E2 + nu * dE2) / d - nu * E2 * g / d**2
            out[2, c] = dE2 / d - E2 * g / d**2
        elif p in ("G12", "G13", "G23"):
            out[{"G12": 3, "G13": 4, "G23": 5}[p], c] = 1.0
        elif p == "density":
            out[6, c] = 1.0
        else:
            raise KeyError(f"unknown orthotropic parameter {p!r}; expected E1 E2 nu12 G12 G13 G23 density")
    return out


def _coef_vector(A, B, D, H) -> np.ndarray:
    return np.array([A[i, j] for i, j in _SYM3] + [B[i, j] for i, j in _SYM3]
                    + [D[i, j] for i, j in _SYM3] + [H[i, j] for i, j in _SYM2])


def coefficients_from_abdh(r: ABDH) -> tuple[np.ndarray, np.ndarray]:
    """(21 coefficients in COEF_NAMES order, (I1, I2, I3)) of laminate resultants."""
    return _coef_vector(r.A, r.B, r.D, r.H), np.array([r.I1, r.I2, r.I3])


def _material_maps(lam: Laminate, shear_factor: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per material name: (L (21, 6): coefficients per unit q; R (3,): I1, I2, I3 per unit density)."""
    z = lam.z_interfaces
    maps: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    units = []
    for k in range(4):
        Q = np.zeros((3, 3))
        idx = [(0, 0), (0, 1), (1, 1), (2, 2)][k]
        Q[idx] = Q[idx[::-1]] = 1.0
        units.append(Q)
    seen: dict[str, Material] = {}
    for k, ply in enumerate(lam.plies):
        name = ply.material.name
        if seen.setdefault(name, ply.material) != ply.material:
            raise FEError(f"two different materials are both named {name!r}; expected distinct names")
        L, R = maps.setdefault(name, (np.zeros((21, 6)), np.zeros(3)))
        z0, z1 = z[k], z[k + 1]
        d1, d2, d3 = z1 - z0, (z1**2 - z0**2) / 2.0, (z1**3 - z0**3) / 3.0
        for c in range(6):
            if c < 4:
                Qb = transform_inplane(units[c], ply.angle_deg)
                L[:, c] += _coef_vector(Qb * d1, Qb * d2, Qb * d3, np.zeros((2, 2)))
            else:
                Qs = np.diag([1.0, 0.0] if c == 4 else [0.0, 1.0])
                Hs = transform_shear(Qs, ply.angle_deg) * d1 * shear_factor
                L[:, c] += _coef_vector(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), Hs)
        R += [d1, d2, d3]
    return maps


# --------------------------------------------------------------- modes --
@dataclass(frozen=True)
class Modes:
    """Elastic modes, ascending.

    ``shapes`` (n_dof, n) are mass-normalised (phi' M phi = 1, units 1/sqrt(kg));
    ``omega2`` in rad^2/s^2; ``rigid_max_omega`` (rad/s) is the largest |omega|
    among the six rigid-body modes that were detected and excluded (with
    springs: the suspension modes).
    """

    frequencies_hz: np.ndarray
    omega2: np.ndarray
    shapes: np.ndarray
    rigid_max_omega: float
    params: Mapping[str, float] = field(default_factory=dict)
    material: str | None = None


@dataclass(frozen=True)
class _Pattern:
    """Fixed CSR sparsity pattern of the global matrices and the element scatter.

    Elements of equal size share one "type"; data = scatter @ Ke_types.ravel()
    with Ke_types (n_types, 6400).
    """

    indptr: np.ndarray
    indices: np.ndarray
    scatter: sp.csr_matrix      # (nnz, n_types * 6400)
    elem_pos: np.ndarray        # (n_elements, 6400) position in data of each element entry
    elem_type: np.ndarray       # (n_elements,) type index
    type_scales: np.ndarray     # (n_types, 6) s_pq of each type
    m_mask: np.ndarray          # (nnz,) bool: positions the mass matrix can fill
    m_indptr: np.ndarray        # CSR of the mass sub-pattern
    cross: np.ndarray           # (nnz,) bool: membrane (u0, v0) x bending (w0, bx, by) positions

    @classmethod
    def build(cls, mesh: Mesh) -> "_Pattern":
        dofs = mesh.element_dofs
        ne = dofs.shape[0]
        h = mesh.element_sizes
        hq = np.round(h / max(mesh.length, mesh.width), 12)
        _, first, etype = np.unique(hq, axis=0, return_index=True, return_inverse=True)
        etype = etype.ravel()
        rows = np.repeat(dofs, 80, axis=1).ravel()
        cols = np.tile(dofs, (1, 80)).ravel()
        key = rows.astype(np.int64) * mesh.n_dof + cols
        ukey, inv = np.unique(key, return_inverse=True)
        n = mesh.n_dof
        r, c = np.divmod(ukey, n)
        indptr = np.searchsorted(r, np.arange(n + 1)).astype(np.int32)
        local = (etype[:, None] * 6400 + np.arange(6400)).ravel()
        scatter = sp.csr_matrix((np.ones(inv.size), (inv, local)),
                                shape=(ukey.size, len(first) * 6400))
        fr, fc = r % NODE_DOF, c % NODE_DOF
        pair = np.minimum(fr, fc) * 10 + np.maximum(fr, fc)
        m_mask = (fr == fc) | (pair == 3) | (pair == 14)  # same field, u-bx, v-by
        m_indptr = np.concatenate([[0], np.cumsum(np.add.reduceat(m_mask, indptr[:-1]))])
        cross = (fr < 2) != (fc < 2)
        return cls(indptr, c.astype(np.int32), scatter, inv.reshape(ne, 6400), etype,
                   _combo_scales(h[first]), m_mask, m_indptr.astype(np.int32), cross)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        n = len(self.indptr) - 1
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(n, n))

    def mass_matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """M from full-pattern data, keeping only its structural non-zeros (~1/5)."""
        n = len(self.indptr) - 1
        return sp.csr_matrix((data[self.m_mask], self.indices[self.m_mask], self.m_indptr),
                             shape=(n, n))


@dataclass(frozen=True)
class _Block:
    """A set of DOF fields whose K, M rows/columns are solved on their own."""

    dofs: np.ndarray      # global DOFs of the block, ascending
    k_pos: np.ndarray     # positions (in the full pattern data) of the block's entries
    indptr: np.ndarray    # block CSR pattern (renumbered)
    indices: np.ndarray
    m_sel: np.ndarray     # positions (in the block data) where M may be non-zero
    m_indptr: np.ndarray

    @classmethod
    def build(cls, pat: _Pattern, fields: Sequence[int]) -> "_Block":
        n = len(pat.indptr) - 1
        rows = np.repeat(np.arange(n), np.diff(pat.indptr))
        in_b = np.isin(np.arange(n) % NODE_DOF, fields)
        dofs = np.flatnonzero(in_b)
        new = np.full(n, -1)
        new[dofs] = np.arange(dofs.size)
        k_pos = np.flatnonzero(in_b[rows] & in_b[pat.indices])
        brow = new[rows[k_pos]]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(brow, minlength=dofs.size))])
        m_sel = np.flatnonzero(pat.m_mask[k_pos])
        m_indptr = np.concatenate([[0], np.cumsum(np.bincount(brow[m_sel], minlength=dofs.size))])
        return cls(dofs, k_pos, indptr.astype(np.int32), new[pat.indices[k_pos]].astype(np.int32),
                   m_sel, m_indptr.astype(np.int32))

    def mass(self, md: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        """Block mass data on the block pattern and the block M (CSR, own sparser pattern)."""
        nb = self.dofs.size
        mb = md[self.k_pos]
        return mb, sp.csr_matrix((mb[self.m_sel], self.indices[self.m_sel], self.m_indptr), shape=(nb, nb))

    def eig(self, kd: np.ndarray, md: np.ndarray, k: int, sigma: float, n_full: int,
            mass: tuple[np.ndarray, sp.csr_matrix] | None = None, ncv: int | None = None):
        """k eigenpairs nearest sigma (shift-invert), vectors expanded to n_full DOFs.

        ``mass``: ``self.mass(md)`` when already known (M depends on density only);
        ``ncv``: Lanczos basis size (default max(2k + 1, 20))."""
        nb = self.dofs.size
        mb, M = self.mass(md) if mass is None else mass
        kb = kd[self.k_pos]
        # K - sigma M is symmetric: its CSR arrays are also its CSC arrays
        A = sp.csc_matrix((kb - sigma * mb, self.indices, self.indptr), shape=(nb, nb))
        lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
        op = spla.LinearOperator((nb, nb), matvec=lu.solve, dtype=float)
        v0 = np.random.default_rng(20120101).standard_normal(nb)  # reproducible
        lam, vec = spla.eigsh(A, k=k, M=M, sigma=sigma, OPinv=op, which="LM", v0=v0,
                              ncv=min(nb - 1, ncv or max(2 * k + 1, 20)), tol=1e-10)
        full = np.zeros((n_full, k))
        full[self.dofs] = vec
        return lam, full


def _point_matrix(mesh: Mesh, pat: _Pattern, x: float, y: float,
                  diag: Sequence[float]) -> np.ndarray:
    """Data vector of sum_k diag[k] N_k' N_k for the 5 DOF fields at one point."""
    e, xi, eta = mesh.locate([[x, y]])
    N, _, _ = _shape_2d(xi, eta)
    NN = np.outer(N[0], N[0])
    Me = np.zeros((16, NODE_DOF, 16, NODE_DOF))
    for k, v in enumerate(diag):
        if v:
            Me[:, k, :, k] = v * NN
    data = np.zeros(pat.indices.size)
    np.add.at(data, pat.elem_pos[e[0]], Me.ravel())
    return data


class PlateModel:
    """Free-free laminated Mindlin plate: precomputed parts, solve per parameter set."""

    def __init__(self, laminate: Laminate, mesh: Mesh, shear_factor: float = 5.0 / 6.0,
                 *, _parts=None, k_add=None, m_add=None, _cache=None):
        self.laminate, self.mesh, self.shear_factor = laminate, mesh, shear_factor
        if _parts is None:
            Kref, Mref = _reference_matrices()
            _parts = (Kref, Mref, _Pattern.build(mesh), _material_maps(laminate, shear_factor))
        self._Ke, self._Me, self._pat, self._maps = _parts
        self._Kflat = np.ascontiguousarray(self._Ke.transpose(1, 0, 2, 3).reshape(21, -1))
        nnz = self._pat.indices.size
        self._k_add = np.zeros(nnz) if k_add is None else k_add
        self._m_add = np.zeros(nnz) if m_add is None else m_add
        cross = self._pat.cross
        self._add_cross = bool(np.any(self._k_add[cross] != 0) or np.any(self._m_add[cross] != 0))
        self._cache: dict = {} if _cache is None else _cache  # mesh-only data, shared by derived models
        self._mass_memo: dict | None = None  # mass data of the last inertias (see _mass)
        self._mem_memo: dict | None = None   # last membrane solve (see _membrane_modes)
        # no added stiffness on the membrane DOFs (the membrane eigenvalue bound needs it)
        fr = np.repeat(np.arange(len(self._pat.indptr) - 1), np.diff(self._pat.indptr)) % NODE_DOF
        self._membrane_k_free = not np.any(self._k_add[(fr < 2) & (self._pat.indices % NODE_DOF < 2)])

    # -- construction ---------------------------------------------------
    @classmethod
    def build(cls, laminate: Laminate, length: float, width: float, mesh=None,
              shear_factor: float = 5.0 / 6.0) -> "PlateModel":
        """Precompute the parts.

        ``mesh``: None (``Mesh.default``, graded at the edges), (nx, ny) for a
        uniform nx x ny mesh, or a Mesh.
        """
        if mesh is None:
            m = Mesh.default(length, width, laminate.thickness)
        elif isinstance(mesh, Mesh):
            m = mesh
        else:
            try:
                nx, ny = mesh
            except (TypeError, ValueError):
                raise FEError(f"mesh = {mesh!r}: expected (nx, ny) elements") from None
            m = Mesh(nx, ny, float(length), float(width))
        for mat in laminate.materials.values():
            mat.check()
        return cls(laminate, m, shear_factor)

    @property
    def k_add(self) -> np.ndarray:
        """Added stiffness (springs, stiffness loss) on the sparse pattern's entries (read-only)."""
        v = self._k_add.view()
        v.flags.writeable = False
        return v

    @property
    def m_add(self) -> np.ndarray:
        """Added mass (point masses) on the sparse pattern's entries (read-only)."""
        v = self._m_add.view()
        v.flags.writeable = False
        return v

    def with_laminate(self, laminate: Laminate) -> "PlateModel":
        """The same mesh, shear factor and added stiffness and mass with another laminate
        (e.g. scaled thickness); mesh-only data are shared."""
        Kref, Mref = self._Ke, self._Me
        return PlateModel(laminate, self.mesh, self.shear_factor,
                          _parts=(Kref, Mref, self._pat, _material_maps(laminate, self.shear_factor)),
                          k_add=self._k_add, m_add=self._m_add, _cache=self._cache)

    def _derived(self, k_add=None, m_add=None) -> "PlateModel":
        return PlateModel(self.laminate, self.mesh, self.shear_factor,
                          _parts=(self._Ke, self._Me, self._pat, self._maps),
                          k_add=self._k_add if k_add is None else k_add,
                          m_add=self._m_add if m_add is None else m_add, _cache=self._cache)

    def with_point_masses(self, masses: Iterable[Sequence[float]]) -> "PlateModel":
        """Add point masses (x, y, m) or (x, y, m, Ix, Iy): m in kg on u0, v0, w0;
        rotary inertias in kg m^2, Ix about the x axis (acts on by), Iy about y (on bx)."""
        add = self._m_add.copy()
        for row in masses:
            row = tuple(float(v) for v in row)
            if len(row) not in (3, 5):
                raise FEError(f"point mass {row!r}: expected (x, y, m_kg) or (x, y, m_kg, Ix, Iy)")
            x, y, m = row[:3]
            Ix, Iy = row[3:] if len(row) == 5 else (0.0, 0.0)
            if not (m >= 0 and Ix >= 0 and Iy >= 0):
                raise FEError(f"point mass {row!r}: expected non-negative mass and inertias")
            add += _point_matrix(self.mesh, self._pat, x, y, (m, m, m, Iy, Ix))
        return self._derived(m_add=add)

    def with_springs(self, springs: Iterable[Sequence[float]]) -> "PlateModel":
        """Add grounded transverse springs (x, y, kz) on w0, kz in N/m."""
        add = self._k_add.copy()
        for row in springs:
            row = tuple(float(v) for v in row)
            if len(row) != 3 or not row[2] >= 0:
                raise FEError(f"spring {row!r}: expected (x, y, kz_N_per_m) with kz >= 0")
            add += _point_matrix(self.mesh, self._pat, row[0], row[1], (0, 0, row[2], 0, 0))
        return self._derived(k_add=add)

    def with_stiffness_loss(self, x0: float, y0: float, size: float, loss: float,
                            params: Mapping[str, float] | None = None,
                            material: str | None = None) -> "PlateModel":
        """A local stiffness loss (damage, a soft patch): inside the square of side ``size``
        (m) centred at (x0, y0), the stiffness drops by the fraction ``loss`` (each element
        by ``loss`` times its area fraction inside the square). The loss is that of the
        stiffness at ``params`` and stays fixed when the model is solved with others."""
        if not 0.0 <= loss <= 1.0 or not size > 0:
            raise FEError(f"stiffness loss {loss!r} over {size!r} m: expected 0 <= loss <= 1 and size > 0")
        c, _ = self.coefficients(params, material)
        pat = self._pat
        Kc = np.tensordot(c, self._Ke, axes=(0, 1)).reshape(self._Ke.shape[0], -1)
        Ke_type = pat.type_scales @ Kc                       # (n_types, element matrix)
        xe, ye = self.mesh.xe, self.mesh.ye
        ox = np.clip(np.minimum(xe[1:], x0 + size / 2) - np.maximum(xe[:-1], x0 - size / 2), 0, None) / np.diff(xe)
        oy = np.clip(np.minimum(ye[1:], y0 + size / 2) - np.maximum(ye[:-1], y0 - size / 2), 0, None) / np.diff(ye)
        add = self._k_add.copy()
        for ey in np.flatnonzero(oy):
            for ex in np.flatnonzero(ox):
                e = ey * self.mesh.nx + ex
                np.add.at(add, pat.elem_pos[e], -loss * ox[ex] * oy[ey] * Ke_type[pat.elem_type[e]])
        return self._derived(k_add=add)

    # -- parameters -----------------------------------------------------
    def _material_name(self, material: str | None) -> str:
        if material is None:
            if len(self._maps) != 1:
                raise KeyError(f"laminate has materials {sorted(self._maps)}; name the one to update")
            return next(iter(self._maps))
        if material not in self._maps:
            raise KeyError(f"material {material!r} not in laminate; expected one of {sorted(self._maps)}")
        return material

    def _materials(self, params, material) -> dict[str, Material]:
        mats = dict(self.laminate.materials)
        if params:
            name = self._material_name(material)
            mats[name] = mats[name].with_params(**params)
            mats[name].check()
        return mats

    def coefficients(self, params: Mapping[str, float] | None = None,
                     material: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(21 stiffness coefficients per COEF_NAMES, (I1, I2, I3)) for a parameter set."""
        c = np.zeros(21)
        inert = np.zeros(3)
        for name, mat in self._materials(params, material).items():
            L, R = self._maps[name]
            c += L @ _q_vector(mat)
            inert += R * mat.density
        return c, inert

    def matrices(self, params=None, material=None) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """Global K (N/m) and M (kg), CSR (M on its own, sparser pattern)."""
        c, inert = self.coefficients(params, material)
        kd, _ = self._data(c, inert)
        return self._pat.matrix(kd), self._mass(inert)["M"].copy()

    def _data(self, c: np.ndarray, inert: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """K and M data vectors on the common pattern."""
        pat = self._pat
        Kc = (c @ self._Kflat).reshape(6, 6400)   # unit element matrix per scale combo
        kd = pat.scatter @ (pat.type_scales @ Kc).ravel() + self._k_add
        return kd, self._mass(inert)["md"]

    def _mass(self, inert: np.ndarray) -> dict:
        """Mass-side data for inertias (I1, I2, I3), memoised for the last inertias
        (M depends on the density only, fixed during most identifications):
        ``md`` (data on the common pattern), ``M`` (global CSR) and, filled on
        demand, ``MR`` (M times the rigid-body vectors), ``G`` (R' M R) and
        per-block ``(mb, Mb)``."""
        key = np.asarray(inert, dtype=float).tobytes()
        memo = self._mass_memo
        if memo is None or memo["key"] != key:
            pat = self._pat
            Mc = np.tensordot(np.asarray(inert, dtype=float), self._Me, 1).ravel()
            md = pat.scatter @ np.outer(pat.type_scales[:, 0], Mc).ravel() + self._m_add
            md.flags.writeable = False
            memo = self._mass_memo = {"key": key, "md": md, "M": pat.mass_matrix(md)}
        return memo

    def _block_mass(self, name: str, inert: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        memo = self._mass(inert)
        if name not in memo:
            memo[name] = self._block(name).mass(memo["md"])
        return memo[name]

    # -- rigid body modes --------------------------------------------------
    def rigid_body_vectors(self) -> np.ndarray:
        """(n_dof, 6) translations x, y, z; rotation about z; rotations about x and y."""
        if "R" in self._cache:
            return self._cache["R"]
        xy = self.mesh.coords
        n = xy.shape[0]
        R = np.zeros((n, NODE_DOF, 6))
        R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
        R[:, 0, 3], R[:, 1, 3] = -xy[:, 1], xy[:, 0]
        R[:, 2, 4], R[:, 4, 4] = xy[:, 1], -1.0
        R[:, 2, 5], R[:, 3, 5] = xy[:, 0], -1.0
        self._cache["R"] = R.reshape(n * NODE_DOF, 6)
        return self._cache["R"]

    # -- solve --------------------------------------------------------------
    def solve(self, n_modes: int = 10, params: Mapping[str, float] | None = None,
              material: str | None = None, sigma: float | None = None) -> Modes:
        """The n_modes lowest elastic modes (rigid-body modes detected and excluded).

        ``params``: constants of ``material`` (contract names) replacing the
        laminate's; K and M are recombined from the precomputed parts.
        """
        c, inert = self.coefficients(params, material)
        modes = self.solve_coefficients(c, inert, n_modes, sigma)
        return Modes(modes.frequencies_hz, modes.omega2, modes.shapes, modes.rigid_max_omega,
                     dict(params or {}), material)

    def solve_coefficients(self, c: np.ndarray, inertias: Sequence[float], n_modes: int = 10,
                           sigma: float | None = None) -> Modes:
        """Modes for explicit laminate coefficients (COEF_NAMES order, see
        ``coefficients_from_abdh``) and inertias (I1, I2, I3)."""
        if isinstance(n_modes, bool) or int(n_modes) != n_modes or n_modes < 1:
            raise FEError(f"n_modes = {n_modes!r}: expected a positive integer")
        n_modes = int(n_modes)
        c, inert = np.asarray(c, dtype=float), np.asarray(inertias, dtype=float)
        kd, md = self._data(c, inert)
        n = self.mesh.n_dof
        if n_modes + 6 + _SPARE >= 0.4 * n - 1:
            raise FEError(f"n_modes = {n_modes}: too many for a mesh of {n} DOF")
        if sigma is None:
            sigma = -1e-3 * self._omega2_scale(c, inert)
        h = self.laminate.thickness
        coupled = (self._add_cross or np.abs(c[6:12]).max() > 1e-10 * np.abs(c[:6]).max() * h
                   or abs(inert[1]) > 1e-10 * inert[0] * h)
        if coupled:
            lam, vec = self._block("all").eig(kd, md, n_modes + 6 + _SPARE, sigma, n,
                                              self._block_mass("all", inert))
        else:
            # B = 0, I2 = 0: bending (w0, bx, by) and membrane (u0, v0) decouple;
            # 3 rigid modes each. Membrane modes are usually far above.
            # ncv = k + 13: ~11 % faster than 2k + 1 for 10 CFRP modes (bench/RESULTS.md,
            # Identification), eigenvalues equal to 1e-12
            kb = n_modes + 3 + _SPARE
            lam, vec = self._block("bending").eig(kd, md, kb, sigma, n, self._block_mass("bending", inert),
                                                  ncv=max(kb + 13, 20))
            top = np.sort(lam)[min(3 + n_modes, lam.size) - 1]
            lam_m, vec_m = self._membrane_modes(kd, c, inert, top, sigma, n)
            lam, vec = np.concatenate([lam, lam_m]), np.hstack([vec, vec_m])
        k = lam.size
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
        rigid = self._rigid_mask(vec, self._mass(inert))
        if rigid.sum() != 6:
            raise FEError(f"found {int(rigid.sum())} rigid-body modes among the {k} lowest, "
                          "expected exactly 6")
        elastic = ~rigid
        if np.any(lam[elastic] < 1e-6 * self._omega2_scale(c, inert)):
            raise FEError("spurious zero-energy mode: elastic mode with omega^2 ~ 0")
        lam_e, vec_e = lam[elastic][:n_modes], vec[:, elastic][:, :n_modes]
        if lam_e.size < n_modes:
            raise FEError("eigen solver returned too few elastic modes")
        rigid_max = float(np.sqrt(np.max(np.abs(lam[rigid]))))
        return Modes(np.sqrt(np.maximum(lam_e, 0.0)) / (2.0 * np.pi), lam_e, vec_e, rigid_max)

    def _membrane_modes(self, kd: np.ndarray, c: np.ndarray, inert: np.ndarray, top: float,
                        sigma: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Membrane (u0, v0) modes of a decoupled plate: all below ``top`` (omega^2,
        the highest bending mode wanted) and at least its 3 rigid-body modes.

        The membrane stiffness is linear and positive in the A matrix only, so
        if A_new - alpha A_old is positive semi-definite every membrane
        eigenvalue (same M) is at least alpha times the old one (Courant-Fischer).
        When that bound puts the first elastic membrane mode of the last
        membrane solve above 1.02 top, that solve's rigid-body pairs (exact
        null vectors of every K_m, M-normalised for this M) are returned
        instead of a new solve: none of its elastic modes could be selected.
        """
        blk = self._block("membrane")
        mass = self._block_mass("membrane", inert)
        A_new = c[[0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(3, 3)
        memo = self._mem_memo
        if memo is not None and memo["mass"] is mass:
            try:
                alpha = float(sl_eigh(A_new, memo["A"], eigvals_only=True)[0])
            except np.linalg.LinAlgError:
                alpha = 0.0
            if alpha * memo["lam_elastic"] > 1.02 * top:
                return memo["lam_rigid"], memo["vec_rigid"]
        km, nm = 6, blk.dofs.size
        while True:
            lam_m, vec_m = blk.eig(kd, self._mass(inert)["md"], km, sigma, n, mass)
            if lam_m.max() > top or km >= 0.4 * nm:
                break
            km *= 2
        order = np.argsort(lam_m)
        if self._membrane_k_free and order.size > 3:
            self._mem_memo = {"mass": mass, "A": A_new, "lam_elastic": float(lam_m[order[3]]),
                              "lam_rigid": lam_m[order[:3]], "vec_rigid": vec_m[:, order[:3]]}
        return lam_m, vec_m

    def _block(self, name: str) -> _Block:
        key = "block_" + name
        if key not in self._cache:
            fields = {"all": range(NODE_DOF), "bending": (2, 3, 4), "membrane": (0, 1)}[name]
            self._cache[key] = _Block.build(self._pat, tuple(fields))
        return self._cache[key]

    def _omega2_scale(self, c: np.ndarray, inert: np.ndarray) -> float:
        """Rough first elastic omega^2 (thin-plate estimate), rad^2/s^2."""
        Dmax = max(c[12], c[15], c[17])
        a = max(self.mesh.length, self.mesh.width)
        return 100.0 * Dmax / (inert[0] * a**4)

    def _rigid_mask(self, vec: np.ndarray, mass: dict) -> np.ndarray:
        """True for modes whose M-norm lies mostly (> 1/2) in the rigid-body space.

        ``mass``: ``self._mass(inertias)``; M R and R' M R are memoised there."""
        if "MR" not in mass:
            R = self.rigid_body_vectors()
            mass["MR"] = np.asarray(mass["M"] @ R)
            mass["G"] = R.T @ mass["MR"]
        P = mass["MR"].T @ vec  # (6, k)
        content = np.einsum("ik,ik->k", P, np.linalg.solve(mass["G"], P))
        return content > 0.5

    # -- mode shapes at points ------------------------------------------------
    def interpolation(self, points: np.ndarray, component: int = 2) -> sp.csr_matrix:
        """(n_points, n_dof) sparse map from DOFs to one field (2 = w0) at (x, y) points."""
        e, xi, eta = self.mesh.locate(points)
        N, _, _ = _shape_2d(xi, eta)
        cols = NODE_DOF * self.mesh.connectivity[e] + component
        rows = np.repeat(np.arange(len(e)), 16)
        return sp.csr_matrix((N.ravel(), (rows, cols.ravel())), shape=(len(e), self.mesh.n_dof))

    def shapes_at(self, modes: Modes, points) -> np.ndarray:
        """(n_modes, n_points) w0 of each mode at (x, y) points, same scaling as modes.shapes."""
        T = self.interpolation(points)
        return np.asarray((T @ modes.shapes).T)

    # -- sensitivities ----------------------------------------------------------
    def eigen_sensitivities(self, modes: Modes, names: Sequence[str], params=None,
                            material=None) -> np.ndarray:
        """(n_modes, len(names)) d(omega^2)/dp = phi'(dK/dp - omega^2 dM/dp) phi, rad^2/s^2 per unit p.

        ``params``/``material`` must be those the modes were solved with
        (defaults: the ones recorded in ``modes``).
        """
        if params is None:
            params, material = modes.params, (modes.material if material is None else material)
        name = self._material_name(material)
        mat = self._materials(params, material)[name]
        dq = _q_derivatives(mat, list(names))          # (7, P)
        L, R = self._maps[name]
        dc = L @ dq[:6]                                 # (21, P)
        dI = np.outer(R, dq[6])                         # (3, P)
        pat = self._pat
        phi = modes.shapes[self.mesh.element_dofs].transpose(2, 0, 1)   # (m, ne, 80)
        m = phi.shape[0]
        nt = pat.type_scales.shape[0]
        # S[t, mode] = sum over elements of type t of phi_e phi_e' (80 x 80), by matmul
        S = np.empty((nt, m, 80, 80))
        for t in range(nt):
            ph = phi[:, pat.elem_type == t] if nt > 1 else phi
            np.matmul(ph.transpose(0, 2, 1), ph, out=S[t])
        Sc = (pat.type_scales.T @ S.reshape(nt, -1)).reshape(6, m, 6400)  # per scale combo
        if "Ke_rows" not in self._cache:   # (6, 6400, 21) reference K per combo, 21 columns
            self._cache["Ke_rows"] = np.ascontiguousarray(self._Ke.reshape(6, 21, 6400).transpose(0, 2, 1))
        Kr = self._cache["Ke_rows"]
        eK = sum(Sc[p] @ Kr[p] for p in range(6))                       # (m, 21)
        eM = Sc[0] @ self._Me.reshape(3, 6400).T                        # (m, 3)
        return eK @ dc - modes.omega2[:, None] * (eM @ dI)


def natural_frequencies(laminate: Laminate, length: float, width: float, n: int = 10,
                        mesh=None) -> np.ndarray:
    """The n lowest free-free elastic natural frequencies, Hz."""
    return PlateModel.build(laminate, length, width, mesh).solve(n).frequencies_hz
