"""Thickness field of the plate: per-element weights of the powers of the thickness scale.

Scaling every ply of an element by s (mid-plane fixed) scales the ply interfaces
z -> s z, so the laminate coefficients go with powers of s: A and H ~ s, B ~ s^2,
D ~ s^3, and the inertias I1, I2, I3 ~ s, s^2, s^3 (``COEF_POWER``). The
element matrices stay linear in the 21 coefficients: one element matrix per
element type and power, and one weighted scatter of fixed pattern (built once
per field) keep the re-solve for new constants free of element loops.

Units: s dimensionless; x, y in m.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .element import FEError
from .mesh import Mesh
from .sparse import Pattern

__all__ = ["COEF_POWER", "thickness_weights", "field_scatter"]

#: power of the thickness scale s of each stiffness coefficient (COEF_NAMES order)
COEF_POWER = np.array([1] * 6 + [2] * 6 + [3] * 6 + [1] * 3)


def thickness_weights(mesh: Mesh, scale) -> np.ndarray:
    """(3, n_elements) element means of s, s^2, s^3; element = ey * nx + ex.

    ``scale``: one factor per element, or a callable s(x, y) of arrays (m),
    averaged over each element with 4 x 4 Gauss points (exact for s^p of degree
    <= 7 in x and y, e.g. a linear s up to p = 3)."""
    if callable(scale):
        g, wg = np.polynomial.legendre.leggauss(4)
        xe, ye = mesh.xe, mesh.ye
        xq = xe[:-1, None] + np.diff(xe)[:, None] * (1.0 + g) / 2.0    # (nx, 4)
        yq = ye[:-1, None] + np.diff(ye)[:, None] * (1.0 + g) / 2.0    # (ny, 4)
        X = np.broadcast_to(xq[None, :, None, :], (mesh.ny, mesh.nx, 4, 4))
        Y = np.broadcast_to(yq[:, None, :, None], (mesh.ny, mesh.nx, 4, 4))
        sq = np.asarray(scale(X, Y), float) * np.ones(X.shape)             # (ny, nx, 4[y], 4[x])
        if not np.all(np.isfinite(sq)) or np.any(sq <= 0):
            raise FEError("thickness field: expected finite s(x, y) > 0 over the plate")
        wq = np.outer(wg, wg) / 4.0
        return np.stack([np.einsum("abij,ij->ab", sq**p, wq).ravel() for p in (1, 2, 3)])
    s = np.asarray(scale, float)
    if s.shape != (mesh.n_elements,):
        raise FEError(f"thickness field of shape {s.shape}: expected one factor per element "
                      f"({mesh.n_elements},)")
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise FEError("thickness field: expected finite factors > 0")
    return np.stack([s, s**2, s**3])


def field_scatter(pat: Pattern, tw: np.ndarray) -> sp.csr_matrix:
    """(nnz, 3 n_types 6400): element data per type and power of s (stacked p = 1, 2, 3)
    to the global data, each element weighted by its mean s^p (``tw`` from thickness_weights)."""
    nt = pat.type_scales.shape[0]
    rows = np.tile(pat.elem_pos.ravel(), 3)
    local = (pat.elem_type[:, None] * 6400 + np.arange(6400)).ravel()
    cols = np.concatenate([local + p * nt * 6400 for p in range(3)])
    data = np.repeat(tw, 6400, axis=1).ravel()
    return sp.csr_matrix((data, (rows, cols)), shape=(pat.indices.size, 3 * nt * 6400))
