"""Eigenvalue sensitivities of a ``PlateModel`` from one solve: d lambda = phi'(dK - lambda dM) phi.

Every input that changes K and M linearly in a known way is differentiated from the
modes at hand, without a new solve (Nelson's first-order term for mass-normalised modes):

* the 21 laminate coefficients and the inertias (I1, I2, I3): the per-coefficient strain
  and kinetic energies of each mode (:func:`coefficient_energies`), from which
  ``PlateModel.eigen_sensitivities`` gives d lambda / d(material constant);
* the geometry (:func:`geometry_sensitivities`): a uniform thickness scale (A, H ~ s,
  B ~ s^2, D ~ s^3, I_k ~ s^k, ``field.COEF_POWER``), a stretch of the plate in x or y (each
  element matrix is a sum of reference matrices times monomials of the element size,
  ``element.combo_scales``), the plate's density, and the positions of point masses (the
  shape functions' slope at the mass).

Measured reason (bench/RESULTS.md, issue 29): the GUM budget of the demo's combined
identification finite-differenced these inputs with 13 re-solves and 5 model builds
(2.7 s CPU, a quarter of ``labid identify``); here they cost one product per mode.

Units SI: lambda = omega^2 in rad^2/s^2; derivatives per unit scale factor (thickness,
length, width, density) or per metre (mass positions).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .element import NODE_DOF, reference_by_combo, shape_2d
from .field import COEF_POWER

__all__ = ["coefficient_energies", "geometry_sensitivities", "X_POWER", "Y_POWER"]

#: powers of the element sizes hx, hy in the six reference-matrix scales s_pq of
#: ``element.combo_scales``: (hx hy / 4, hy / 2, hx / 2, hy / hx, 1, hx / hy)
X_POWER = np.array([1, 0, 1, -1, 0, 1])
Y_POWER = np.array([1, 1, 0, 1, 0, -1])


def coefficient_energies(model, modes, per_combo: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(eK, eM): phi' dK/dc_k phi for the 21 coefficients, (m, 21) -- or per scale combination
    of the element matrices, (6, m, 21), with ``per_combo`` -- and phi' dM/dI_j phi for the
    three inertias, (m, 3); ``modes`` of ``model`` (a thickness field weights them)."""
    pat = model._pat
    phi = modes.shapes[model.mesh.element_dofs].transpose(2, 0, 1)   # (m, ne, 80)
    m = phi.shape[0]
    nt = pat.type_scales.shape[0]
    Kr = reference_by_combo()                                        # (6, 6400, 21)
    Me = model._Me.reshape(3, 6400).T                                # (6400, 3)

    def energies(w):
        # S[t, mode] = sum over elements of type t of w_e phi_e phi_e' (80 x 80), by matmul
        S = np.empty((nt, m, 80, 80))
        pw = phi if w is None else phi * w[None, :, None]
        for t in range(nt):
            sel = pat.elem_type == t
            ph, phw = (phi[:, sel], pw[:, sel]) if nt > 1 else (phi, pw)
            np.matmul(phw.transpose(0, 2, 1), ph, out=S[t])
        Sc = (pat.type_scales.T @ S.reshape(nt, -1)).reshape(6, m, 6400)  # per scale combo
        eKp = np.stack([Sc[p] @ Kr[p] for p in range(6)])               # (6, m, 21)
        return (eKp if per_combo else eKp.sum(axis=0)), Sc[0] @ Me     # ..., (m, 3)

    tw = model._tw
    if tw is None:
        return energies(None)
    # thickness field: coefficient k and inertia j go with s^power
    eK = np.zeros((6, m, 21) if per_combo else (m, 21))
    eM = np.zeros((m, 3))
    for p in (1, 2, 3):
        k, mm = energies(tw[p - 1])
        eK[..., COEF_POWER == p] = k[..., COEF_POWER == p]
        eM[:, p - 1] = mm[:, p - 1]
    return eK, eM


def _mass_slopes(model, modes, masses) -> tuple[np.ndarray, np.ndarray]:
    """(d lambda/dx_i, d lambda/dy_i), each (m, n_masses): point mass i moved on the plate.

    A point mass adds sum_k d_k N' N on field k (d = (m, m, m, Iy, Ix), ``with_point_masses``),
    so d lambda / dx = -lambda sum_k d_k 2 w_k w_k,x with w_k the mode's field k at the mass.
    The elements are C0: on an element edge the slope is that of the element ``Mesh.locate``
    gives (a difference across the edge averages the two sides)."""
    mesh = model.mesh
    pts = np.array([[float(r[0]), float(r[1])] for r in masses], float).reshape(-1, 2)
    e, xi, eta = mesh.locate(pts)
    N, Nxi, Neta = shape_2d(xi, eta)                                   # (n_masses, 16)
    h = mesh.element_sizes[e]                                          # (n_masses, 2)
    Nx, Ny = Nxi * (2.0 / h[:, :1]), Neta * (2.0 / h[:, 1:])
    lam = modes.omega2
    gx = np.zeros((lam.size, len(pts)))
    gy = np.zeros((lam.size, len(pts)))
    for i, row in enumerate(masses):
        row = tuple(float(v) for v in row)
        Ix, Iy = row[3:] if len(row) == 5 else (0.0, 0.0)
        for k, d in enumerate((row[2], row[2], row[2], Iy, Ix)):
            if not d:
                continue
            dofs = NODE_DOF * mesh.connectivity[e[i]] + k
            v = modes.shapes[dofs]                                     # (16, m)
            w, wx, wy = N[i] @ v, Nx[i] @ v, Ny[i] @ v
            gx[:, i] -= lam * d * 2.0 * w * wx
            gy[:, i] -= lam * d * 2.0 * w * wy
    return gx, gy


def geometry_sensitivities(model, modes, masses: Sequence[Sequence[float]] = (), params=None,
                           material: str | None = None) -> dict[str, np.ndarray]:
    """d lambda of each mode of ``modes`` (solved by ``model`` at ``params``, default the
    ones recorded in ``modes``), rad^2/s^2 per unit of:

    ``thickness``: the scale s of every ply (h = s h0; point masses and springs unchanged);
    ``length`` / ``width``: the scale of the plate in x / y (the mesh stretched; the point
    ``masses`` (x, y, m[, Ix, Iy]) stay where they are on the plate);
    ``density``: the scale of the plate's density (point masses unchanged);
    ``masses_x`` / ``masses_y``: every point mass moved together, per metre.
    Springs (``with_springs``) stay on their mesh points.
    """
    if params is None:
        params, material = modes.params, (modes.material if material is None else material)
    c, inert = model.coefficients(params, material)
    eKp, eM = coefficient_energies(model, modes, per_combo=True)
    lam = modes.omega2
    kin = eM @ inert                                      # phi' M_plate phi
    out = {"thickness": eKp.sum(axis=0) @ (c * COEF_POWER) - lam * (eM @ (inert * np.array([1.0, 2.0, 3.0]))),
           "density": -lam * kin}
    for name, power in (("length", X_POWER), ("width", Y_POWER)):
        out[name] = np.tensordot(power, eKp, axes=1) @ c - lam * power[0] * kin
    if len(masses):
        gx, gy = _mass_slopes(model, modes, masses)
        pos = np.array([[float(r[0]), float(r[1])] for r in masses])
        # stretching the mesh moves a fixed physical point by -x in the stretched frame
        out["length"] = out["length"] - gx @ pos[:, 0]
        out["width"] = out["width"] - gy @ pos[:, 1]
        out["masses_x"], out["masses_y"] = gx.sum(axis=1), gy.sum(axis=1)
    else:
        out["masses_x"] = out["masses_y"] = np.zeros(lam.size)
    return out
