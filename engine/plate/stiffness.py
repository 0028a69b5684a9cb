"""Material linearity of the plate: per-material maps to the 21 laminate coefficients.

Linearity: every element matrix is a fixed linear combination of 21 unit
element matrices (the independent entries of A, B, D, H) for K and of 3 (I1,
I2, I3) for M; for a rectangle of size (hx, hy) each unit matrix is itself a
combination of 6 reference matrices with factors that are monomials in hx, hy.
A, B, D, H are linear in each material's reduced stiffnesses (Q11, Q12, Q22,
Q66, G13, G23) and I1, I2, I3 in its density. Re-solving for new constants
therefore only forms a 21-vector, one 80x80 matrix per element size and one
sparse scatter of fixed pattern: no re-assembly.

Units SI: Pa, m, kg/m^3.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..laminate import ABDH, Laminate, Material, transform_inplane, transform_shear
from .element import SYM2, SYM3, FEError

__all__ = ["COEF_NAMES", "Q_NAMES", "q_vector", "q_derivatives", "coefficients_from_abdh", "material_maps"]

#: names of the 21 stiffness coefficients (independent entries of A, B, D, H)
COEF_NAMES = tuple(f"{m}{i + 1}{j + 1}" for m in "ABD" for i, j in SYM3) + tuple(
    f"H{i + 4}{j + 4}" for i, j in SYM2)
#: per-material stiffness components K is linear in
Q_NAMES = ("Q11", "Q12", "Q22", "Q66", "G13", "G23")


# ------------------------------------------------- material linearity --
def q_vector(mat: Material) -> np.ndarray:
    """(Q11, Q12, Q22, Q66, G13, G23) of paper Eq. 4, Pa."""
    nu21 = mat.nu12 * mat.E2 / mat.E1
    d = 1.0 - mat.nu12 * nu21
    return np.array([mat.E1 / d, mat.nu12 * mat.E2 / d, mat.E2 / d, mat.G12, mat.G13, mat.G23])


def q_derivatives(mat: Material, names: Sequence[str]) -> np.ndarray:
    """d(q, density)/dp, shape (7, len(names)); q as in ``q_vector``, chain rule through Eq. 4.

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
    return np.array([A[i, j] for i, j in SYM3] + [B[i, j] for i, j in SYM3]
                    + [D[i, j] for i, j in SYM3] + [H[i, j] for i, j in SYM2])


def coefficients_from_abdh(r: ABDH) -> tuple[np.ndarray, np.ndarray]:
    """(21 coefficients in COEF_NAMES order, (I1, I2, I3)) of laminate resultants."""
    return _coef_vector(r.A, r.B, r.D, r.H), np.array([r.I1, r.I2, r.I3])


def material_maps(lam: Laminate, shear_factor: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
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
