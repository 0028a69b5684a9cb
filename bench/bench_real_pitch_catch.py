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
  antisymmetric pair.

Independent estimate (numpy/scipy only, no labid code): per mode record, a 4th-order
Butterworth band-pass (zero phase) of +-20 % around f, the Hilbert envelope, its first peak
above 30 % of the record's envelope maximum at B and at D, c_g = (0.42 - 0.12) / (t_D - t_B),
at f = 150, 165, 180, 195, 210 kHz. Reference (not a measurement): the exact Rayleigh-Lamb
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
from labid.cli.main import main as labid  # noqa: E402

HERE = ROOT / "bench" / "import_real"
MIRROR = Path("/work/.mirror/chulminy+Lamb_Wave_Mode_Decomposition/repo")
COMMIT = "18e4cffff92ba112de165df6a1ec35f4ec558a2c"
FS = 5.0e6
PEAK = 5000                      # the burst's peak (sample), Run_EXPValid.m
PATH = 0.42 - 0.12               # D - B, m
FREQS = (150e3, 165e3, 180e3, 195e3, 210e3)


def record(name: str, clone: Path | None) -> np.ndarray:
    """One text record (volts) from a clone or the fetched mirror (git objects)."""
    rel = f"data/exp/180k_{name}_F11"
    if clone is not None:
        return np.loadtxt(clone / rel)
    text = subprocess.run(["git", "--git-dir", str(MIRROR), "show", f"{COMMIT}:{rel}"], check=True,
                          capture_output=True, text=True).stdout
    return np.loadtxt(io.StringIO(text))


def envelope_cg(xb: np.ndarray, xd: np.ndarray, f: float) -> float:
    """The independent estimate of the module docstring (m/s)."""
    sos = signal.butter(4, [0.8 * f, 1.2 * f], "bandpass", fs=FS, output="sos")
    times = []
    for x in (xb, xd):
        y = signal.sosfiltfilt(sos, x - np.mean(x[:PEAK - 200]))
        e = np.abs(signal.hilbert(y))
        seg = e[PEAK - 100:]
        pk, _ = signal.find_peaks(seg, height=0.3 * seg.max())
        k = int(pk[0])
        la, lb, lc = np.log(seg[k - 1:k + 2])
        times.append((k + 0.5 * (la - lc) / (la - 2 * lb + lc)) / FS)
    return PATH / (times[1] - times[0])


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
    runs = {"A alone": (rec["CH0CH1"], rec["CH0CH2"], None),
            "S: (A + C) / 2": ((rec["CH0CH1"] + rec["CH3CH1"]) / 2, (rec["CH0CH2"] + rec["CH3CH2"]) / 2, "symmetric"),
            "A: (A - C) / 2": ((rec["CH0CH1"] - rec["CH3CH1"]) / 2, (rec["CH0CH2"] - rec["CH3CH2"]) / 2,
                               "antisymmetric")}
    f = np.array(FREQS)
    ref = reference(f)
    indep = {"S0": [envelope_cg(*runs["S: (A + C) / 2"][:2], fi) for fi in f],
             "A0": [envelope_cg(*runs["A: (A - C) / 2"][:2], fi) for fi in f]}
    print("\nindependent envelope-peak estimate (band-pass +-20 %, Hilbert), B -> D, m/s:")
    for m in ("S0", "A0"):
        print(f"  {m}: " + ", ".join(f"{fi / 1e3:.0f} kHz {v:.0f}" for fi, v in zip(f, indep[m]))
              + "   (Rayleigh-Lamb, generic Al: " + ", ".join(f"{v:.0f}" for v in ref[m]) + ")")
    rig_text = (HERE / "yeum_rig.toml").read_text()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for j, (label, (xb, xd, pair)) in enumerate(runs.items()):
            rig = d / "rig.toml"
            rig.write_text(rig_text if pair is None else rig_text.replace(
                'diameter_m = 0.010\n', f'diameter_m = 0.010\npair = "{pair}"\n'))
            write_csv(d / "B.csv", "B", xb)
            write_csv(d / "D.csv", "D", xd)
            run, feats = d / f"run_{j}.h5", d / f"f_{j}.json"
            code, out, wi, ci = cli(["import", str(d / "B.csv"), str(d / "D.csv"), "--rig", str(rig), "--specimen",
                                     str(HERE / "yeum_al_nominal_off.toml"), "--out", str(run), "--rate", "5e6",
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
                mine = np.interp(fw, f, indep[w["mode"]], left=np.nan, right=np.nan)
                rl = reference(fw)[w["mode"]]
                print(f"  {w['mode']}: " + "; ".join(
                    f"{fi / 1e3:.0f} kHz {vi:.0f} +- {si:.0f}" + (f" (envelope {mi:.0f}, {100 * (vi / mi - 1):+.1f} %)"
                                                              if np.isfinite(mi) else "")
                    + f" [R-L {100 * (vi / ri - 1):+.1f} %]" for fi, vi, si, mi, ri in zip(fw, v, s, mine, rl)))


if __name__ == "__main__":
    main(sys.argv[1:])
