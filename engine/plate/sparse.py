"""Fixed sparse pattern of the global plate matrices, its element scatter and eigen blocks.

Every element matrix is a fixed linear combination of reference matrices
(:mod:`engine.plate.element`), so a new parameter set needs one 80x80 matrix per
element size and one scatter of fixed pattern into the CSR data (``Pattern.scatter``);
the mass matrix keeps its own sub-pattern (~1/5 of the entries: a third of the
ARPACK time went to M products on the full K pattern), and the DOF blocks of a
symmetric layup (bending / membrane) have their positions precomputed (``Block``).

Why hand-made (measured, kept on purpose): on the default CFRP mesh (3125 DOF)
K and M from new constants cost 4.4 ms CPU against 10.7 ms for scipy's textbook
COO assembly (``coo_matrix((data, (rows, cols))).tocsr()``) and 12.8 ms with the
bending-block slicing a symmetric layup needs: 17-23 % of the CPU time of every
solve (bench/bench_plate_pattern.py, bench/RESULTS.md); the matrices are the same
to 1e-14 (``tests/test_plate_fe.py::test_fixed_pattern_equals_scipy_coo_assembly``).

Eigen solver: shift-invert Lanczos (ARPACK eigsh) with a small negative shift,
SuperLU factorisation of K - sigma M, on one DOF block (all fields, or the
bending / membrane fields of a symmetric layup).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .element import NODE_DOF, combo_scales, shape_2d
from .mesh import Mesh
from .warm import COUNTS, WarmStart, warm_eig

__all__ = ["Pattern", "Block", "point_entries", "Added", "symmetric_lu"]


def symmetric_lu(A: sp.spmatrix):
    """SuperLU of a symmetric positive definite ``A`` (K - sigma M, sigma below the spectrum):
    symmetric ordering of A + A', diagonal pivots (the eigen blocks, the surrogate's
    shift-invert blocks)."""
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


@dataclass(frozen=True)
class Pattern:
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
    def build(cls, mesh: Mesh) -> "Pattern":
        """The pattern of ``mesh`` from its node pairs: element DOFs are node-blocked (5 a + k),
        so the unique (row, column) DOF pairs and each element entry's position follow from
        the unique NODE pairs, 25x fewer to sort than the 6400 DOF pairs per element (the
        demo plate's 1.5x mesh: 0.12 -> 0.02 s CPU warm, 0.17-0.25 s cold in identify's
        profile; bench/RESULTS.md, issue 29 session 27). Equal arrays to a np.unique of
        the DOF pairs (tests/unit/engine/plate/test_plate_pattern.py)."""
        conn = np.asarray(mesh.connectivity)
        ne, nl = conn.shape
        nd = NODE_DOF
        h = mesh.element_sizes
        hq = np.round(h / max(mesh.length, mesh.width), 12)
        _, first, etype = np.unique(hq, axis=0, return_index=True, return_inverse=True)
        etype = etype.ravel()
        nn = mesh.n_dof // nd
        ukey, ninv = np.unique((conn[:, :, None].astype(np.int64) * nn + conn[:, None, :]).ravel(),
                               return_inverse=True)
        na, nb = np.divmod(ukey, nn)
        nodeptr = np.searchsorted(na, np.arange(nn + 1))
        deg = np.diff(nodeptr)
        # DOF row (a, fa) holds the columns nd b + fb over a's neighbours b (ascending), fb < nd
        row_len = np.repeat(nd * deg, nd)
        indptr = np.concatenate([[0], np.cumsum(row_len)])
        within = np.arange(indptr[-1]) - np.repeat(indptr[:-1] - np.repeat(nd * nodeptr[:-1], nd), row_len)
        c = (nd * nb[:, None] + np.arange(nd)).ravel()[within]
        fr, fc = np.repeat(np.arange(nn * nd) % nd, row_len), c % nd
        # element entry (local node i, field fa; local node j, field fb), row node a: position
        # nd^2 nodeptr[a] + nd fa deg[a] + nd (q - nodeptr[a]) + fb, q its node pair's index
        f = np.arange(nd)
        base = nd * ninv.reshape(ne, nl, nl) + (nd * nd - nd) * nodeptr[conn][:, :, None]
        inv = (base[:, :, None, :, None] + nd * f[None, None, :, None, None] * deg[conn][:, :, None, None, None]
               + f[None, None, None, None, :]).reshape(ne, -1)
        local = (etype[:, None] * 6400 + np.arange(6400)).ravel()
        scatter = sp.csr_matrix((np.ones(inv.size), (inv.ravel(), local)),
                                shape=(c.size, len(first) * 6400))
        pair = np.minimum(fr, fc) * 10 + np.maximum(fr, fc)
        m_mask = (fr == fc) | (pair == 3) | (pair == 14)  # same field, u-bx, v-by
        m_indptr = np.concatenate([[0], np.cumsum(np.add.reduceat(m_mask, indptr[:-1]))])
        cross = (fr < 2) != (fc < 2)
        return cls(indptr.astype(np.int32), c.astype(np.int32), scatter, inv, etype,
                   combo_scales(h[first]), m_mask, m_indptr.astype(np.int32), cross)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        n = len(self.indptr) - 1
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(n, n))

    def mass_matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """M from full-pattern data, keeping only its structural non-zeros (~1/5)."""
        n = len(self.indptr) - 1
        return sp.csr_matrix((data[self.m_mask], self.indices[self.m_mask], self.m_indptr),
                             shape=(n, n))


@dataclass(frozen=True)
class Block:
    """A set of DOF fields whose K, M rows/columns are solved on their own."""

    dofs: np.ndarray      # global DOFs of the block, ascending
    k_pos: np.ndarray     # positions (in the full pattern data) of the block's entries
    indptr: np.ndarray    # block CSR pattern (renumbered)
    indices: np.ndarray
    m_sel: np.ndarray     # positions (in the block data) where M may be non-zero
    m_indptr: np.ndarray

    @classmethod
    def build(cls, pat: Pattern, fields: Sequence[int]) -> "Block":
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

    def factor(self, kd: np.ndarray, mb: np.ndarray, sigma: float):
        """SuperLU of the block's K - sigma M (K data ``kd`` on the full pattern, ``mb``
        the block mass data)."""
        nb = self.dofs.size
        # K - sigma M is symmetric: its CSR arrays are also its CSC arrays
        return symmetric_lu(sp.csc_matrix((kd[self.k_pos] - sigma * mb, self.indices, self.indptr), shape=(nb, nb)))

    def eig(self, kd: np.ndarray, md: np.ndarray, k: int, sigma: float, n_full: int,
            mass: tuple[np.ndarray, sp.csr_matrix] | None = None, ncv: int | None = None, lu=None):
        """k eigenpairs nearest sigma (shift-invert), vectors expanded to n_full DOFs.

        ``mass``: ``self.mass(md)`` when already known (M depends on density only);
        ``ncv``: Lanczos basis size (default max(2k + 1, 20)); ``lu``: ``self.factor``'s."""
        nb = self.dofs.size
        mb, M = self.mass(md) if mass is None else mass
        lu = self.factor(kd, mb, sigma) if lu is None else lu
        op = spla.LinearOperator((nb, nb), matvec=lu.solve, dtype=float)
        v0 = np.random.default_rng(20120101).standard_normal(nb)  # reproducible
        # A itself is not used by eigsh when OPinv is given (only its shape and dtype)
        lam, vec = spla.eigsh(op, k=k, M=M, sigma=sigma, OPinv=op, which="LM", v0=v0,
                              ncv=min(nb - 1, ncv or max(2 * k + 1, 20)), tol=1e-10)
        return lam, self.expand(vec, n_full)

    def expand(self, vec: np.ndarray, n_full: int) -> np.ndarray:
        """Block vectors (n_block, k) as full vectors (n_full, k), zero outside the block."""
        full = np.zeros((n_full, vec.shape[1]))
        full[self.dofs] = vec
        return full

    def eig_warm(self, kd: np.ndarray, k: int, sigma: float, n_full: int, mass, ncv: int | None,
                 start, c: np.ndarray, coupled: bool, n_want: int):
        """(lam, full vectors, the next WarmStart, "warm" | "arpack"): the n_want lowest
        eigenpairs from ``start`` (engine.plate.warm, certified) when it can, else ARPACK's
        k (one factorisation either way)."""
        mb, M = mass
        lu = self.factor(kd, mb, sigma)
        if start is not None:
            got = warm_eig(start, lu, M, sigma, c, coupled, n_want)
            if got is not None:
                lam, vec, nxt = got
                COUNTS["warm"] += 1
                return lam, self.expand(vec, n_full), nxt, "warm"
            COUNTS["failed"] += 1
        lam, full = self.eig(kd, None, k, sigma, n_full, mass, ncv=ncv, lu=lu)
        o = np.argsort(lam)
        nxt = None
        if lam.size > n_want:   # ARPACK's values are converged to 1e-10 (relative, theta)
            nxt = WarmStart(full[self.dofs][:, o], lam[o], n_want, float(lam[o][n_want]) * (1 - 1e-8),
                            np.array(c, float), M)
        return lam, full, nxt, "arpack"


def point_entries(mesh: Mesh, pat: Pattern, x: float, y: float,
                  diag: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(positions in the pattern's data, values) of sum_k diag[k] N_k' N_k for the 5 DOF
    fields at one point (one element's 6400 entries)."""
    e, xi, eta = mesh.locate([[x, y]])
    N, _, _ = shape_2d(xi, eta)
    NN = np.outer(N[0], N[0])
    Me = np.zeros((16, NODE_DOF, 16, NODE_DOF))
    for k, v in enumerate(diag):
        if v:
            Me[:, k, :, k] = v * NN
    return pat.elem_pos[e[0]], Me.ravel()


@dataclass(frozen=True)
class Added:
    """Stiffness or mass added to a pattern's data (springs, point masses, a stiffness loss):
    sorted unique positions and their values. Kept sparse: a full-length array per model
    (2.9 MB on the demo's mesh, mostly zeros) made ~20 MB of a 3-constant diagnosis' peak,
    whose effect refits keep several models (bench/RESULTS.md, issue 29)."""

    idx: np.ndarray
    val: np.ndarray

    @classmethod
    def none(cls) -> "Added":
        return cls(np.zeros(0, np.int64), np.zeros(0))

    def plus(self, pos: np.ndarray, vals: np.ndarray) -> "Added":
        """These values added at ``pos`` (repeats within ``pos`` summed in order first).
        Merged into the sorted positions (a diagnosis adds masses to models that hold
        200 000 entries: a full re-sort per mass cost it 1.3 s CPU)."""
        u, inv = np.unique(np.asarray(pos, np.int64).ravel(), return_inverse=True)
        nv = np.bincount(inv.ravel(), weights=np.asarray(vals, float).ravel(), minlength=u.size)
        loc = np.searchsorted(self.idx, u)
        found = loc < self.idx.size
        found[found] = self.idx[loc[found]] == u[found]
        val = self.val.copy()
        val[loc[found]] += nv[found]
        new = ~found
        return Added(np.insert(self.idx, loc[new], u[new]), np.insert(val, loc[new], nv[new]))

    def add_to(self, data: np.ndarray) -> np.ndarray:
        """``data`` (owned by the caller) with the values added in place."""
        data[self.idx] += self.val
        return data

    def dense(self, n: int) -> np.ndarray:
        out = np.zeros(n)
        out[self.idx] = self.val
        return out

    def any_at(self, mask: np.ndarray) -> bool:
        """True when a non-zero value sits where ``mask`` (over the data) is True."""
        return bool(np.any(self.val[mask[self.idx]] != 0))
