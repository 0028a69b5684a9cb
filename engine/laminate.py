"""Ply constants -> stiffness matrices, rotations, laminate A, B, D, H.

Units: Pa, m, kg/m^3, degrees for angles.

Conventions
-----------
* 3D Voigt order is (11, 22, 33, 23, 13, 12); engineering shear strains.
* A ply at ``angle_deg`` = theta has its fibre direction 1 rotated by +theta
  from the laminate x axis towards y (Reddy, Jones). The paper (Eq. 6) writes
  the coupling terms Q16, Q26 with the opposite sign, i.e. theta -> -theta;
  the other terms are identical.
* Plane-stress in-plane order is (x, y, xy); transverse shear order is
  (xz, yz), as in paper Eq. 11 (gamma = [gamma_xz, gamma_yz]).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

__all__ = [
    "Material", "Ply", "Laminate", "ABDH",
    "stiffness_3d", "rotate_z", "reduced_stiffness", "transform_inplane",
    "transform_shear", "abdh", "PhysicsError",
]

ORTHOTROPIC_PARAMS = ("E1", "E2", "nu12", "G12", "G13", "G23", "density")
ISOTROPIC_PARAMS = ("E", "G", "nu", "density")


class PhysicsError(ValueError):
    """Unphysical input (non positive-definite stiffness, negative thickness...)."""


@dataclass(frozen=True)
class Material:
    """Orthotropic (or isotropic) ply material.

    Moduli in Pa, density in kg/m^3. ``E3``, ``nu13`` and ``nu23`` may be left
    ``None``: they then follow transverse isotropy (E3 = E2, nu13 = nu12,
    nu23 = E2/(2 G23) - 1) and track E2, nu12, G23 when those are updated.
    """

    E1: float
    E2: float
    nu12: float
    G12: float
    G13: float
    G23: float
    density: float
    E3: float | None = None
    nu13: float | None = None
    nu23: float | None = None
    isotropic: bool = False
    name: str = ""

    # -- constructors -------------------------------------------------
    @classmethod
    def isotropic_from(cls, E: float, density: float, *, nu: float | None = None,
                       G: float | None = None, name: str = "") -> "Material":
        """Isotropic material from E and either nu or G."""
        if (nu is None) == (G is None):
            raise PhysicsError("isotropic material needs exactly one of nu or G")
        if G is None:
            G = E / (2.0 * (1.0 + nu))
        nu_ = E / (2.0 * G) - 1.0
        return cls(E1=E, E2=E, nu12=nu_, G12=G, G13=G, G23=G, density=density,
                   E3=E, nu13=nu_, nu23=nu_, isotropic=True, name=name)

    # -- derived constants ---------------------------------------------
    @property
    def e3(self) -> float:
        return self.E2 if self.E3 is None else self.E3

    @property
    def v13(self) -> float:
        return self.nu12 if self.nu13 is None else self.nu13

    @property
    def v23(self) -> float:
        return self.E2 / (2.0 * self.G23) - 1.0 if self.nu23 is None else self.nu23

    @property
    def param_names(self) -> tuple[str, ...]:
        return ISOTROPIC_PARAMS if self.isotropic else ORTHOTROPIC_PARAMS

    def params(self) -> dict[str, float]:
        """The identifiable constants by their contract names."""
        if self.isotropic:
            return {"E": self.E1, "G": self.G12, "nu": self.nu12, "density": self.density}
        return {k: float(getattr(self, k)) for k in ORTHOTROPIC_PARAMS}

    def with_params(self, **p: float) -> "Material":
        """A copy with some constants replaced (contract parameter names)."""
        if self.isotropic:
            unknown = set(p) - set(ISOTROPIC_PARAMS)
            if unknown:
                raise KeyError(f"unknown isotropic parameter(s) {sorted(unknown)}; expected {ISOTROPIC_PARAMS}")
            E = p.get("E", self.E1)
            rho = p.get("density", self.density)
            if "G" in p and "nu" in p:
                raise PhysicsError("isotropic material: give G or nu, not both")
            if "nu" in p:
                return Material.isotropic_from(E, rho, nu=p["nu"], name=self.name)
            return Material.isotropic_from(E, rho, G=p.get("G", self.G12), name=self.name)
        unknown = set(p) - set(ORTHOTROPIC_PARAMS) - {"E3", "nu13", "nu23"}
        if unknown:
            raise KeyError(f"unknown orthotropic parameter(s) {sorted(unknown)}; expected {ORTHOTROPIC_PARAMS}")
        return replace(self, **{k: float(v) for k, v in p.items()})

    def compliance(self) -> np.ndarray:
        """3D compliance matrix S (6x6, Voigt 11,22,33,23,13,12), 1/Pa."""
        E1, E2, E3 = self.E1, self.E2, self.e3
        S = np.zeros((6, 6))
        S[0, 0], S[1, 1], S[2, 2] = 1.0 / E1, 1.0 / E2, 1.0 / E3
        S[0, 1] = S[1, 0] = -self.nu12 / E1
        S[0, 2] = S[2, 0] = -self.v13 / E1
        S[1, 2] = S[2, 1] = -self.v23 / E2
        S[3, 3], S[4, 4], S[5, 5] = 1.0 / self.G23, 1.0 / self.G13, 1.0 / self.G12
        return S

    def check(self) -> None:
        """Raise PhysicsError naming the first unphysical constant."""
        for key in ("E1", "E2", "G12", "G13", "G23", "density"):
            v = getattr(self, key)
            if not np.isfinite(v) or v <= 0:
                raise PhysicsError(f"{key} = {v!r}: expected a positive finite value")
        if self.E3 is not None and not self.E3 > 0:
            raise PhysicsError(f"E3 = {self.E3!r}: expected a positive value")
        eig = np.linalg.eigvalsh(self.compliance())
        if not np.all(eig > 0):
            raise PhysicsError(
                "elastic constants give a 3D stiffness that is not positive definite "
                f"(nu12={self.nu12:g}, nu13={self.v13:g}, nu23={self.v23:g}); "
                "expected Poisson ratios within the stability bounds")


def stiffness_3d(mat: Material) -> np.ndarray:
    """3D stiffness C (6x6 Voigt, Pa) in the material axes."""
    return np.linalg.inv(mat.compliance())


def _voigt_to_tensor(C: np.ndarray) -> np.ndarray:
    idx = {(0, 0): 0, (1, 1): 1, (2, 2): 2, (1, 2): 3, (2, 1): 3, (0, 2): 4,
           (2, 0): 4, (0, 1): 5, (1, 0): 5}
    T = np.empty((3, 3, 3, 3))
    for (i, j), a in idx.items():
        for (k, l), b in idx.items():
            T[i, j, k, l] = C[a, b]
    return T


_VOIGT_PAIRS = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))


def rotate_z(C: np.ndarray, angle_deg: float) -> np.ndarray:
    """Stiffness (6x6 Voigt) of a material whose axes are turned by +angle about z.

    Returns the stiffness expressed in the fixed (x, y, z) axes.
    """
    t = np.deg2rad(angle_deg)
    c, s = np.cos(t), np.sin(t)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.einsum("ia,jb,kc,ld,abcd->ijkl", R, R, R, R, _voigt_to_tensor(C), optimize=True)
    out = np.empty((6, 6))
    for a, (i, j) in enumerate(_VOIGT_PAIRS):
        for b, (k, l) in enumerate(_VOIGT_PAIRS):
            out[a, b] = T[i, j, k, l]
    return out


def reduced_stiffness(mat: Material) -> tuple[np.ndarray, np.ndarray]:
    """Plane-stress reduced stiffness (paper Eq. 4).

    Returns ``(Q, Qs)``: Q is 3x3 in material (1, 2, 12) order, Pa;
    Qs = diag(G13, G23) is the transverse shear stiffness in (13, 23) order.
    """
    nu21 = mat.nu12 * mat.E2 / mat.E1
    d = 1.0 - mat.nu12 * nu21
    Q = np.array([
        [mat.E1 / d, mat.nu12 * mat.E2 / d, 0.0],
        [mat.nu12 * mat.E2 / d, mat.E2 / d, 0.0],
        [0.0, 0.0, mat.G12],
    ])
    return Q, np.diag([mat.G13, mat.G23])


def transform_inplane(Q: np.ndarray, angle_deg: float) -> np.ndarray:
    """Transformed reduced stiffness Qbar (paper Eq. 6a), (x, y, xy) order.

    Linear in Q. Sign convention of the 16/26 terms: see the module docstring.
    """
    t = np.deg2rad(angle_deg)
    m, n = np.cos(t), np.sin(t)
    Q11, Q12, Q22, Q66 = Q[0, 0], Q[0, 1], Q[1, 1], Q[2, 2]
    m2, n2 = m * m, n * n
    Qb = np.empty((3, 3))
    Qb[0, 0] = Q11 * m2 * m2 + 2 * (Q12 + 2 * Q66) * n2 * m2 + Q22 * n2 * n2
    Qb[0, 1] = (Q11 + Q22 - 4 * Q66) * n2 * m2 + Q12 * (n2 * n2 + m2 * m2)
    Qb[1, 1] = Q11 * n2 * n2 + 2 * (Q12 + 2 * Q66) * n2 * m2 + Q22 * m2 * m2
    Qb[0, 2] = (Q11 - Q12 - 2 * Q66) * n * m2 * m + (Q12 - Q22 + 2 * Q66) * n2 * n * m
    Qb[1, 2] = (Q11 - Q12 - 2 * Q66) * n2 * n * m + (Q12 - Q22 + 2 * Q66) * n * m2 * m
    Qb[2, 2] = (Q11 + Q22 - 2 * Q12 - 2 * Q66) * n2 * m2 + Q66 * (n2 * n2 + m2 * m2)
    Qb[1, 0], Qb[2, 0], Qb[2, 1] = Qb[0, 1], Qb[0, 2], Qb[1, 2]
    return Qb


def transform_shear(Qs: np.ndarray, angle_deg: float) -> np.ndarray:
    """Transverse shear stiffness in (xz, yz) order (paper Eq. 6b). Linear in Qs.

    ``Qs`` is diag(G13, G23) in material (13, 23) order.
    """
    t = np.deg2rad(angle_deg)
    m, n = np.cos(t), np.sin(t)
    # gamma_13 = m gamma_xz + n gamma_yz ; gamma_23 = -n gamma_xz + m gamma_yz
    T = np.array([[m, n], [-n, m]])
    return T.T @ Qs @ T


@dataclass(frozen=True)
class Ply:
    """One ply: material, fibre angle (deg, from x towards y), thickness (m)."""

    material: Material
    angle_deg: float
    thickness: float


@dataclass(frozen=True)
class ABDH:
    """Laminate stiffness resultants (paper Eq. 12).

    A (N/m), B (N), D (N m) are 3x3 in (x, y, xy) order; H (N/m) is 2x2 in
    (xz, yz) order and includes the shear factor. I1 (kg/m^2), I2 (kg/m),
    I3 (kg) are the inertias of Eq. 9.
    """

    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    H: np.ndarray
    I1: float
    I2: float
    I3: float


@dataclass(frozen=True)
class Laminate:
    """Plies listed bottom first; z is measured from the mid-plane."""

    plies: tuple[Ply, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "plies", tuple(self.plies))
        if not self.plies:
            raise PhysicsError("laminate has no plies")
        for i, p in enumerate(self.plies):
            if not (np.isfinite(p.thickness) and p.thickness > 0):
                raise PhysicsError(f"ply {i} thickness = {p.thickness!r}: expected a positive value in m")

    @property
    def thickness(self) -> float:
        return float(sum(p.thickness for p in self.plies))

    @property
    def z_interfaces(self) -> np.ndarray:
        """Ply interface coordinates from -h/2 to h/2 (m), length n_plies + 1."""
        z = np.concatenate([[0.0], np.cumsum([p.thickness for p in self.plies])])
        return z - z[-1] / 2.0

    @property
    def materials(self) -> dict[str, Material]:
        """Distinct materials by name (first occurrence wins)."""
        out: dict[str, Material] = {}
        for p in self.plies:
            out.setdefault(p.material.name, p.material)
        return out

    @property
    def mean_density(self) -> float:
        return float(sum(p.material.density * p.thickness for p in self.plies) / self.thickness)

    def with_params(self, params: Mapping[str, float], material: str | None = None) -> "Laminate":
        """Replace constants of one material (the only one if ``material`` is None)."""
        mats = self.materials
        if material is None:
            if len(mats) != 1:
                raise KeyError(f"laminate has materials {sorted(mats)}; name the one to update")
            material = next(iter(mats))
        new = mats[material].with_params(**params)
        return Laminate(tuple(replace(p, material=new) if p.material.name == material else p
                              for p in self.plies))

    def scaled_thickness(self, factor: float) -> "Laminate":
        return Laminate(tuple(replace(p, thickness=p.thickness * factor) for p in self.plies))


def abdh(lam: Laminate, shear_factor: float = 5.0 / 6.0) -> ABDH:
    """A, B, D, H and inertias I1, I2, I3 of a laminate (paper Eqs. 9, 12)."""
    z = lam.z_interfaces
    A = np.zeros((3, 3)); B = np.zeros((3, 3)); D = np.zeros((3, 3)); H = np.zeros((2, 2))
    I1 = I2 = I3 = 0.0
    for k, ply in enumerate(lam.plies):
        z0, z1 = z[k], z[k + 1]
        Q, Qs = reduced_stiffness(ply.material)
        Qb = transform_inplane(Q, ply.angle_deg)
        Qsb = transform_shear(Qs, ply.angle_deg)
        d1, d2, d3 = z1 - z0, (z1**2 - z0**2) / 2.0, (z1**3 - z0**3) / 3.0
        A += Qb * d1; B += Qb * d2; D += Qb * d3; H += Qsb * d1
        rho = ply.material.density
        I1 += rho * d1; I2 += rho * d2; I3 += rho * d3
    return ABDH(A, B, D, shear_factor * H, I1, I2, I3)
