"""Published pitch-catch records analysed from a nominal 32 % off (issue 24): Yeum et al. (2011).

Records (real): GitHub chulminy/Lamb_Wave_Mode_Decomposition, commit
18e4cffff92ba112de165df6a1ec35f4ec558a2c, data/exp/180k_<act><sens>_F11 (text, one column of
volts, 5 MHz, 50000 samples; F11 = whole dual PZT actuating and sensing): actuator A (top
face) or C (bottom face, collocated with A) to sensors B (120 mm) and D (420 mm) on the
diagonal of a 1 m x 1 m x 3 mm aluminium plate, a 180 kHz burst whose peak is at sample 5000.
The repository is mirrored with the ``fetch`` tool (``/work/.mirror/...``, git objects) or
read from a clone given as the first argument.

Three runs go through ``labid import`` and ``labid analyze`` (CLI, in process), with the
specimen file bench/import_real/yeum_al_nominal_off.toml (E, G 32 % low) and the rig file
bench/import_real/yeum_rig.toml (what is assumed is written there):

* 'A': actuator A alone (what a lab with one PZT records: S0 and A0 in one record);
* 'S': (A + C) / 2 and 'A': (A - C) / 2, the modes separated by the collocated actuators as
  the authors do (Run_EXPValid.m); analysed with the rig's source as a symmetric /
  antisymmetric pair;
* "S'" and "A'": the same with the other mode's residue removed (engine.waves.pair): the
  actuators leave A0 at -14 dB in S (and S0 at -22 dB in A); the residue ratio r is measured at
  D, where the foreign packet arrives alone, and S - Re(r H[A]) formed at B and D (B and D lie on
  one ray from the pair, so one r holds for both). Nothing of it comes from the nominal.

Each run is analysed from two nominals: E, G 32 % low (yeum_al_nominal_off.toml) and 32 % high
(yeum_al_nominal_high.toml).

Independent estimate (numpy/scipy only, no labid code): per mode record, a 4th-order
Butterworth band-pass (zero phase) of +-20 % around f, the Hilbert envelope, its first peak
above 30 % of the record's envelope maximum at B and at D, c_g = (0.42 - 0.12) / (t_D - t_B),
at f = 135-225 kHz every 15 kHz; on the raw (A +- C) / 2 and on the residue-free records; and
with a +-10 % band-pass at 120-240 kHz every 10 kHz on the residue-free records (a narrower
band follows the curve closer to f; its envelope is longer). The
velocity belongs to the packets' own centre frequency, not to f: on a burst's sloping spectrum
the band-passed packet's power centroid (between the envelope's half-peak points, mean of B
and D) lies up to ~10 kHz nearer the burst's 180 kHz, which on the dispersive A0 is worth
~1 %; labid's points are compared with the estimate interpolated at those centroids.
Reference (not a measurement): the exact Rayleigh-Lamb
c_g of a generic aluminium (E 70 GPa, nu 0.33, 2700 kg/m^3) at f h = 0.45-0.63 MHz mm,
from bench/independent/legendre_safe.py (within 1e-7 of the exact table in ORACLES.md).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_real_pitch_catch.py [CLONE_DIR]
"""
from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import signal

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._machine import machine  # noqa: E402
from bench.independent.legendre_safe import LegendrePlate, branches, layers_of  # noqa: E402
from engine.waves.pair import cancel_residue, residue_ratio  # noqa: E402
from labid.cli.main import main as labid  # noqa: E402

HERE = ROOT / "bench" / "import_real"
MIRROR = Path("/work/.mirror/chulminy+Lamb_Wave_Mode_Decomposition/repo")
COMMIT = "18e4cffff92ba112de165df6a1ec35f4ec558a2c"
FS = 5.0e6
PEAK = 5000                      # the burst's peak (sample), Run_EXPValid.m
PATH = 0.42 - 0.12               # D - B, m
FREQS = (135e3, 150e3, 165e3, 180e3, 195e3, 210e3, 225e3)
BAND = (100e3, 260e3)             # the 180 kHz 5-cycle burst's band, Hz
MAX_SPREAD = 0.05                 # refuse a residue ratio that moves more with its gate


def record(name: str, clone: Path | None) -> np.ndarray:
    """One text record (volts) from a clone or the fetched mirror (git objects)."""
    rel = f"data/exp/180k_{name}_F11"
    if clone is not None:
        return np.loadtxt(clone / rel)
    text = subprocess.run(["git", "--git-dir", str(MIRROR), "show", f"{COMMIT}:{rel}"], check=True,
                          capture_output=True, text=True).stdout
    return np.loadtxt(io.StringIO(text))


def envelope_cg(xb: np.ndarray, xd: np.ndarray, f: float, half: float = 0.2) -> tuple[float, float]:
    """The independent estimate of the module docstring: (c_g m/s, centroid frequency Hz)."""
    sos = signal.butter(4, [(1 - half) * f, (1 + half) * f], "bandpass", fs=FS, output="sos")
    times, cents = [], []
    for x in (xb, xd):
        y = signal.sosfiltfilt(sos, x - np.mean(x[:PEAK - 200]))
        e = np.abs(signal.hilbert(y))
        seg = e[PEAK - 100:]
        pk, _ = signal.find_peaks(seg, height=0.3 * seg.max())
        k = int(pk[0])
        la, lb, lc = np.log(seg[k - 1:k + 2])
        times.append((k + 0.5 * (la - lc) / (la - 2 * lb + lc)) / FS)
        lo, hi = k, k
        while lo > 0 and seg[lo - 1] > 0.5 * seg[k]:
            lo -= 1
        while hi < seg.size - 1 and seg[hi + 1] > 0.5 * seg[k]:
            hi += 1
        g = y[PEAK - 100 + lo:PEAK - 100 + hi + 1] * signal.windows.tukey(hi - lo + 1, 0.5)
        p = np.abs(np.fft.rfft(g, 1 << 16)) ** 2
        fr = np.fft.rfftfreq(1 << 16, 1 / FS)
        cents.append(float(np.sum(fr * p) / np.sum(p)))
    return PATH / (times[1] - times[0]), float(np.mean(cents))


def at_centroids(curve: list, fw: np.ndarray) -> np.ndarray:
    """The envelope estimate [(c_g, f_centroid), ...] interpolated at ``fw`` (NaN outside)."""
    fc, v = np.array([c[1] for c in curve]), np.array([c[0] for c in curve])
    o = np.argsort(fc)
    return np.interp(fw, fc[o], v[o], left=np.nan, right=np.nan)


def reference(f: np.ndarray) -> dict:
    """Rayleigh-Lamb c_g of a generic aluminium 3 mm (independent model; m/s)."""
    E, nu, rho = 70e9, 0.33, 2700.0
    G = E / (2 * (1 + nu))
    c = dict(E1=E, E2=E, E3=E, nu12=nu, nu13=nu, nu23=nu, G12=G, G13=G, G23=G, density=rho)
    br = branches(LegendrePlate(layers_of([(c, 0.0, 3e-3)]), 6), float(np.max(f)) * 1.05)
    return {"A0": br.at(0, 2 * np.pi * f)[1], "S0": br.at(2, 2 * np.pi * f)[1]}


def write_csv(path: Path, name: str, x: np.ndarray) -> None:
    path.write_text(f"{name}\n" + "\n".join(f"{v:.8g}" for v in x) + "\n")


def cli(argv: list[str]) -> tuple[int, str, float, float]:
    out, err = io.StringIO(), io.StringIO()
    w, c = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = labid(argv)
    return code, out.getvalue() + err.getvalue(), time.perf_counter() - w, time.process_time() - c


def main(argv) -> None:
    print(f"machine: {machine()}")
    clone = Path(argv[0]) if argv else None
    if clone is None and not MIRROR.exists():
        print(f"records not found: fetch github:chulminy/Lamb_Wave_Mode_Decomposition (mirror {MIRROR}) "
              "or give a clone's path")
        return
    rec = {k: record(k, clone) for k in ("CH0CH1", "CH0CH2", "CH3CH1", "CH3CH2")}
    sym = ((rec["CH0CH1"] + rec["CH3CH1"]) / 2, (rec["CH0CH2"] + rec["CH3CH2"]) / 2)
    anti = ((rec["CH0CH1"] - rec["CH3CH1"]) / 2, (rec["CH0CH2"] - rec["CH3CH2"]) / 2)
    t0 = PEAK / FS
    res = {"A0 in S": residue_ratio(sym[1], anti[1], FS, BAND, after_s=t0),
           "S0 in A": residue_ratio(anti[1], sym[1], FS, BAND, after_s=t0)}
    print("\nresidue of the other mode, measured at D (where its packet arrives alone):")
    for k, r in res.items():
        print(f"  {k}: r = {abs(r.ratio):.3f} at {np.degrees(np.angle(r.ratio)):.1f} deg ({r.level_db:.1f} dB), gate "
              f"{(r.gate_s[0] - t0) * 1e6:.1f}-{(r.gate_s[1] - t0) * 1e6:.1f} us, "
              f"moves {100 * r.spread:.1f} % with the gate"
              + ("" if r.spread <= MAX_SPREAD else "  REFUSED (not alone in the gate)"))
    runs = {"A alone": (rec["CH0CH1"], rec["CH0CH2"], None),
            "S: (A + C) / 2": (*sym, "symmetric"),
            "A: (A - C) / 2": (*anti, "antisymmetric")}
    if res["A0 in S"].spread <= MAX_SPREAD:
        r = res["A0 in S"].ratio
        runs["S': A0 residue removed"] = (cancel_residue(sym[0], anti[0], r), cancel_residue(sym[1], anti[1], r),
                                          "symmetric")
    if res["S0 in A"].spread <= MAX_SPREAD:
        r = res["S0 in A"].ratio
        runs["A': S0 residue removed"] = (cancel_residue(anti[0], sym[0], r), cancel_residue(anti[1], sym[1], r),
                                          "antisymmetric")
    f = np.array(FREQS)
    ref = reference(f)
    f10 = np.arange(120e3, 245e3, 10e3)
    src = {"S0": ("S: (A + C) / 2", "S': A0 residue removed"), "A0": ("A: (A - C) / 2", "A': S0 residue removed")}
    est: dict = {}
    for m, (raw, cleaned) in src.items():
        est[m] = {"raw +-20 %": [envelope_cg(*runs[raw][:2], fi) for fi in f]}
        if cleaned in runs:
            est[m]["clean +-20 %"] = [envelope_cg(*runs[cleaned][:2], fi) for fi in f]
            est[m]["clean +-10 %"] = [envelope_cg(*runs[cleaned][:2], fi, 0.1) for fi in f10]
    print("\nindependent envelope-peak estimate (Butterworth band-pass around f, Hilbert), B -> D, "
          "m/s (packet centroid kHz); raw = (A +- C) / 2, clean = residue removed:")
    for m in ("S0", "A0"):
        for k, curve in est[m].items():
            print(f"  {m} {k}: " + ", ".join(f"{v:.0f} ({c / 1e3:.0f})" for v, c in curve))
        print(f"  {m} Rayleigh-Lamb, generic Al, at "
              + ", ".join(f"{fi / 1e3:.0f} kHz {v:.0f}" for fi, v in zip(f, ref[m])))
    rig_text = (HERE / "yeum_rig.toml").read_text()
    for spec in ("yeum_al_nominal_off.toml", "yeum_al_nominal_high.toml"):
        print(f"\n=== nominal {spec}")
        with tempfile.TemporaryDirectory() as tmp:
            analyse(Path(tmp), runs, rig_text, HERE / spec, est)


def analyse(d: Path, runs: dict, rig_text: str, spec: Path, est: dict) -> None:
    """labid import + analyze of each run; its points against the envelope estimate."""
    for j, (label, (xb, xd, pair)) in enumerate(runs.items()):
        rig = d / "rig.toml"
        rig.write_text(rig_text if pair is None else rig_text.replace(
            'diameter_m = 0.010\n', f'diameter_m = 0.010\npair = "{pair}"\n'))
        write_csv(d / "B.csv", "B", xb)
        write_csv(d / "D.csv", "D", xd)
        run, feats = d / f"run_{j}.h5", d / f"f_{j}.json"
        code, out, wi, ci = cli(["import", str(d / "B.csv"), str(d / "D.csv"), "--rig", str(rig), "--specimen",
                                 str(spec), "--out", str(run), "--rate", "5e6",
                                 "--pretrigger", "4931", "--units", "B=V,D=V", "--quiet"])
        if code:
            print(f"\n{label}: import failed ({code}): {out.strip()[-300:]}")
            continue
        code, out, wa, ca = cli(["analyze", str(run), "--out", str(feats)])
        print(f"\n{label}: import {wi:.1f} s wall / {ci:.1f} s CPU, analyze {wa:.1f} s wall / {ca:.1f} s CPU "
              f"(exit {code})")
        for ln in out.splitlines():
            if ln.startswith(("warning", "A0", "S0", "dropped", "features")):
                print("  " + ln[:230])
        if code:
            continue
        doc = json.loads(feats.read_text())
        for w in doc.get("waves", []):
            fw, v, s = (np.array(w[k]) for k in ("frequency_hz", "group_velocity_m_s", "sigma_m_s"))
            rl = reference(fw)[w["mode"]]
            near = {k: at_centroids(c, fw) for k, c in est[w["mode"]].items()}
            print(f"  {w['mode']}: {len(fw)} points " + "; ".join(
                f"{fi / 1e3:.0f} kHz {vi:.0f} +- {si:.0f}" + "".join(
                    f" ({k} {e[i]:.0f}, {100 * (vi / e[i] - 1):+.1f} %)" for k, e in near.items() if np.isfinite(e[i]))
                + f" [R-L {100 * (vi / ri - 1):+.1f} %]" for i, (fi, vi, si, ri) in enumerate(zip(fw, v, s, rl))))


if __name__ == "__main__":
    main(sys.argv[1:])
