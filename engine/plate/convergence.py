"""Discretisation error of the plate model: reference meshes and per-mode error from two meshes.

The identification's default mesh (``Mesh.default``: DEFAULT_ELEMENTS interior elements
along the longer side) holds ten modes of the 12-ply CFRP within 0.05 %, but its error
grows with the mode number: measured on that plate (330 x 330 x 1.6 mm, 60 modes) against
an 18-element mesh, 0.03 % at mode 12, 0.46 % at mode 24, 1.9 % at mode 39 and up to 4.8 %
by mode 60 -- far above a 0.1 % measurement sigma. With 9 elements the same modes are within
0.05 / 0.25 / 0.29 % and 0.51 % at worst, with 12 within 0.01 / 0.05 / 0.06 % and 0.11 %.

* :func:`reference_mesh` -- a mesh ``REFERENCE_FACTOR`` x finer per direction than the
  default (what the simulated rig synthesises from: the identification's model never
  coincides with the "real" plate).
* :func:`mode_corrections` -- the model's modes on its own mesh and on a mesh
  ``FINE_FACTOR`` x finer: per mode the ratio f_fine / f_coarse (applied to the coarse
  predictions) and the remaining error of the corrected prediction, estimated by
  Richardson extrapolation with a conservative order ``ORDER`` (the cubic 16-node element
  converged at order ~5.4 on the CFRP plate above): ``|f_fine - f_coarse| r^p / (1 - r^p)``,
  r = 1 / FINE_FACTOR.

Units: m, Hz.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .mesh import DEFAULT_ELEMENTS, Mesh

__all__ = ["reference_mesh", "finer_mesh", "mode_corrections", "ModeCorrections", "REFERENCE_FACTOR",
           "FINE_FACTOR", "ORDER"]

#: the simulated rig's mesh: 2x the default elements per direction (4x the DOF); on the CFRP
#: plate its 60 lowest modes are within 0.11 % (0.06 % by mode 40) of an 18-element mesh
REFERENCE_FACTOR = 2.0
#: the identification's second mesh (per-mode correction and error)
FINE_FACTOR = 1.5
#: convergence order assumed by the Richardson estimate (measured ~5.4; 4 is conservative)
ORDER = 4.0


def _default_n(length: float, width: float) -> int:
    big, small = max(length, width), min(length, width)
    return int(np.ceil(DEFAULT_ELEMENTS * np.sqrt(big / small) - 1e-9))


def finer_mesh(length: float, width: float, thickness: float | None, factor: float) -> Mesh:
    """``Mesh.default`` with ``factor`` x the interior elements along each side (m)."""
    return Mesh.default(length, width, thickness, n=int(math.ceil(factor * _default_n(length, width))))


def reference_mesh(length: float, width: float, thickness: float | None) -> Mesh:
    """The converged reference mesh (REFERENCE_FACTOR x the default elements)."""
    return finer_mesh(length, width, thickness, REFERENCE_FACTOR)


@dataclass(frozen=True)
class ModeCorrections:
    """Per mode (ascending, elastic): ``ratio`` f_fine / f_coarse and ``error_rel`` the
    estimated relative error of the corrected coarse prediction; ``coarse_hz``, ``fine_hz``."""

    ratio: np.ndarray
    error_rel: np.ndarray
    coarse_hz: np.ndarray
    fine_hz: np.ndarray


def mode_corrections(model, fine_model, n_modes: int, params: Mapping[str, float] | None = None,
                     material: str | None = None, order: float = ORDER) -> ModeCorrections:
    """Correction and error of ``model``'s ``n_modes`` lowest modes from ``fine_model``
    (the same plate on a finer mesh) at ``params``. Modes are matched by MAC on the
    fine model's shapes at the coarse nodes' positions when their order differs."""
    cm = model.solve(n_modes, params=dict(params or {}), material=material)
    fm = fine_model.solve(n_modes, params=dict(params or {}), material=material)
    fc, ff = cm.frequencies_hz, fm.frequencies_hz
    # pair by shapes at a grid of points (close modes may swap order between meshes)
    m = model.mesh
    xs = np.linspace(0.02, 0.98, 13) * m.length
    ys = np.linspace(0.02, 0.98, 13) * m.width
    pts = np.array([[x, y] for x in xs for y in ys])
    a, b = model.shapes_at(cm, pts), fine_model.shapes_at(fm, pts)
    num = np.abs(a @ b.T) ** 2
    den = np.outer((a * a).sum(1), (b * b).sum(1))
    M = num / np.where(den > 0, den, np.inf)
    idx = np.arange(n_modes)
    best = np.argmax(M, axis=1)
    if len(set(best.tolist())) == n_modes:
        idx = best
    fpair = ff[idx]
    r = 1.0 / FINE_FACTOR
    k = r ** order / (1.0 - r ** order)
    ratio = fpair / fc
    err = np.abs(fpair - fc) * k / fpair
    return ModeCorrections(ratio, err, fc, fpair)
