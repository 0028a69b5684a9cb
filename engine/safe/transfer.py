"""Per-mode transfer functions of a point or line source to a surface sensor (package-internal).

The SAFE modes (wavenumbers, group velocities, surface amplitudes at the top and bottom
faces) of ``mode_data`` give, per mode, the response of ``transfer_from_data``: the
modal participation of a normal force or an in-plane "pin" load (a bonded PZT disc's rim)
times the spatial kernel of a point source (Hankel functions, ``spatial``) or a line source,
with the flexural mode's evanescent near field (``spatial_near``) where asked. Used by
``engine.safe.transient`` (``mode_transfer``, ``transient_response``). Units SI.
"""
from __future__ import annotations

import numpy as np

from .branches import cheb_branches, dense_table, invert_table, reduce_class
from .labels import branch_table
from .model import TWO_PI, SafeError

__all__ = ["hankel", "spatial", "spatial_near", "check_common", "check_load", "mode_data",
           "transfer_from_data", "PROBES", "LOADS", "FACES", "QUANTITIES"]

QUANTITIES = ("displacement", "velocity", "acceleration", "strain")
N_CHEB_MAX = 256      # Chebyshev nodes for lambda (eigenvalues only)
N_VEC = 64            # nodes for the eigenvector (surface amplitude) series


# ---------------------------------------------------------------------------
# modal transfer functions
def hankel(nu: int, z: np.ndarray) -> np.ndarray:
    """H_nu^(1)(z) for real z > 0: exact below 25, 8-term asymptotic series above."""
    from scipy import special  # here: the dispersion curves import no scipy (~0.2 s CPU)
    z = np.asarray(z, float)
    out = np.empty(z.shape, complex)
    small = z < 25.0
    if np.any(small):
        out[small] = special.hankel1(nu, z[small])
    if np.any(~small):
        zz = z[~small]
        mu = 4.0 * nu * nu
        term = np.ones_like(zz, dtype=complex)
        s = term.copy()
        for m in range(1, 9):
            term = term * (mu - (2 * m - 1) ** 2) / (m * 8.0 * zz) * 1j
            s = s + term
        out[~small] = np.sqrt(2.0 / (np.pi * zz)) * np.exp(1j * (zz - nu * np.pi / 2 - np.pi / 4)) * s
    return out


def spatial(k: np.ndarray, x: float, source: str, kind: str) -> np.ndarray:
    """Spatial factor replacing exp(ikx): kind 'w' (w-like), 'u' (u-like), 'du' (d/dx of u-like);
    'ui', 'dui': the radial u of an in-plane point force along the path, far-field part
    (k/2) i H0(kr), and its d/dr (``transfer_from_data``, load 'inplane')."""
    if kind in ("ui", "dui"):
        kr = k * x
        return 0.5 * k * 1j * hankel(0, kr) if kind == "ui" else -0.5 * k * k * 1j * hankel(1, kr)
    if source == "line":
        e = np.exp(1j * k * x)
        return e * (1j * k) if kind == "du" else e
    kr = k * x
    if kind == "w":
        return 0.5 * k * hankel(0, kr)
    if kind == "u":
        return 0.5 * k * 1j * hankel(1, kr)
    return 0.5 * k * 1j * (k * hankel(0, kr) - hankel(1, kr) / x)


def spatial_near(k: np.ndarray, x: float, source: str, kind: str) -> np.ndarray:
    """Near-field (evanescent, k -> i k) partner of ``spatial`` for the flexural mode.

    Kirchhoff plate: the point-force Green's function is (i / 8 D k^2) [H0(kr) - H0(ikr)]
    = (i / 8 D k^2) [H0(kr) + (2i/pi) K0(kr)]; the line force gives
    (i / 4 D k^3) [exp(ikx) + i exp(-kx)]. So H0 -> (2i/pi) K0, H1 -> (2i/pi) K1 (point)
    and exp(ikx) -> i exp(-kx) for w, -exp(-kx) for u = -(h/2) dw/dx (line).
    """
    if source == "line":
        e = np.exp(-k * x)
        return {"w": 1j * e, "u": -e, "du": k * e}[kind]
    from scipy import special  # here, as in hankel
    kr = k * x
    e = np.exp(-kr)                  # K_n(z) = k_ne(z) exp(-z): no overflow, 0 far away
    if kind == "w":
        return (1j * k / np.pi) * special.k0e(kr) * e
    if kind == "u":
        return (-k / np.pi) * special.k1e(kr) * e
    return (k / np.pi) * (k * special.k0e(kr) + special.k1e(kr) / x) * e


def check_common(distance_m, quantity, sensor_length_m, source):
    if quantity not in QUANTITIES:
        raise SafeError(f"quantity {quantity!r}: expected one of {QUANTITIES}")
    if source not in ("point", "line"):
        raise SafeError(f"source {source!r}: expected 'point' or 'line'")
    if not (np.isfinite(distance_m) and distance_m > 0):
        raise SafeError(f"distance {distance_m!r} m: expected a positive value")
    if not (sensor_length_m >= 0 and sensor_length_m / 2 < distance_m):
        raise SafeError(f"sensor length {sensor_length_m!r} m: expected 0 <= L < 2 d")


#: surface probes of the mode data, in order: (face, component) -> row; products column p * 4 + q
PROBES = {("top", "u"): 0, ("top", "w"): 1, ("bottom", "u"): 2, ("bottom", "w"): 3}
LOADS = ("normal", "pin", "inplane")
FACES = ("top", "bottom")


def mode_data(model, wmax: float, labels, strict: bool = True):
    """Per included mode: Chebyshev series of lambda, lambda' and surface products."""
    rows = branch_table(model, wmax)
    if labels is not None:
        missing = set(labels) - {r["label"] for r in rows}
        if missing and strict:
            raise SafeError(f"mode(s) {sorted(missing)} do not exist below {wmax / TWO_PI:g} Hz; "
                            f"expected some of {[r['label'] for r in rows]}")
        rows = [r for r in rows if r["label"] in labels]
    top = 3 * (len(model.z_nodes) - 1)
    out = []
    for ci in sorted({r["ci"] for r in rows}):
        rs = [r for r in rows if r["ci"] == ci]
        cls = model.classes[ci]
        nb = max(r["j"] for r in rs) + 1
        red = reduce_class(cls, wmax, n_branches=nb, n_k=5, extra=1)   # phase error <~2e-2 rad at 0.3 m
        if red is None:
            continue
        # (4, r): phi_u, phi_w at the top, then at the bottom (PROBES); their pairwise
        # products (16 series) give every source face / sensor face combination
        probes = (cls.to_phys[[top, top + 2, 0, 2], :] @ red.basis)
        br = cheb_branches(red, nb, probes=probes, n_max=N_CHEB_MAX, n_vec=N_VEC, n_rigid=cls.n_rigid,
                           inplane_rows=(PROBES[("top", "u")], PROBES[("bottom", "u")]))
        for r in rs:
            out.append((r["label"], br, r["j"], r["cutoff"]))
    return out


def transfer_from_data(data, f: np.ndarray, distance_m, quantity, sensor_length_m, source,
                        near_field: bool = False, loss_factor: float = 0.0, load: str = "normal",
                        radius_m: float = 0.0, source_face: str = "top", sensor_face: str = "top"):
    """Complex transfer per mode (physics convention), per unit force, on grid f (Hz).

    near_field: add to A0 its evanescent partner (``spatial_near``), which cancels the
    spurious 1/r^2 (point) near field of the propagating-only term as k r -> 0.
    loss_factor: eta of moduli C (1 + i eta): each mode decays as exp(-alpha x),
    alpha = eta w / (2 |c_g|) (first order in eta: lambda(k) (1 + i eta) = w^2).
    load: 'normal' (a force along +z) or 'pin' (a ring of radial surface traction of
    radius ``radius_m``, total 1 N: the pin-force model of a bonded piezo disc); the
    source factor is phi_w (normal) or J1(k a) phi_u (pin) at ``source_face``, the
    receiver factor phi_u (u, strain) or i phi_w (w) at ``sensor_face`` (module docstring).
    'inplane': a point force of 1 N along the path on ``source_face`` (a pencil lead broken
    on the plate's edge): the gradient of the pin ring's field as its radius a -> 0 gives
    u_r = phi_u^2 (k/2) i H1'(kr) cos(theta) / D, H1'(z) = H0(z) - H1(z)/z (theta from the
    force; the caller applies cos(theta)). The near-field piece -H1(z)/z (~1/(kr) of the
    far field) is left out: in the whole field it cancels, to leading order in 1/(kr)^2,
    against the transverse (SH) mode's radial near field u_r ~ H1(k_s r)/(k_s r), which
    the u/w probes of the mode data do not hold; alone it would make a step force's strain
    grow like 1/f^2 at low frequency. Kept: u_r = phi_u^2 (k/2) i H0(kr) cos(theta) / D
    (a radial sensor does not read SH0's far field, u_theta). Strain only.
    """
    if load == "inplane" and quantity != "strain":
        raise SafeError(f"inplane load: only the strain is modelled, not the {quantity}")
    w = TWO_PI * f
    src = PROBES[(source_face, "w" if load == "normal" else "u")]
    col_u = PROBES[(sensor_face, "u")] * 4 + src
    col_w = PROBES[(sensor_face, "w")] * 4 + src
    n_u = int(src in (PROBES[("top", "u")], PROBES[("bottom", "u")]))  # u factors besides the receiver's
    res = {}
    for label, br, j, _cut in data:
        if near_field and label == "A0":
            kernel = lambda k, x, s, kind: spatial(k, x, s, kind) + spatial_near(k, x, s, kind)
        else:
            kernel = spatial
        kt, lt, dt, ex = dense_table(br, j)
        k, i, t = invert_table(kt, lt, dt, w)
        s = np.ones(f.shape)
        if label == "A0":
            # lambda = w^2 carries an absolute round-off (|lambda(0)|, ~1 rad^2/s^2 for a
            # 1.6 mm CFRP), so below w_K (relative error 1e-4) A0 follows its thin-plate
            # law from w_K: k ~ w^1/2, D = 2 w c_g ~ w^3/2, phi_u phi_w ~ k, phi_w^2 const
            wK = 100.0 * np.sqrt(abs(lt[0]) + 1e-14 * abs(lt[-1]))
            below = (w < wK) & (w > 0)
            if np.any(below):
                kK, iK, tK = invert_table(kt, lt, dt, np.array([wK]))
                s = np.where(below, w / wK, 1.0)
                k = np.where(below, kK[0] * np.sqrt(s), k)
                i, t = np.where(below, iK[0], i), np.where(below, tK[0], t)
        ok = np.isfinite(k)
        H = np.zeros(f.shape, complex)
        if np.any(ok):
            i, t, kk, s = i[ok], t[ok], k[ok], s[ok]
            lerp = lambda v: v[i] + t * (v[i + 1] - v[i])
            wK_ok = w[ok] / s
            D = 2.0 * wK_ok * lerp(dt / (2.0 * np.sqrt(np.maximum(lt, 1e-300)))) * s ** 1.5   # 2 w c_g
            prod = ex["prod"]              # (n+1, 16): products of the PROBES rows
            # A0 below w_K: phi_u ~ k ~ s^1/2, phi_w constant
            puw = lerp(prod[:, col_u]) * s ** ((1 + n_u) / 2)
            pww = lerp(prod[:, col_w]) * s ** (n_u / 2)
            if load == "pin":
                from scipy import special  # here, as in hankel
                ring = special.j1(kk * radius_m)
                puw, pww = puw * ring, pww * ring
            alpha = loss_factor * w[ok] ** 2 / np.abs(D)          # eta w / (2 |c_g|)
            if quantity == "strain":
                if sensor_length_m > 0:
                    L = sensor_length_m
                    x1, x0 = distance_m + L / 2, distance_m - L / 2
                    ku = "ui" if load == "inplane" else "u"
                    sp = (kernel(kk, x1, source, ku) * np.exp(-alpha * x1)
                          - kernel(kk, x0, source, ku) * np.exp(-alpha * x0)) / L
                else:
                    ku, kd = ("ui", "dui") if load == "inplane" else ("u", "du")
                    sp = (kernel(kk, distance_m, source, kd)
                          - alpha * kernel(kk, distance_m, source, ku)) * np.exp(-alpha * distance_m)
                H[ok] = puw * sp / D
            else:
                Hw = 1j * pww * kernel(kk, distance_m, source, "w") * np.exp(-alpha * distance_m) / D
                ww = w[ok]
                H[ok] = {"displacement": Hw, "velocity": -1j * ww * Hw,
                         "acceleration": -ww * ww * Hw}[quantity]
        res[label] = H
    return res


def check_load(load, radius_m, source_face, sensor_face, source, near_field) -> None:
    if load not in LOADS:
        raise SafeError(f"load {load!r}: expected one of {LOADS}")
    for name, face in (("source_face", source_face), ("sensor_face", sensor_face)):
        if face not in FACES:
            raise SafeError(f"{name} {face!r}: expected one of {FACES}")
    if load == "pin" and not (source == "point" and np.isfinite(radius_m) and radius_m > 0):
        raise SafeError(f"pin load: expected a point source with actuator radius > 0 m, got "
                        f"source={source!r}, radius={radius_m!r}")
    if load == "inplane" and source != "point":
        raise SafeError(f"inplane load: expected a point source, got source={source!r}")
    if near_field and (load, source_face) != ("normal", "top"):
        raise SafeError("near_field: only for a normal force on the top face")
