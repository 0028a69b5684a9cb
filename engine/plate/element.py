"""The 16-node bicubic Mindlin plate element: shape functions, quadrature, reference matrices.

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

Units SI: m, kg, s, Pa. The reference matrices are per unit stiffness coefficient
(COEF_NAMES, :mod:`engine.plate.stiffness`) and per unit inertia (I1, I2, I3).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["FEError", "NODE_DOF", "SYM3", "SYM2", "shape_2d", "combo_scales", "reference_matrices",
           "reference_by_coefficient", "reference_by_combo"]

NODE_DOF = 5   # (u0, v0, w0, bx, by); global DOF = 5 node + k
_NODES_1D = np.array([-1.0, -1.0 / 3.0, 1.0 / 3.0, 1.0])
_G4, _W4 = np.polynomial.legendre.leggauss(4)
_G3, _ = np.polynomial.legendre.leggauss(3)
SYM3 = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
SYM2 = ((0, 0), (0, 1), (1, 1))


class FEError(ValueError):
    """Bad mesh, point outside the plate, or a failed rigid-body-mode check."""


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


def shape_2d(xi: np.ndarray, eta: np.ndarray):
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


def combo_scales(h: np.ndarray) -> np.ndarray:
    """(n, 6) factors s_pq = hx hy / 4 * f_p f_q with f_0 = 1, f_x = 2/hx, f_y = 2/hy."""
    hx, hy = h[:, 0], h[:, 1]
    return np.column_stack([hx * hy / 4.0, hy / 2.0, hx / 2.0, hy / hx, np.ones_like(hx), hx / hy])


@lru_cache(maxsize=1)
def reference_by_coefficient() -> np.ndarray:
    """The reference K as (21 coefficients, 6 combos x 6400), contiguous: one matrix product
    with the coefficients gives the unit element matrix per combo. The one stored copy of
    the reference K (read-only): :func:`reference_matrices` and :func:`reference_by_combo`
    are views of it (each ``PlateModel`` held two 6.2 MB copies, 55 MB in a 3-constant
    diagnosis; bench/RESULTS.md, issue 29)."""
    K = np.ascontiguousarray(_reference_matrices()[0].transpose(1, 0, 2, 3).reshape(21, -1))
    K.flags.writeable = False
    return K


def reference_by_combo() -> np.ndarray:
    """The reference K as (6 combos, 6400, 21) (a view: per combo a BLAS-ready transposed
    block, for the sensitivities' products)."""
    return reference_by_coefficient().reshape(21, 6, 6400).transpose(1, 2, 0)


@lru_cache(maxsize=1)
def reference_matrices() -> tuple[np.ndarray, np.ndarray]:
    """Reference element matrices: K (6 combos, 21 coefs, 80, 80), M (3 inertias, 80, 80).

    The unit stiffness of coefficient i of an element (hx, hy) is
    sum_pq s_pq(hx, hy) K[pq, i]; its unit mass is s_00 M. Computed once and shared by every
    model, read-only (K a view of :func:`reference_by_coefficient`).
    """
    M = _reference_matrices()[1]
    M.flags.writeable = False
    return reference_by_coefficient().reshape(21, 6, 80, 80).transpose(1, 0, 2, 3), M


def _reference_matrices() -> tuple[np.ndarray, np.ndarray]:
    XI, ETA = np.meshgrid(_G4, _G4, indexing="ij")
    xi, eta = XI.ravel(), ETA.ravel()
    w = np.outer(_W4, _W4).ravel()
    npt = len(xi)
    N, Nxi, Neta = shape_2d(xi, eta)

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
    Nt, Ntx, _ = shape_2d(TX.ravel(), TY.ravel())
    to_int_x = lambda f: np.einsum("ak,kbd->abd", lx, f.reshape(3, 4, 80)).reshape(npt, 80)
    gxz0, gxzx = to_int_x(field(BX, Nt)), to_int_x(field(W, Ntx))
    TX, TY = np.meshgrid(_G4, _G3, indexing="ij")  # yz: 4 along x, 3 along y
    Nt, _, Nty = shape_2d(TX.ravel(), TY.ravel())
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
        for c, (i, j) in enumerate(SYM3):
            if "0" not in combo:
                K[ci, c] = unit(Bm, Bm, p, q, i, j)
                K[ci, 12 + c] = unit(Bb, Bb, p, q, i, j)
                mb = unit(Bm, Bb, p, q, i, j)
                K[ci, 6 + c] = mb + mb.T
        for c, (i, j) in enumerate(SYM2):
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
