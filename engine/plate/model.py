"""PlateModel: a free-free laminated Mindlin plate, precomputed once, solved per parameter set.

Eigen solver: shift-invert with the shift at -0.1 of the plate's frequency scale and a
SuperLU factorisation of K - sigma M: a certified warm block solve from the model's last
modes when the constants moved little (engine.plate.warm), else ARPACK eigsh (Lanczos).
When B = 0 and I2 = 0 (symmetric
layups) the bending (w0, bx, by) and membrane (u0, v0) blocks are solved
apart. The six rigid-body modes are recognised by their mass-weighted
projection on the analytic rigid-body vectors and excluded; exactly six must
be found.

Units SI: m, kg, s, Pa; eigenvalues lambda = omega^2 in rad^2/s^2.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Iterable, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from scipy.linalg import eigh as sl_eigh

from ..laminate import Laminate, Material
from .element import NODE_DOF, FEError, reference_by_coefficient, reference_matrices, shape_2d
from .field import COEF_POWER, field_data, thickness_weights
from .mesh import Mesh
from .sensitivity import coefficient_energies
from .sparse import Added, Block, Pattern, point_entries
from .warm import COUNTS
from .stiffness import material_maps, q_derivatives, q_vector

__all__ = ["Modes", "PlateModel", "natural_frequencies"]

_SPARE = 4


# --------------------------------------------------------------- modes --
@dataclass(frozen=True)
class Modes:
    """Elastic modes, ascending.

    ``shapes`` (n_dof, n) are mass-normalised (phi' M phi = 1, units 1/sqrt(kg));
    ``omega2`` in rad^2/s^2; ``rigid_max_omega`` (rad/s) is the largest |omega|
    among the six rigid-body modes that were detected and excluded (with
    springs: the suspension modes).
    """

    frequencies_hz: np.ndarray
    omega2: np.ndarray
    shapes: np.ndarray
    rigid_max_omega: float
    params: Mapping[str, float] = field(default_factory=dict)
    material: str | None = None



@lru_cache(maxsize=3)
def mesh_parts(mesh: Mesh) -> tuple[Pattern, dict]:
    """(sparse pattern, mesh-only cache: rigid modes, DOF blocks) of ``mesh``, shared by every
    model built on an equal mesh (read-only once built). A 3-constant ``labid diagnose`` built
    the same two meshes five times (its estimate, the correction at the estimate, the gap's
    model): 0.3 s CPU and ~40-80 MiB of transient arrays each time on the fine mesh
    (bench/RESULTS.md, issue 29 session 24). The last three meshes are kept (the demo plate's
    default and finer mesh, and one more)."""
    return Pattern.build(mesh), {}


class PlateModel:
    """Free-free laminated Mindlin plate: precomputed parts, solve per parameter set."""

    def __init__(self, laminate: Laminate, mesh: Mesh, shear_factor: float = 5.0 / 6.0,
                 *, _parts=None, k_add=None, m_add=None, _cache=None, thickness_weights=None):
        self.laminate, self.mesh, self.shear_factor = laminate, mesh, shear_factor
        if _parts is None:
            Kref, Mref = reference_matrices()
            pat, mesh_cache = mesh_parts(mesh)
            _parts = (Kref, Mref, pat, material_maps(laminate, shear_factor))
            _cache = mesh_cache if _cache is None else _cache
        self._Ke, self._Me, self._pat, self._maps = _parts
        self._Kflat = reference_by_coefficient()   # (21, 6 x 6400): shared, read-only
        self._k_add = Added.none() if k_add is None else k_add
        self._m_add = Added.none() if m_add is None else m_add
        cross = self._pat.cross
        self._add_cross = self._k_add.any_at(cross) or self._m_add.any_at(cross)
        self._cache: dict = {} if _cache is None else _cache  # mesh-only data, shared by derived models
        self._mass_memo: dict | None = None  # mass data of the last inertias (see _mass)
        self._mem_memo: dict | None = None   # last membrane solve (see _membrane_modes)
        self._warm: dict = {}                # block name -> WarmStart of the last solve (see _eig)
        # no added stiffness on the membrane DOFs (the membrane eigenvalue bound needs it)
        fr = np.repeat(np.arange(len(self._pat.indptr) - 1), np.diff(self._pat.indptr)) % NODE_DOF
        self._membrane_k_free = not self._k_add.any_at((fr < 2) & (self._pat.indices % NODE_DOF < 2))
        # thickness field: (3, n_elements) element means of s, s^2, s^3 (None: uniform s = 1)
        self._tw = None if thickness_weights is None else np.asarray(thickness_weights, float)

    # -- construction ---------------------------------------------------
    @classmethod
    def build(cls, laminate: Laminate, length: float, width: float, mesh=None,
              shear_factor: float = 5.0 / 6.0) -> "PlateModel":
        """Precompute the parts.

        ``mesh``: None (``Mesh.default``, graded at the edges), (nx, ny) for a
        uniform nx x ny mesh, or a Mesh.
        """
        if mesh is None:
            m = Mesh.default(length, width, laminate.thickness)
        elif isinstance(mesh, Mesh):
            m = mesh
        else:
            try:
                nx, ny = mesh
            except (TypeError, ValueError):
                raise FEError(f"mesh = {mesh!r}: expected (nx, ny) elements") from None
            m = Mesh(nx, ny, float(length), float(width))
        for mat in laminate.materials.values():
            mat.check()
        return cls(laminate, m, shear_factor)

    @property
    def k_add(self) -> np.ndarray:
        """Added stiffness (springs, stiffness loss) on the sparse pattern's entries (read-only)."""
        v = self._k_add.dense(self._pat.indices.size)
        v.flags.writeable = False
        return v

    @property
    def m_add(self) -> np.ndarray:
        """Added mass (point masses) on the sparse pattern's entries (read-only)."""
        v = self._m_add.dense(self._pat.indices.size)
        v.flags.writeable = False
        return v

    def with_laminate(self, laminate: Laminate) -> "PlateModel":
        """The same mesh, shear factor and added stiffness and mass with another laminate
        (e.g. scaled thickness); mesh-only data are shared."""
        Kref, Mref = self._Ke, self._Me
        return PlateModel(laminate, self.mesh, self.shear_factor,
                          _parts=(Kref, Mref, self._pat, material_maps(laminate, self.shear_factor)),
                          k_add=self._k_add, m_add=self._m_add, _cache=self._cache,
                          thickness_weights=self._tw)

    def _derived(self, k_add=None, m_add=None, thickness_weights=False) -> "PlateModel":
        return PlateModel(self.laminate, self.mesh, self.shear_factor,
                          _parts=(self._Ke, self._Me, self._pat, self._maps),
                          k_add=self._k_add if k_add is None else k_add,
                          m_add=self._m_add if m_add is None else m_add, _cache=self._cache,
                          thickness_weights=self._tw if thickness_weights is False else thickness_weights)

    # -- thickness field ----------------------------------------------------
    @property
    def thickness_scale(self) -> np.ndarray | None:
        """Per-element mean thickness factor (n_elements,), element = ey * nx + ex; None: uniform 1."""
        return None if self._tw is None else self._tw[0].copy()

    def with_thickness_field(self, scale) -> "PlateModel":
        """The same plate with a thickness field: at (x, y) every ply of the laminate is
        scaled by s(x, y) > 0 (the mid-plane stays at z = 0), so A and H scale by s, B by
        s^2, D by s^3 and the inertias I1, I2, I3 by s, s^2, s^3.

        ``scale``: one factor per element (n_elements,), element = ey * nx + ex, or a
        callable s(x, y) of arrays (m); each element then takes the means of s, s^2
        and s^3 over its area (4 x 4 Gauss points: exact for a linear s). Replaces any
        field of this model; added stiffness and mass (springs, point masses, stiffness
        loss) are kept as they are. ``None``: no field. (Weights and scatter: :mod:`.field`.)
        """
        if scale is None:
            return self._derived(thickness_weights=None)
        return self._derived(thickness_weights=thickness_weights(self.mesh, scale))

    def with_added_mass(self, data: np.ndarray) -> "PlateModel":
        """The same model plus mass ``data`` given on the sparse pattern's entries (the
        ``m_add`` layout, kg and kg m^2: e.g. a distributed mass built once and scaled)."""
        data = np.asarray(data, float)
        nz = np.flatnonzero(data)
        return PlateModel(self.laminate, self.mesh, self.shear_factor,
                          _parts=(self._Ke, self._Me, self._pat, self._maps), k_add=self._k_add,
                          m_add=self._m_add.plus(nz, data[nz]), _cache=self._cache, thickness_weights=self._tw)

    def with_point_masses(self, masses: Iterable[Sequence[float]]) -> "PlateModel":
        """Add point masses (x, y, m) or (x, y, m, Ix, Iy): m in kg on u0, v0, w0;
        rotary inertias in kg m^2, Ix about the x axis (acts on by), Iy about y (on bx)."""
        add = self._m_add
        for row in masses:
            row = tuple(float(v) for v in row)
            if len(row) not in (3, 5):
                raise FEError(f"point mass {row!r}: expected (x, y, m_kg) or (x, y, m_kg, Ix, Iy)")
            x, y, m = row[:3]
            Ix, Iy = row[3:] if len(row) == 5 else (0.0, 0.0)
            if not (m >= 0 and Ix >= 0 and Iy >= 0):
                raise FEError(f"point mass {row!r}: expected non-negative mass and inertias")
            add = add.plus(*point_entries(self.mesh, self._pat, x, y, (m, m, m, Iy, Ix)))
        return self._derived(m_add=add)

    def with_springs(self, springs: Iterable[Sequence[float]]) -> "PlateModel":
        """Add grounded transverse springs (x, y, kz) on w0, kz in N/m."""
        add = self._k_add
        for row in springs:
            row = tuple(float(v) for v in row)
            if len(row) != 3 or not row[2] >= 0:
                raise FEError(f"spring {row!r}: expected (x, y, kz_N_per_m) with kz >= 0")
            add = add.plus(*point_entries(self.mesh, self._pat, row[0], row[1], (0, 0, row[2], 0, 0)))
        return self._derived(k_add=add)

    def with_stiffness_loss(self, x0: float, y0: float, size: float, loss: float,
                            params: Mapping[str, float] | None = None,
                            material: str | None = None) -> "PlateModel":
        """A local stiffness loss (damage, a soft patch): inside the square of side ``size``
        (m) centred at (x0, y0), the stiffness drops by the fraction ``loss`` (each element
        by ``loss`` times its area fraction inside the square). The loss is that of the
        stiffness at ``params`` and stays fixed when the model is solved with others."""
        if not 0.0 <= loss <= 1.0 or not size > 0:
            raise FEError(f"stiffness loss {loss!r} over {size!r} m: expected 0 <= loss <= 1 and size > 0")
        c, _ = self.coefficients(params, material)
        pat = self._pat
        tw = np.ones((3, self.mesh.n_elements)) if self._tw is None else self._tw
        # (power of the thickness scale, n_types, element matrix); p = 1, 2, 3
        Ke_type = np.stack([pat.type_scales @ np.tensordot(c * (COEF_POWER == p), self._Ke, axes=(0, 1)
                                                           ).reshape(self._Ke.shape[0], -1) for p in (1, 2, 3)])
        xe, ye = self.mesh.xe, self.mesh.ye
        ox = np.clip(np.minimum(xe[1:], x0 + size / 2) - np.maximum(xe[:-1], x0 - size / 2), 0, None) / np.diff(xe)
        oy = np.clip(np.minimum(ye[1:], y0 + size / 2) - np.maximum(ye[:-1], y0 - size / 2), 0, None) / np.diff(ye)
        pos, vals = [], []
        for ey in np.flatnonzero(oy):
            for ex in np.flatnonzero(ox):
                e = ey * self.mesh.nx + ex
                Ke = tw[:, e] @ Ke_type[:, pat.elem_type[e]]
                pos.append(pat.elem_pos[e])
                vals.append(-loss * ox[ex] * oy[ey] * Ke)
        if not pos:
            return self._derived()
        return self._derived(k_add=self._k_add.plus(np.concatenate(pos), np.concatenate(vals)))

    # -- parameters -----------------------------------------------------
    def _material_name(self, material: str | None) -> str:
        if material is None:
            if len(self._maps) != 1:
                raise KeyError(f"laminate has materials {sorted(self._maps)}; name the one to update")
            return next(iter(self._maps))
        if material not in self._maps:
            raise KeyError(f"material {material!r} not in laminate; expected one of {sorted(self._maps)}")
        return material

    def _materials(self, params, material) -> dict[str, Material]:
        mats = dict(self.laminate.materials)
        if params:
            name = self._material_name(material)
            mats[name] = mats[name].with_params(**params)
            mats[name].check()
        return mats

    def coefficients(self, params: Mapping[str, float] | None = None,
                     material: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(21 stiffness coefficients per COEF_NAMES, (I1, I2, I3)) for a parameter set
        (of the laminate; a thickness field scales them per element, see with_thickness_field)."""
        c = np.zeros(21)
        inert = np.zeros(3)
        for name, mat in self._materials(params, material).items():
            L, R = self._maps[name]
            c += L @ q_vector(mat)
            inert += R * mat.density
        return c, inert

    def matrices(self, params=None, material=None) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """Global K (N/m) and M (kg), CSR (M on its own, sparser pattern)."""
        c, inert = self.coefficients(params, material)
        return self._pat.matrix(self._data(c, inert)), self._mass(inert)["M"].copy()

    def _data(self, c: np.ndarray, inert: np.ndarray) -> np.ndarray:
        """K data on the common pattern (M: :meth:`_mass`)."""
        pat = self._pat
        if self._tw is not None:   # thickness field: one element matrix per type and power of s
            Kc = np.stack([((c * (COEF_POWER == p)) @ self._Kflat).reshape(6, 6400) for p in (1, 2, 3)])
            return self._k_add.add_to(field_data(pat, self._tw, pat.type_scales @ Kc))
        Kc = (c @ self._Kflat).reshape(6, 6400)   # unit element matrix per scale combo
        return self._k_add.add_to(pat.scatter @ (pat.type_scales @ Kc).ravel())

    def _mass(self, inert: np.ndarray) -> dict:
        """Mass-side data for inertias (I1, I2, I3), memoised for the last inertias
        (M depends on the density only, fixed during most identifications):
        ``M`` (global CSR) and, filled on demand, ``MR`` (M times the rigid-body vectors),
        ``G`` (R' M R), per-block ``(mb, Mb)`` and, until the first solve has built the
        block masses, ``md`` (the data on the common pattern: 2.9 MB on the demo's mesh,
        not kept by every cached model of a diagnosis)."""
        key = np.asarray(inert, dtype=float).tobytes()
        memo = self._mass_memo
        if memo is None or memo["key"] != key:
            md = self._mass_data(inert)
            memo = self._mass_memo = {"key": key, "md": md, "M": self._pat.mass_matrix(md)}
        return memo

    def _mass_data(self, inert: np.ndarray) -> np.ndarray:
        """M data on the common pattern (read-only)."""
        pat = self._pat
        inert = np.asarray(inert, dtype=float)
        if self._tw is not None:   # I1, I2, I3 go with s, s^2, s^3
            Mc = (inert[:, None] * self._Me.reshape(3, -1))                       # (3, 6400)
            md = self._m_add.add_to(field_data(pat, self._tw, pat.type_scales[None, :, 0, None] * Mc[:, None, :]))
        else:
            Mc = np.tensordot(inert, self._Me, 1).ravel()
            md = self._m_add.add_to(pat.scatter @ np.outer(pat.type_scales[:, 0], Mc).ravel())
        md.flags.writeable = False
        return md

    def _block_mass(self, name: str, inert: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        memo = self._mass(inert)
        if name not in memo:
            if "md" not in memo:        # released after the first solve (see solve_coefficients)
                memo["md"] = self._mass_data(inert)
            memo[name] = self._block(name).mass(memo["md"])
        return memo[name]

    # -- rigid body modes --------------------------------------------------
    def rigid_body_vectors(self) -> np.ndarray:
        """(n_dof, 6) translations x, y, z; rotation about z; rotations about x and y."""
        if "R" in self._cache:
            return self._cache["R"]
        xy = self.mesh.coords
        n = xy.shape[0]
        R = np.zeros((n, NODE_DOF, 6))
        R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
        R[:, 0, 3], R[:, 1, 3] = -xy[:, 1], xy[:, 0]
        R[:, 2, 4], R[:, 4, 4] = xy[:, 1], -1.0
        R[:, 2, 5], R[:, 3, 5] = xy[:, 0], -1.0
        self._cache["R"] = R.reshape(n * NODE_DOF, 6)
        return self._cache["R"]

    # -- solve --------------------------------------------------------------
    def solve(self, n_modes: int = 10, params: Mapping[str, float] | None = None,
              material: str | None = None, sigma: float | None = None) -> Modes:
        """The n_modes lowest elastic modes (rigid-body modes detected and excluded).

        ``params``: constants of ``material`` (contract names) replacing the
        laminate's; K and M are recombined from the precomputed parts.
        """
        c, inert = self.coefficients(params, material)
        modes = self.solve_coefficients(c, inert, n_modes, sigma)
        return Modes(modes.frequencies_hz, modes.omega2, modes.shapes, modes.rigid_max_omega,
                     dict(params or {}), material)

    def solve_coefficients(self, c: np.ndarray, inertias: Sequence[float], n_modes: int = 10,
                           sigma: float | None = None) -> Modes:
        """Modes for explicit laminate coefficients (COEF_NAMES order, see
        ``coefficients_from_abdh``) and inertias (I1, I2, I3)."""
        if isinstance(n_modes, bool) or int(n_modes) != n_modes or n_modes < 1:
            raise FEError(f"n_modes = {n_modes!r}: expected a positive integer")
        n_modes = int(n_modes)
        c, inert = np.asarray(c, dtype=float), np.asarray(inertias, dtype=float)
        kd = self._data(c, inert)
        n = self.mesh.n_dof
        if n_modes + 6 + _SPARE >= 0.4 * n - 1:
            raise FEError(f"n_modes = {n_modes}: too many for a mesh of {n} DOF")
        if sigma is None:
            sigma = -0.1 * self._omega2_scale(c, inert)
        h = self.laminate.thickness
        coupled = (self._add_cross or np.abs(c[6:12]).max() > 1e-10 * np.abs(c[:6]).max() * h
                   or abs(inert[1]) > 1e-10 * inert[0] * h)
        if coupled:
            lam, vec = self._eig("all", kd, n_modes + 6 + _SPARE, sigma, inert, c, n_modes + 6)
        else:
            # B = 0, I2 = 0: bending (w0, bx, by) and membrane (u0, v0) decouple;
            # 3 rigid modes each. Membrane modes are usually far above.
            # ncv = k + 13: ~11 % faster than 2k + 1 for 10 CFRP modes (bench/RESULTS.md,
            # Identification), eigenvalues equal to 1e-12
            kb = n_modes + 3 + _SPARE
            lam, vec = self._eig("bending", kd, kb, sigma, inert, c, n_modes + 3, ncv=max(kb + 13, 20))
            top = np.sort(lam)[min(3 + n_modes, lam.size) - 1]
            lam_m, vec_m = self._membrane_modes(kd, c, inert, top, sigma, n)
            lam, vec = np.concatenate([lam, lam_m]), np.hstack([vec, vec_m])
        k = lam.size
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
        rigid = self._rigid_mask(vec, self._mass(inert))
        if rigid.sum() != 6:
            raise FEError(f"found {int(rigid.sum())} rigid-body modes among the {k} lowest, "
                          "expected exactly 6")
        elastic = ~rigid
        if np.any(lam[elastic] < 1e-6 * self._omega2_scale(c, inert)):
            raise FEError("spurious zero-energy mode: elastic mode with omega^2 ~ 0")
        lam_e, vec_e = lam[elastic][:n_modes], vec[:, elastic][:, :n_modes]
        if lam_e.size < n_modes:
            raise FEError("eigen solver returned too few elastic modes")
        rigid_max = float(np.sqrt(np.max(np.abs(lam[rigid]))))
        self._mass(inert).pop("md", None)     # the block masses are built: M's data not kept
        return Modes(np.sqrt(np.maximum(lam_e, 0.0)) / (2.0 * np.pi), lam_e, vec_e, rigid_max)

    def _membrane_modes(self, kd: np.ndarray, c: np.ndarray, inert: np.ndarray, top: float,
                        sigma: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Membrane (u0, v0) modes of a decoupled plate: all below ``top`` (omega^2,
        the highest bending mode wanted) and at least its 3 rigid-body modes.

        The membrane stiffness is linear and positive in the A matrix only, so
        if A_new - alpha A_old is positive semi-definite every membrane
        eigenvalue (same M) is at least alpha times the old one (Courant-Fischer).
        When that bound puts the first elastic membrane mode of the last
        membrane solve above 1.02 top, that solve's rigid-body pairs (exact
        null vectors of every K_m, M-normalised for this M) are returned
        instead of a new solve: none of its elastic modes could be selected.
        """
        blk = self._block("membrane")
        mass = self._block_mass("membrane", inert)
        A_new = c[[0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(3, 3)
        memo = self._mem_memo
        if memo is not None and memo["mass"] is mass:
            try:
                alpha = float(sl_eigh(A_new, memo["A"], eigvals_only=True)[0])
            except np.linalg.LinAlgError:
                alpha = 0.0
            if alpha * memo["lam_elastic"] > 1.02 * top:
                return memo["lam_rigid"], memo["vec_rigid"]
        km, nm = 6, blk.dofs.size
        while True:
            lam_m, vec_m = blk.eig(kd, None, km, sigma, n, mass)
            if lam_m.max() > top or km >= 0.4 * nm:
                break
            km *= 2
        order = np.argsort(lam_m)
        if self._membrane_k_free and order.size > 3:
            self._mem_memo = {"mass": mass, "A": A_new, "lam_elastic": float(lam_m[order[3]]),
                              "lam_rigid": lam_m[order[:3]], "vec_rigid": vec_m[:, order[:3]]}
        return lam_m, vec_m

    def _eig(self, name, kd, k, sigma, inert, c, n_want, ncv=None):
        """The block's eigenpairs: the last ones again for the same inputs (arrays shared:
        callers index, never write); warm from the last solve when certified (engine.plate.warm;
        not with added stiffness), else ARPACK's k. ``LABID_PLATE_WARM=0``: no warm start."""
        key = (name, c.tobytes(), inert.tobytes(), sigma, k)
        if self._warm.get("last", (None,))[0] == key:    # the same solve again (another caller)
            COUNTS["again"] += 1
            return self._warm["last"][1:]
        start = self._warm.get(name) if os.environ.get("LABID_PLATE_WARM", "1") != "0" else None
        lam, vec, nxt, _ = self._block(name).eig_warm(kd, k, sigma, self.mesh.n_dof, self._block_mass(
            name, inert), ncv, start, c, name == "all", n_want)
        self._warm[name] = None if self._k_add.idx.size else nxt
        self._warm["last"] = (key, lam, vec)
        return lam, vec

    def _block(self, name: str) -> Block:
        key = "block_" + name
        if key not in self._cache:
            fields = {"all": range(NODE_DOF), "bending": (2, 3, 4), "membrane": (0, 1)}[name]
            self._cache[key] = Block.build(self._pat, tuple(fields))
        return self._cache[key]

    def _omega2_scale(self, c: np.ndarray, inert: np.ndarray) -> float:
        """Rough first elastic omega^2 (thin-plate estimate), rad^2/s^2."""
        Dmax = max(c[12], c[15], c[17])
        a = max(self.mesh.length, self.mesh.width)
        return 100.0 * Dmax / (inert[0] * a**4)

    def _rigid_mask(self, vec: np.ndarray, mass: dict) -> np.ndarray:
        """True for modes whose M-norm lies mostly (> 1/2) in the rigid-body space.

        ``mass``: ``self._mass(inertias)``; M R and R' M R are memoised there."""
        if "MR" not in mass:
            R = self.rigid_body_vectors()
            mass["MR"] = np.asarray(mass["M"] @ R)
            mass["G"] = R.T @ mass["MR"]
        P = mass["MR"].T @ vec  # (6, k)
        content = np.einsum("ik,ik->k", P, np.linalg.solve(mass["G"], P))
        return content > 0.5

    # -- mode shapes at points ------------------------------------------------
    def interpolation(self, points: np.ndarray, component: int = 2) -> sp.csr_matrix:
        """(n_points, n_dof) sparse map from DOFs to one field (2 = w0) at (x, y) points."""
        e, xi, eta = self.mesh.locate(points)
        N, _, _ = shape_2d(xi, eta)
        cols = NODE_DOF * self.mesh.connectivity[e] + component
        rows = np.repeat(np.arange(len(e)), 16)
        return sp.csr_matrix((N.ravel(), (rows, cols.ravel())), shape=(len(e), self.mesh.n_dof))

    def shapes_at(self, modes: Modes, points) -> np.ndarray:
        """(n_modes, n_points) w0 of each mode at (x, y) points, same scaling as modes.shapes."""
        T = self.interpolation(points)
        return np.asarray((T @ modes.shapes).T)

    # -- sensitivities ----------------------------------------------------------
    def eigen_sensitivities(self, modes: Modes, names: Sequence[str], params=None,
                            material=None) -> np.ndarray:
        """(n_modes, len(names)) d(omega^2)/dp = phi'(dK/dp - omega^2 dM/dp) phi, rad^2/s^2 per unit p.

        ``params``/``material`` must be those the modes were solved with
        (defaults: the ones recorded in ``modes``).
        """
        if params is None:
            params, material = modes.params, (modes.material if material is None else material)
        name = self._material_name(material)
        mat = self._materials(params, material)[name]
        dq = q_derivatives(mat, list(names))          # (7, P)
        L, R = self._maps[name]
        dc = L @ dq[:6]                                 # (21, P)
        dI = np.outer(R, dq[6])                         # (3, P)
        eK, eM = coefficient_energies(self, modes)
        return eK @ dc - modes.omega2[:, None] * (eM @ dI)


def natural_frequencies(laminate: Laminate, length: float, width: float, n: int = 10,
                        mesh=None) -> np.ndarray:
    """The n lowest free-free elastic natural frequencies, Hz."""
    return PlateModel.build(laminate, length, width, mesh).solve(n).frequencies_hz
