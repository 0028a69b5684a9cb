"""Mode family labels of a free plate from its FE mode shapes: (m, n) in nodal lines.

A free plate's modes are classically described by products of free-free beam functions
X_m(x) Y_n(y) (Warburton; Leissa, *Vibration of Plates*, NASA SP-160, ch. 4): X_0 = 1
(translation), X_1 = 2x/L - 1 (rotation), X_m (m >= 2) the free-free beam modes with
beta_m L = 4.730, 7.853, 10.996, ... (roots of cos(b) cosh(b) = 1). X_m has m nodes, so
the label (m, n) counts the nodal lines crossed along x and along y: (2,0) is the first
bending mode along the length, (1,1) the twisting (torsion) mode, (0,2) the first bending
mode across the width. Each FE shape w(x, y) is projected on the products (these are
orthogonal on the plate), and the label is the dominant product. Anisotropic plates skew
and curve the nodal lines, and square plates combine degenerate (m, n) and (n, m) shapes
into X- and ring-shaped modes: when a second product carries at least half the energy of
the first, both are named, '(2,0)/(0,2)'. Modes with no transverse displacement (in-plane,
membrane modes) are labelled 'in-plane'. Positions in m.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["beam_function", "family_components", "family_label", "mode_families"]

#: highest beam-function order used (nodal lines per direction)
MAX_ORDER = 9
#: a second product is named when its energy share is at least this fraction of the first
MIXED = 0.5


def _beta(m: int) -> float:
    """beta_m L of the free-free beam: roots of cos(b) cosh(b) = 1 (m >= 2)."""
    b = (2 * m - 1) * np.pi / 2
    for _ in range(30):   # Newton on f(b) = cos b cosh b - 1
        f = np.cos(b) * np.cosh(b) - 1.0
        df = -np.sin(b) * np.cosh(b) + np.cos(b) * np.sinh(b)
        b -= f / df
    return float(b)


def beam_function(m: int, s: np.ndarray) -> np.ndarray:
    """Free-free beam function X_m on s = x / L in [0, 1] (unnormalised; m nodes)."""
    s = np.asarray(s, float)
    if m == 0:
        return np.ones_like(s)
    if m == 1:
        return 2.0 * s - 1.0
    b = _beta(m)
    sig = (np.cosh(b) - np.cos(b)) / (np.sinh(b) - np.sin(b))
    # cosh(bs) - sig sinh(bs) written with exp(-bs) terms: no cancellation for large b
    hyp = 0.5 * ((1.0 - sig) * np.exp(b * s) + (1.0 + sig) * np.exp(-b * s))
    return hyp + np.cos(b * s) - sig * np.sin(b * s)


@lru_cache(maxsize=8)
def _basis(n_pts: int) -> np.ndarray:
    """(MAX_ORDER + 1, n_pts) beam functions on a uniform grid of [0, 1], unit rms (read-only,
    kept: it was rebuilt for every mode, 7 % of a 3-constant identification's CPU)."""
    s = np.linspace(0.0, 1.0, n_pts)
    B = np.array([beam_function(m, s) for m in range(MAX_ORDER + 1)])
    B = B / np.sqrt(np.mean(B ** 2, axis=1, keepdims=True))
    B.flags.writeable = False
    return B


def family_components(w: np.ndarray) -> np.ndarray:
    """Energy share of every product X_m Y_n in one shape sampled on a uniform grid
    ``w[iy, ix]`` over the plate: array ``E[m, n]`` summing to <= 1."""
    w = np.asarray(w, float)
    ny, nx = w.shape
    Bx, By = _basis(nx), _basis(ny)
    C = By @ w @ Bx.T / (nx * ny)        # C[n, m]: projection on Y_n X_m
    total = float(np.mean(w ** 2))
    return (C.T ** 2) / total if total > 0 else np.zeros_like(C.T)


def family_label(E: np.ndarray) -> str:
    """'(m,n)' of the dominant product, '(1,1) torsion', or '(m,n)/(p,q)' for a mixed shape."""
    order = np.argsort(E, axis=None)[::-1]
    (m, n), (p, q) = np.unravel_index(order[0], E.shape), np.unravel_index(order[1], E.shape)
    first = "(1,1) torsion" if (m, n) == (1, 1) else f"({m},{n})"
    if E[p, q] >= MIXED * E[m, n]:
        return f"({m},{n})/({p},{q})"
    return first


def mode_families(model, modes, length: float, width: float, n_grid: int = 61) -> list[str]:
    """Family label of every mode of ``modes`` (``engine.plate.Modes`` of ``model``, a
    ``PlateModel``) on a plate ``length`` x ``width`` (m), e.g. ['(1,1) torsion', '(2,0)']."""
    xs = np.linspace(0.0, length, n_grid)
    ys = np.linspace(0.0, width, n_grid)
    X, Y = np.meshgrid(xs, ys)
    W = model.shapes_at(modes, np.column_stack([X.ravel(), Y.ravel()]))
    # transverse amplitude per unit modal mass: in-plane modes have none
    peaks = np.max(np.abs(W), axis=1)
    ref = float(np.median(peaks)) if peaks.size else 0.0
    return ["in-plane" if p < 1e-6 * ref else family_label(family_components(w.reshape(n_grid, n_grid)))
            for w, p in zip(W, peaks)]
