"""Per-mode discretisation error of the plate model, from two meshes (the model-form allowance).

The diagnosis' plate model uses the default mesh (``Mesh.default``: n interior
elements along the longer side). The same plate on a finer mesh (3n/2)
gives, mode by mode, the change f_n - f_3n/2; with the O(h^2) convergence of
the element, Richardson's estimate of the default mesh's error is
|f_n - f_3n/2| / (1 - (2/3)^2) = 1.8 |f_n - f_3n/2| (Hz). The modes of the two
meshes are matched by MAC on a 9 x 9 grid. This enters the whitening in
quadrature with the measured sigma, so modes above the mesh's converged range
are used with their error instead of being cut.

(Helper note: ``engine/plate/convergence.py`` on the identification side does
the same job for ``labid identify``; the two should be unified.)
"""
from __future__ import annotations

import math

import numpy as np

from ..forward import mac
from ..plate import DEFAULT_ELEMENTS, Mesh, PlateModel

__all__ = ["discretisation_error", "RICHARDSON"]

#: error of the default mesh per unit difference to the 1.5x finer one (O(h^2))
RICHARDSON = 1.0 / (1.0 - (2.0 / 3.0) ** 2)


def discretisation_error(fw, params, modal_fw=None) -> np.ndarray:
    """Estimated FE error (Hz) of each measured mode's predicted frequency at ``params``.

    ``fw``: the diagnosis' forward model (default mesh, declared masses);
    ``modal_fw``: its paired modal forward model (default ``fw.modal_forward()``).
    """
    p = fw.features
    mf = modal_fw if modal_fw is not None else fw.modal_forward()
    modes, idx, _ = mf.solve(dict(params))
    big, small = max(p.length, p.width), min(p.length, p.width)
    n_fine = int(math.ceil(1.5 * DEFAULT_ELEMENTS * math.sqrt(big / small) - 1e-9))
    fine = PlateModel.build(p.laminate, p.length, p.width, Mesh.default(p.length, p.width,
                                                                        p.laminate.thickness, n=n_fine))
    masses = p.rig.masses()
    if masses:
        fine = fine.with_point_masses(masses)
    n_need = int(np.max(idx)) + 1
    fm = fine.solve(n_need + 4, params=dict(params), material=p.material)
    g = np.linspace(0.0, 1.0, 9)
    X, Y = np.meshgrid(g * p.length, g * p.width)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    A = mf.model.shapes_at(modes, pts)[idx]
    B = fine.shapes_at(fm, pts)
    M = mac(A, B)
    # nearest fine mode by MAC, ties broken by frequency
    f_def = modes.frequencies_hz[idx]
    cost = (1.0 - M) + np.abs(np.log(f_def[:, None] / fm.frequencies_hz[None, :]))
    j = np.argmin(cost, axis=1)
    return RICHARDSON * np.abs(f_def - fm.frequencies_hz[j])
