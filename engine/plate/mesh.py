"""Tensor-grid meshes of rectangular 16-node elements on a free rectangular plate.

Meshes: uniform free-edge meshes converge only like O(h) because of the
Mindlin free-edge boundary layer (width ~ thickness); the default mesh adds one
row of elements 2 thicknesses wide along every edge (bench/RESULTS.md).

Units: m.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .element import NODE_DOF, FEError

__all__ = ["Mesh", "DEFAULT_ELEMENTS", "EDGE_LAYER"]

#: Default mesh (CFRP convergence study, bench/RESULTS.md): DEFAULT_ELEMENTS
#: interior elements along the longer side plus an edge row of EDGE_LAYER
#: plate thicknesses; ten elastic modes of the 12-ply CFRP within 0.05 %.
DEFAULT_ELEMENTS = 6
EDGE_LAYER = 2.0


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
