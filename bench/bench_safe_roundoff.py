"""How far a change of the SAFE numerics moves the curves, against exact and independent values.

Run in each tree (before / after), then compare:

    cd /tmp && PYTHONPATH=TREE python /work/wt/h44/bench/bench_safe_roundoff.py dump OUT.npz
    python bench/bench_safe_roundoff.py compare BEFORE.npz AFTER.npz

``dump`` writes labid's curves (``engine.safe.dispersion``, every mode) on the cases below;
``compare`` prints, per case, the largest relative change of k and c_g between the trees and,
for each tree, the error against

* the **exact** Rayleigh-Lamb roots of the isotropic plate (built-in 'aluminium', 3.175 mm):
  brentq on the real, entire forms of the symmetric / antisymmetric dispersion functions
  (p^2, q^2 as arguments, so no branch cuts), c_g = -F_k / F_w by complex-step derivatives
  (exact to ~1e-14);
* the **independent** Legendre model (bench/independent/legendre_safe.py, via
  tests/wave_reference.py: its c_g is interpolated on 250 wavenumbers, ~1e-5).

Units SI: Hz, rad/m, m/s.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

CASES = {   # name: (specimen, fmax Hz, n, direction deg, extra low frequencies Hz)
    "cfrp-cmd": ("cfrp", 1e6, 10, 0.0, ()),
    "cfrp-0-1MHz": ("cfrp", 1e6, 200, 0.0, ()),
    "cfrp-30-1MHz": ("cfrp", 1e6, 200, 30.0, ()),
    "cfrp-90-200k": ("cfrp", 2e5, 200, 90.0, (1e3, 2e3, 3e3, 5e3)),
    "al-cmd": ("aluminium", 1e6, 10, 0.0, ()),
    "al-2MHz": ("aluminium", 2e6, 200, 0.0, (1e3, 2e3, 3e3, 5e3)),
    "al-low": ("aluminium", 2e6, 1, 0.0, tuple(np.geomspace(1e3, 2e4, 30))),   # the round-off floor
    "cfrp-low": ("cfrp", 1e6, 1, 0.0, tuple(np.geomspace(1e3, 2e4, 30))),
    "al-vlow": ("aluminium", 4e5, 1, 0.0, tuple(np.geomspace(10.0, 1e3, 21))),   # a rig's lowest bins
}


def dump(out: str) -> None:
    from engine.safe import dispersion
    from labid.inputs.specimen import load_specimen
    arrays = {}
    for name, (spec, fmax, n, ang, low) in CASES.items():
        f = np.concatenate([np.asarray(low, float), np.arange(1, n + 1) * fmax / n])
        f = np.unique(f)
        d = dispersion(load_specimen(spec).laminate, f, ang)
        arrays[f"{name}|f"] = f
        for m in d.modes:
            arrays[f"{name}|{m.label}|k"] = m.wavenumber_rad_m
            arrays[f"{name}|{m.label}|cg"] = m.group_velocity_m_s
    np.savez(out, **arrays)


def _entire(x, d):
    """cos(sqrt(x) d) and sin(sqrt(x) d) / sqrt(x): entire functions of x (any sign, complex)."""
    s = np.sqrt(x + 0j)
    small = np.abs(s) < 1e-12
    sx = np.where(small, d, np.sin(s * d) / np.where(small, 1.0, s))
    return np.cos(s * d), sx


def rayleigh_lamb(k, w, cl, ct, h, sym: bool):
    """Dispersion function of the free isotropic plate (thickness h), real for real k, w."""
    d = h / 2
    p2, q2 = w * w / cl ** 2 - k * k, w * w / ct ** 2 - k * k
    cp_, sp = _entire(p2, d)
    cq, sq = _entire(q2, d)
    if sym:    # (q^2-k^2)^2 cos(pd) sin(qd)/q + 4 k^2 p sin(pd) cos(qd)
        return (q2 - k * k) ** 2 * cp_ * sq + 4 * k * k * p2 * sp * cq
    return (q2 - k * k) ** 2 * sp * cq + 4 * k * k * q2 * sq * cp_     # divided by p


def exact_lamb(f, k_guess, cl, ct, h, sym: bool):
    """Exact (k, c_g) of the branch nearest k_guess at each frequency f (Hz)."""
    from scipy.optimize import brentq
    ks, cgs = [], []
    for fi, kg in zip(f, k_guess):
        w = 2 * np.pi * fi
        if not np.isfinite(kg):
            ks.append(np.nan); cgs.append(np.nan); continue
        g = lambda k: float(np.real(rayleigh_lamb(k, w, cl, ct, h, sym)))
        for span in (1e-7, 1e-6, 1e-5, 1e-4, 1e-3):
            a, b = kg * (1 - span), kg * (1 + span)
            if g(a) * g(b) < 0:
                break
        else:
            ks.append(np.nan); cgs.append(np.nan); continue
        k = brentq(g, a, b, xtol=1e-15 * kg, rtol=1e-15, maxiter=200)
        e = 1e-20
        fk = np.imag(rayleigh_lamb(k + 1j * e * k, w, cl, ct, h, sym)) / (e * k)
        fw = np.imag(rayleigh_lamb(k, w + 1j * e * w, cl, ct, h, sym)) / (e * w)
        ks.append(k); cgs.append(-fk / fw)
    return np.array(ks), np.array(cgs)


def _rel(a, b):
    ok = np.isfinite(a) & np.isfinite(b)
    if not ok.any():
        return np.nan
    return float(np.max(np.abs(a[ok] - b[ok]) / np.abs(b[ok])))


def compare(before: str, after: str) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from labid.inputs.specimen import load_specimen
    A, B = np.load(before), np.load(after)
    print("| case | modes | max rel. change k | max rel. change c_g | where (f, mode) |")
    print("|---|---|---|---|---|")
    for name in CASES:
        f = A[f"{name}|f"]
        labels = sorted({key.split("|")[1] for key in A.files if key.startswith(name + "|") and key.count("|") == 2})
        wk, wc, where = 0.0, 0.0, ""
        for lb in labels:
            rk = np.nan_to_num(np.abs(A[f"{name}|{lb}|k"] - B[f"{name}|{lb}|k"]) / np.abs(A[f"{name}|{lb}|k"]))
            rc = np.nan_to_num(np.abs(A[f"{name}|{lb}|cg"] - B[f"{name}|{lb}|cg"]) / np.abs(A[f"{name}|{lb}|cg"]))
            wk = max(wk, float(rk.max()))
            if rc.max() > wc:
                wc, where = float(rc.max()), f"{f[np.argmax(rc)]:.0f} Hz {lb}"
        worst = (wk, wc, where)
        print(f"| {name} | {len(labels)} | {worst[0]:.1e} | {worst[1]:.1e} | {worst[2]} |")
    # exact Rayleigh-Lamb (isotropic)
    mat = load_specimen("aluminium").laminate.plies[0].material
    lam = load_specimen("aluminium").laminate
    from engine.laminate import stiffness_3d
    C = stiffness_3d(mat)
    cl, ct, h = np.sqrt(C[0, 0] / mat.density), np.sqrt(C[5, 5] / mat.density), lam.thickness
    print("\n| case | mode | f range | before: max rel. error k / c_g vs exact | after | 1-5 kHz points before / after (c_g) |")
    print("|---|---|---|---|---|---|")
    for name in ("al-cmd", "al-2MHz", "al-low", "al-vlow"):
        f = A[f"{name}|f"]
        for lb, sym in (("A0", False), ("S0", True), ("A1", False), ("S1", True)):
            if f"{name}|{lb}|k" not in A.files:
                continue
            ke, cge = exact_lamb(f, A[f"{name}|{lb}|k"], cl, ct, h, sym)
            errs = []
            for T in (A, B):
                errs.append((_rel(T[f"{name}|{lb}|k"], ke), _rel(T[f"{name}|{lb}|cg"], cge)))
            low = (f < 6e3) if name != "al-vlow" else (f < 1.1e3)
            lows = [_rel(T[f"{name}|{lb}|cg"][low], cge[low]) if low.any() else np.nan for T in (A, B)]
            if name in ("al-low", "al-vlow"):    # the median error over the 30 low frequencies, not only the max
                sel = np.isfinite(cge) & (f < (3e4 if name == "al-low" else 1.1e3))
                sel = sel & (cge > 0)
                med = [np.nan] * 2 if not sel.any() else [float(np.median(np.abs(T[f"{name}|{lb}|cg"][sel] / cge[sel] - 1))) for T in (A, B)]
                lows = [f"{x:.2e} (median {m:.1e})" for x, m in zip(lows, med)]
            else:
                lows = [f"{x:.2e}" for x in lows]
            print(f"| {name} | {lb} | {f.min():.0f}-{f.max():.0f} Hz | {errs[0][0]:.2e} / {errs[0][1]:.2e} | "
                  f"{errs[1][0]:.2e} / {errs[1][1]:.2e} | {lows[0]} / {lows[1]} |")
    # the independent Legendre model (~1e-5: its c_g is interpolated on 250 wavenumbers)
    from tests.wave_reference import independent_group_velocity
    print("\n| case | mode | before: max rel. diff c_g vs Legendre | after |")
    print("|---|---|---|---|")
    for name in ("cfrp-cmd", "cfrp-0-1MHz", "cfrp-90-200k", "cfrp-low", "al-2MHz"):
        spec, fmax, n, ang, low = CASES[name]
        f = A[f"{name}|f"]
        sel = f <= min(fmax, 1.5e5) if spec == "cfrp" else f <= 6e5
        sel &= f >= 5e3
        for lb in ("A0", "S0", "SH0"):
            if f"{name}|{lb}|cg" not in A.files:
                continue
            try:
                ref = independent_group_velocity(load_specimen(spec).laminate, f[sel], lb, ang)
            except AssertionError:      # below the independent model's lowest wavenumber
                continue
            print(f"| {name} | {lb} | {_rel(A[f'{name}|{lb}|cg'][sel], ref):.2e} | "
                  f"{_rel(B[f'{name}|{lb}|cg'][sel], ref):.2e} |")


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2])
    else:
        compare(sys.argv[2], sys.argv[3])
