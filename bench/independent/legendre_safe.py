"""An independent guided-wave model of a layered plate: global Legendre polynomials through
the thickness (Lefebvre / Othman "Legendre polynomial approach"), written with numpy/scipy only.

It shares no code with ``engine.safe`` (spectral elements per ply, Lagrange-GLL nodes,
branches as Chebyshev series in k): here each displacement component is ONE expansion
in Legendre polynomials P_0..P_N over the whole thickness, the plies enter only through
piecewise-constant stiffness and density under Gauss quadrature, the ply stiffness is
built from the engineering constants by this module's own compliance inversion and
4th-order tensor rotation, and the modes at a frequency are the real roots k of the
quadratic eigenproblem (linearised, ``scipy.linalg.eig``), not w(k) inverted by tables.
Convergence is by the order N (a global basis converges algebraically across the ply
interfaces, where the strain jumps; at the frequencies of the bench, fh < 0.6 MHz mm,
the error in c_g is < 1e-5 at N = 24: ``tests/unit/bench/test_legendre_safe.py``).

Model. u(x, z, t) = U(z) exp(i(k x - w t)), x along the propagation direction, z from the
mid-plane. With the strain operator eps = Lx du/dx + Lz du/dz (Voigt 11, 22, 33, 23, 13,
12) the weak form gives [A(k) - w^2 M] q = f with the Hermitian
A(k) = k^2 K2 + i k (K1^T - K1) + K0, K2 = int N^T Lx^T C Lx N, K1 = int N^T Lx^T C Lz N',
K0 = int N'^T Lz^T C Lz N', M = int rho N^T N. Group velocity c_g = q^H A'(k) q / (2 w q^H M q)
(Hellmann-Feynman). Response of a surface force by the residues of the wavenumber integral
(outgoing roots, c_g > 0): a line force gives U = i q (q^H f) exp(ikx) / (2 w c_g) per mode
(q M-normalised); a point force replaces exp(ikx) by the cylindrical kernels (k/2) H0(kr)
(w-like) and (k/2) i H1(kr) (radial, u-like), whose r-derivative is the radial strain
(isotropic spreading along the path: no beam skew, as the simulated rig assumes). A
bonded piezo disc of radius a (ring of radial traction, 1 N in total) has the source
factor -i J1(k a) conj(q_u) in place of conj(q_w) (the order-1 Hankel transform of the ring).

Units SI: m, s, Hz, Pa, kg/m^3, rad/m, m/s; angles in degrees (ply angle from x towards y).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from numpy.polynomial import legendre as leg
from scipy import special

__all__ = ["Layer", "layers_of", "ply_stiffness_3d", "LegendrePlate", "Branches", "branches", "plate_of", "transfer"]

# strain = LX du/dx + LZ du/dz, Voigt (11, 22, 33, 23, 13, 12), u = (u, v, w)
LX = np.zeros((6, 3)); LX[0, 0] = 1.0; LX[4, 2] = 1.0; LX[5, 1] = 1.0
LZ = np.zeros((6, 3)); LZ[2, 2] = 1.0; LZ[3, 1] = 1.0; LZ[4, 0] = 1.0
_VOIGT = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))


@dataclass(frozen=True)
class Layer:
    """One ply: stiffness in the plate axes x (= propagation direction), y, z (6x6 Voigt, Pa),
    density (kg/m^3), z_bottom and z_top (m, from the mid-plane)."""

    C: np.ndarray
    density: float
    z0: float
    z1: float


def ply_stiffness_3d(E1, E2, E3, nu12, nu13, nu23, G12, G13, G23) -> np.ndarray:
    """Orthotropic 6x6 stiffness (Voigt 11, 22, 33, 23, 13, 12; engineering shear) from the
    engineering constants, by inverting the compliance."""
    S = np.diag([1 / E1, 1 / E2, 1 / E3, 1 / G23, 1 / G13, 1 / G12])
    S[0, 1] = S[1, 0] = -nu12 / E1
    S[0, 2] = S[2, 0] = -nu13 / E1
    S[1, 2] = S[2, 1] = -nu23 / E2
    return np.linalg.inv(S)


def _rotated(C: np.ndarray, angle_deg: float) -> np.ndarray:
    """C (Voigt) of a material whose axis 1 is turned by ``angle_deg`` about z from x:
    through the 4th-order tensor c_ijkl -> a_ip a_jq a_kr a_ls c_pqrs."""
    c = np.zeros((3, 3, 3, 3))
    for I, (i, j) in enumerate(_VOIGT):
        for J, (k, l) in enumerate(_VOIGT):
            for a, b in ((i, j), (j, i)):
                for cc, d in ((k, l), (l, k)):
                    c[a, b, cc, d] = C[I, J]
    t = math.radians(angle_deg)
    a = np.array([[math.cos(t), -math.sin(t), 0.0], [math.sin(t), math.cos(t), 0.0], [0.0, 0.0, 1.0]])
    r = np.einsum("ip,jq,kr,ls,pqrs->ijkl", a, a, a, a, c)
    return np.array([[r[i, j, k, l] for (k, l) in _VOIGT] for (i, j) in _VOIGT])


def layers_of(plies, direction_deg: float = 0.0) -> tuple[Layer, ...]:
    """Layers of a ply list, bottom first. ``plies``: iterables (constants, angle_deg,
    thickness_m) with constants a mapping E1, E2, E3, nu12, nu13, nu23, G12, G13, G23,
    density; or objects with ``material`` (attributes E1, E2, nu12, G12, G13, G23, density,
    and optionally E3, nu13, nu23 = None: transversely isotropic), ``angle_deg``,
    ``thickness`` (an ``engine.laminate.Ply`` is read as plain data)."""
    rows = []
    for p in plies:
        if hasattr(p, "material"):
            m = p.material
            e3 = m.E3 if m.E3 is not None else m.E2
            n13 = m.nu13 if m.nu13 is not None else m.nu12
            n23 = m.nu23 if m.nu23 is not None else m.E2 / (2 * m.G23) - 1
            c = dict(E1=m.E1, E2=m.E2, E3=e3, nu12=m.nu12, nu13=n13, nu23=n23, G12=m.G12, G13=m.G13,
                     G23=m.G23, density=m.density)
            rows.append((c, p.angle_deg, p.thickness))
        else:
            rows.append(tuple(p))
    h = sum(t for _, _, t in rows)
    z = -h / 2
    out = []
    for c, ang, t in rows:
        C = ply_stiffness_3d(c["E1"], c["E2"], c["E3"], c["nu12"], c["nu13"], c["nu23"], c["G12"], c["G13"],
                             c["G23"])
        out.append(Layer(_rotated(C, ang - direction_deg), float(c["density"]), z, z + t))
        z += t
    return tuple(out)


def _shape(p: int, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hierarchical (Babuska-Szabo) shape functions on [-1, 1] and their xi-derivatives:
    (1 - xi)/2, (1 + xi)/2, then (P_j - P_(j-2)) / sqrt(2 (2j - 1)), j = 2..p (integrated
    Legendre polynomials, zero at both ends)."""
    n = p + 1
    V = np.zeros((xi.size, n))
    D = np.zeros((xi.size, n))
    V[:, 0], V[:, 1] = 0.5 * (1 - xi), 0.5 * (1 + xi)
    D[:, 0], D[:, 1] = -0.5, 0.5
    eye = np.eye(p + 1)
    for j in range(2, n):
        c = (eye[j] - eye[j - 2]) / math.sqrt(2 * (2 * j - 1))
        V[:, j] = leg.legval(xi, c)
        D[:, j] = leg.legval(xi, leg.legder(c))
    return V, D


class LegendrePlate:
    """The plate's guided waves along one direction: one p-element of hierarchical Legendre
    shape functions per ply (degree ``order``), displacement continuous across the plies."""

    def __init__(self, layers: tuple[Layer, ...], order: int = 6):
        self.layers, self.p = layers, int(order)
        self.h = layers[-1].z1 - layers[0].z0
        p, nl = self.p, len(layers)
        n_node = nl + 1                                 # interface (vertex) functions
        n_scalar = n_node + nl * (p - 1)                # per displacement component
        ndof = 3 * n_scalar
        K0, K1, K2, M = (np.zeros((ndof, ndof)) for _ in range(4))
        xq, wq = leg.leggauss(p + 3)
        V, D = _shape(p, xq)
        for li, L in enumerate(layers):
            t = L.z1 - L.z0
            loc = [li, li + 1] + [n_node + li * (p - 1) + j for j in range(p - 1)]
            idx = np.array([c * n_scalar + i for c in range(3) for i in loc])
            k0, k1, k2, m = (np.zeros((idx.size, idx.size)) for _ in range(4))
            for qi in range(xq.size):
                w = 0.5 * t * wq[qi]
                Nz = np.kron(np.eye(3), V[qi][None, :])
                dNz = np.kron(np.eye(3), D[qi][None, :]) * (2.0 / t)
                Bx, Bz = LX @ Nz, LZ @ dNz
                k2 += w * Bx.T @ L.C @ Bx
                k1 += w * Bx.T @ L.C @ Bz
                k0 += w * Bz.T @ L.C @ Bz
                m += w * L.density * Nz.T @ Nz
            ix = np.ix_(idx, idx)
            K0[ix] += k0
            K1[ix] += k1
            K2[ix] += k2
            M[ix] += m
        self.K0, self.K1, self.K2, self.M = K0, K1, K2, M
        self.K1a = K1.T - K1                      # A(k) = k^2 K2 + i k K1a + K0
        e = np.eye(ndof)
        top, bot = nl, 0                          # vertex functions at z = +h/2 and -h/2
        self.probe = {("top", "u"): e[top], ("top", "w"): e[2 * n_scalar + top],
                      ("bottom", "u"): e[bot], ("bottom", "w"): e[2 * n_scalar + bot]}

    def A(self, k: float) -> np.ndarray:
        return k * k * self.K2 + 1j * k * self.K1a + self.K0

    def frequencies(self, k: float, n_modes: int = 6) -> tuple[np.ndarray, np.ndarray]:
        """(w (rad/s), M-normalised eigenvectors) of the lowest ``n_modes`` branches at real k."""
        lam, Q = sla.eigh(self.A(k), self.M, subset_by_index=(0, n_modes - 1))
        return np.sqrt(np.maximum(lam, 0.0)), Q

    def group_velocity_at_k(self, k: float, n_modes: int = 6) -> tuple[np.ndarray, np.ndarray]:
        """(w, c_g) of the lowest branches at real k (Hellmann-Feynman)."""
        w, Q = self.frequencies(k, n_modes)
        dA = 2 * k * self.K2 + 1j * self.K1a
        cg = np.real(np.einsum("ij,ik,kj->j", Q.conj(), dA, Q)) / (2 * np.maximum(w, 1e-300))
        return w, cg

    def roots(self, f_hz: float, kmax: float | None = None):
        """Propagating modes at frequency f: (k (rad/m), c_g (m/s), M-normalised q) of every
        real root k > 0 with c_g > 0, sorted by k (fastest phase first): the quadratic
        eigenproblem [k^2 K2 + i k K1a + K0 - w^2 M] q = 0 linearised in (q, k q)."""
        w = 2 * math.pi * f_hz
        n = self.M.shape[0]
        # dimensionless: kappa = k h, matrices over a stiffness scale (balanced linearisation)
        s = float(np.abs(self.K2).max())
        K0, K1, K2 = self.K0 * self.h ** 2 / s, self.K1a * self.h / s, self.K2 / s
        Mw = w * w * self.M * self.h ** 2 / s
        Z, I = np.zeros((n, n)), np.eye(n)
        L0 = np.block([[Z, I], [K0 - Mw, 1j * K1]])
        L1 = np.block([[I, Z], [Z, -K2]])
        ev, V = sla.eig(L0, L1)
        out = []
        for j in np.flatnonzero(np.isfinite(ev)):
            k = ev[j] / self.h
            if not (k.real > 0 and abs(k.imag) < 1e-5 * abs(k)):
                continue
            if kmax is not None and k.real > kmax:
                continue
            kr = float(k.real)
            # refine by inverse iteration on the Hermitian pencil at that k
            lam, Q = sla.eigh(self.A(kr), self.M)
            i = int(np.argmin(np.abs(lam - w * w)))
            q = Q[:, i]
            dA = 2 * kr * self.K2 + 1j * self.K1a
            dlam = float(np.real(q.conj() @ dA @ q))
            for _ in range(3):                          # Newton on lambda(k) = w^2
                kr = kr - (lam[i] - w * w) / dlam
                lam, Q = sla.eigh(self.A(kr), self.M)
                i = int(np.argmin(np.abs(lam - w * w)))
                q = Q[:, i]
                dA = 2 * kr * self.K2 + 1j * self.K1a
                dlam = float(np.real(q.conj() @ dA @ q))
            dA = 2 * kr * self.K2 + 1j * self.K1a
            cg = float(np.real(q.conj() @ dA @ q)) / (2 * w)
            if cg > 0:
                out.append((kr, cg, q))
        out.sort(key=lambda r: r[0])
        return out

    def velocities(self, f_hz) -> list[list[tuple[float, float]]]:
        """Per frequency: [(k, c_g), ...] of the propagating modes, sorted by k."""
        return [[(k, cg) for k, cg, _ in self.roots(f)] for f in np.atleast_1d(f_hz)]


@dataclass(frozen=True)
class Branches:
    """The lowest ``n`` branches w_j(k) of a plate on a geometric k grid (rad/m), with their
    group velocities (m/s) and surface products: ``prod[(rcv, src)]`` = q_rcv conj(q_src)
    of the M-normalised mode (rcv, src: probe names such as ('top', 'u'))."""

    k: np.ndarray              # (nk,)
    w: np.ndarray              # (nb, nk)
    cg: np.ndarray             # (nb, nk)
    prod: dict

    def at(self, j: int, w_target: np.ndarray):
        """(k, c_g, {probe pair: product}) of branch j at the angular frequencies
        ``w_target`` (NaN outside the range it covers): k by cubic Hermite inversion of
        w_j(k) with dk/dw = 1 / c_g at the nodes, the rest by Hermite/linear interpolation in k."""
        wj, cj, kk = self.w[j], self.cg[j], self.k
        # the monotonic run at the top of the grid (round-off makes the lowest k of A0 noisy;
        # a backward-wave turn would end the branch)
        bad = np.flatnonzero(np.diff(wj) <= 0)
        start = int(bad[-1]) + 1 if bad.size else 0
        wj, cj, kk = wj[start:], cj[start:], kk[start:]
        wt = np.asarray(w_target, float)
        i = np.clip(np.searchsorted(wj, wt) - 1, 0, wj.size - 2)
        inside = (wt >= wj[0]) & (wt <= wj[-1])
        h = wj[i + 1] - wj[i]
        t = (wt - wj[i]) / h
        h00, h10 = 2 * t ** 3 - 3 * t ** 2 + 1, t ** 3 - 2 * t ** 2 + t
        h01, h11 = -2 * t ** 3 + 3 * t ** 2, t ** 3 - t ** 2
        k = h00 * kk[i] + h10 * h / cj[i] + h01 * kk[i + 1] + h11 * h / cj[i + 1]
        tk = (k - kk[i]) / (kk[i + 1] - kk[i])
        cg = cj[i] + tk * (cj[i + 1] - cj[i])
        prod = {key: v[j, start:][i] + tk * (v[j, start:][i + 1] - v[j, start:][i]) for key, v in self.prod.items()}
        nan = np.where(inside, 1.0, np.nan)
        return k * nan, cg * nan, {key: v * nan for key, v in prod.items()}


def branches(plate: LegendrePlate, fmax_hz: float, n_branches: int = 3, n_k: int = 600) -> Branches:
    """The lowest ``n_branches`` of ``plate`` up to (beyond) ``fmax_hz`` on ``n_k`` geometric
    wavenumbers from 5e-3 k_A0(fmax) to 1.05 k_A0(fmax) (eigh of the Hermitian pencil at each k)."""
    w_max = 2 * math.pi * fmax_hz
    # k of the slowest branch at fmax: bisection on w_0(k)
    lo, hi = 1e-3, 1.0
    while plate.frequencies(hi, 1)[0][0] < w_max:
        hi *= 2
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if plate.frequencies(mid, 1)[0][0] < w_max else (lo, mid)
    kmax = 1.05 * hi
    k = np.geomspace(kmax * 5e-3, kmax, n_k)
    nb = n_branches
    W, CG = np.zeros((nb, n_k)), np.zeros((nb, n_k))
    keys = [(r, s) for r in plate.probe for s in plate.probe]
    P = {key: np.zeros((nb, n_k), complex) for key in keys}
    for i, kk in enumerate(k):
        lam, Q = sla.eigh(plate.A(kk), plate.M, subset_by_index=(0, nb - 1))
        w = np.sqrt(np.maximum(lam, 0.0))
        dA = 2 * kk * plate.K2 + 1j * plate.K1a
        W[:, i] = w
        CG[:, i] = np.real(np.einsum("ij,ik,kj->j", Q.conj(), dA, Q)) / (2 * np.maximum(w, 1e-300))
        for r, s in keys:
            P[(r, s)][:, i] = (plate.probe[r] @ Q) * np.conj(plate.probe[s] @ Q)
    return Branches(k, W, CG, P)


@functools.lru_cache(maxsize=64)
def _plate(key: tuple, order: int) -> LegendrePlate:
    layers = tuple(Layer(np.array(C).reshape(6, 6), rho, z0, z1) for C, rho, z0, z1 in key)
    return LegendrePlate(layers, order)


def plate_of(layers: tuple[Layer, ...], order: int = 6) -> LegendrePlate:
    """A cached ``LegendrePlate``."""
    key = tuple((tuple(L.C.ravel().round(3)), L.density, L.z0, L.z1) for L in layers)
    return _plate(key, order)


def _kernels(k: np.ndarray, r: float, kind: str) -> np.ndarray:
    """Cylindrical spreading of a point source: w-like (k/2) H0(kr); radial u-like
    (k/2) i H1(kr); 'du': d/dr of the u-like one. An in-plane point force along the path:
    its P-like field is the gradient of the scalar one, u_r = (k/2) i H1'(kr) per unit
    phi_u^2, H1'(z) = H0(z) - H1(z)/z; of it the far field (k/2) i H0(kr) ('ui') and its
    d/dr, -(k^2/2) i H1(kr) ('dui'): the near-field piece cancels against the SH mode's
    radial near field in the whole field (not modelled here)."""
    kr = k * r
    if kind == "ui":
        return 0.5 * k * 1j * special.hankel1(0, kr)
    if kind == "dui":
        return -0.5 * k * k * 1j * special.hankel1(1, kr)
    if kind == "w":
        return 0.5 * k * special.hankel1(0, kr)
    if kind == "u":
        return 0.5 * k * 1j * special.hankel1(1, kr)
    return 0.5 * k * 1j * (k * special.hankel1(0, kr) - special.hankel1(1, kr) / r)


@functools.lru_cache(maxsize=64)
def _branches_cached(plate: LegendrePlate, fmax_hz: float, n_branches: int) -> Branches:
    return branches(plate, fmax_hz, n_branches)


def transfer(plate: LegendrePlate, distance_m: float, f_hz: np.ndarray, *, load: str = "normal",
             radius_m: float = 0.0, source_face: str = "top", sensor_face: str = "top",
             sensor_length_m: float = 0.0, n_branches: int = 3) -> dict:
    """{'mode<j>': complex radial surface strain per newton} over ``f_hz`` (physics convention
    exp(i(kr - wt))), j = 0, 1, ... the branches by increasing frequency at given k (A0, SH0,
    S0 below the first cut-off), from a point source: 'normal' force along +z, a 'pin'
    ring of radial traction of ``radius_m`` (a bonded piezo disc), or an 'inplane' point
    force of 1 N along the path (a lead broken on the plate's edge; the caller applies the
    cos(theta) of a path at theta from the force), on ``source_face``; strain along the
    path averaged over ``sensor_length_m``; zero where a branch does not reach."""
    f = np.atleast_1d(np.asarray(f_hz, float))
    out: dict[str, np.ndarray] = {}
    if f.size == 0 or not np.any(f > 0):
        return out
    br = _branches_cached(plate, float(f.max()) * 1.01, n_branches)
    src = (source_face, "w" if load == "normal" else "u")
    rcv = (sensor_face, "u")
    w = 2 * math.pi * f
    for j in range(n_branches):
        kk, cg, prod = br.at(j, w)
        ok = np.isfinite(kk) & (cg > 0) & (w > 0)
        H = np.zeros(f.shape, complex)
        if np.any(ok):
            k, p = kk[ok], prod[(rcv, src)][ok]
            D = 2 * w[ok] * cg[ok]
            if load == "pin":
                p = -1j * p * special.j1(k * radius_m)
            elif load == "inplane":       # the pin ring's source factor without J1(ka) (its a -> 0 gradient)
                p = -1j * p
            ku, kd = ("ui", "dui") if load == "inplane" else ("u", "du")
            if sensor_length_m > 0:
                L = sensor_length_m
                sp = (_kernels(k, distance_m + L / 2, ku) - _kernels(k, distance_m - L / 2, ku)) / L
            else:
                sp = _kernels(k, distance_m, kd)
            H[ok] = 1j * p * sp / D
        out[f"mode{j}"] = H
    return out
