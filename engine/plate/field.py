"""Thickness field of the plate: per-element weights of the powers of the thickness scale.

Scaling every ply of an element by s (mid-plane fixed) scales the ply interfaces
z -> s z, so the laminate coefficients go with powers of s: A and H ~ s, B ~ s^2,
D ~ s^3, and the inertias I1, I2, I3 ~ s, s^2, s^3 (``COEF_POWER``). The
element matrices stay linear in the 21 coefficients: one element matrix per
element type and power, weighted per element and summed into the fixed pattern
(``field_data``, one ``np.bincount``), keep the re-solve for new constants free of
element loops.

Units: s dimensionless; x, y in m.
"""
from __future__ import annotations

import numpy as np

from .element import FEError
from .mesh import Mesh
from .sparse import Pattern

__all__ = ["COEF_POWER", "thickness_weights", "field_data"]

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


def field_data(pat: Pattern, tw: np.ndarray, per_power: np.ndarray) -> np.ndarray:
    """Global data (nnz,) of element matrices given per power of s and element type,
    ``per_power`` (3, n_types, 6400), each element weighted by its mean s^p (``tw`` from
    thickness_weights). Summed per entry by ``np.bincount`` on the element positions: no
    weighted scatter matrix (it took 9.4 MB per field and ~47 MB while built, the peak of
    a 3-constant diagnosis; bench/RESULTS.md, issue 29)."""
    elem = np.einsum("pe,pek->ek", tw, per_power[:, pat.elem_type])           # (n_elements, 6400)
    return np.bincount(pat.elem_pos.ravel(), weights=elem.ravel(), minlength=pat.indices.size)
