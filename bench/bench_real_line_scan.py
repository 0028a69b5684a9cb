"""A second published record set (issue 24): a line scan on an aluminium plate.

Records (real): GitHub eriknbd/Lamb_wave_analisis, commit a137a37a041fd01d747478ae596fd5a2031f289e,
all_data/test_Al_tren_2105.mat: per burst frequency (250, 340, 500, 640 kHz) a matrix whose
column 0 is the time (s) and columns 1-35 the records at 35 positions along one line (0, 2.5 .. 35
mm every 2.5 mm, 35.5 .. 45 mm every 0.5 mm: the repository's notebook). The plate: aluminium,
E 68.9 GPa, nu 0.33, 2700 kg/m^3 (the repository's Aluminium.py), 1 mm by its file names (1.5 mm
in Aluminium.py's example). Not stated: the source, its distance, the trigger.

Independent estimate (numpy/scipy only): per frequency, a 4th-order Butterworth band-pass of
+-20 %, the Hilbert envelope's first peak above 30 % of its maximum (parabola through log), at
all 35 positions, and a straight-line fit of time against position: c_g = 1 / slope (the line
scan's own estimate, 45 mm of lever, no source time needed). Reference (not a measurement):
Rayleigh-Lamb A0 / S0 of that aluminium at 1.0 and 1.5 mm (bench/independent/legendre_safe.py).

labid: each burst's records at 0 and 45 mm as a pitch-catch pair (rig
bench/import_real/erik_line_rig.toml says what is assumed; its burst frequency is set to the
file's, and its rate: 41.7 MHz for the 250 kHz file, 62.5 MHz for the others), ``labid import`` + ``labid analyze`` from E, G 32 % low and 32 % high
(bench/import_real/erik_al_nominal_low|high.toml); each point against the line estimate
interpolated (linearly in f between the bursts' centres) and against the same two positions'
envelope peaks (numpy/scipy only).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_real_line_scan.py [--pairs]
(the repository is mirrored with the ``fetch`` tool: github:eriknbd/Lamb_wave_analisis).
``--pairs``: labid takes two sensors per direction (the nearest and the farthest); the other
positions of the line are given to it as other pairs (``PAIRS``, mm), each analysed alone, every
point against the same estimates: do the positions agree, and does another pair hold more points?
Each analysis also prints the crosstalk coupling bounds it used per sensor distance
(``engine.wavefeatures.crosstalk``: min-max over shots and wavelets; session 29 moved its noise
std to the picks' median-block estimate, ``engine.wavefeatures.noise``).
"""
from __future__ import annotations

import io
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.io import loadmat

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._machine import machine  # noqa: E402
from bench.bench_real_pitch_catch import cli, write_csv  # noqa: E402
from bench.independent.legendre_safe import LegendrePlate, branches, layers_of  # noqa: E402
from engine.wavefeatures import crosstalk  # noqa: E402

#: the crosstalk coupling bounds of the current analysis: sensor distance (m) -> [c, ...]
BOUNDS: dict = {}


def _traced_bound(real):
    """``crosstalk._bound`` that also notes the coupling bound c per sensor distance."""
    def bound(d, x, s, *rest):
        out = real(d, x, s, *rest)
        BOUNDS.setdefault(round(s.distance_m, 4), []).append(out[1])
        return out
    return bound

HERE = ROOT / "bench" / "import_real"
MIRROR = Path("/work/.mirror/eriknbd+Lamb_wave_analisis/repo")
COMMIT = "a137a37a041fd01d747478ae596fd5a2031f289e"
FILE = "all_data/test_Al_tren_2105.mat"
PAIRS = ((0.0, 45.0), (0.0, 22.5), (22.5, 45.0), (10.0, 40.0), (5.0, 45.0))     # mm, for --pairs
POS = np.array([0.0] + list(np.arange(2.5, 35.01, 2.5)) + list(np.arange(35.5, 45.01, 0.5))) * 1e-3


def line_cg(a: np.ndarray, f0: float, half: float = 0.2) -> tuple[float, float]:
    """(c_g m/s, rms residual of the line s) from the 35 envelope peaks (module docstring);
    band-pass f0 (1 +- half)."""
    t = a[:, 0]
    fs = 1.0 / float(np.median(np.diff(t)))
    sos = signal.butter(4, [(1 - half) * f0, (1 + half) * f0], "bandpass", fs=fs, output="sos")
    peaks = []
    for j in range(1, a.shape[1]):
        e = np.abs(signal.hilbert(signal.sosfiltfilt(sos, a[:, j] - np.mean(a[:, j]))))
        k = int(signal.find_peaks(e, height=0.3 * e.max())[0][0])
        la, lb, lc = np.log(e[k - 1:k + 2])
        peaks.append(t[k] + 0.5 * (la - lc) / (la - 2 * lb + lc) / fs)
    A = np.vstack([POS, np.ones(POS.size)]).T
    c = np.linalg.lstsq(A, np.array(peaks), rcond=None)[0]
    return 1.0 / c[0], float(np.std(np.array(peaks) - A @ c))


def reference(h: float, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    E, nu, rho = 68.9e9, 0.33, 2700.0
    G = E / (2 * (1 + nu))
    c = dict(E1=E, E2=E, E3=E, nu12=nu, nu13=nu, nu23=nu, G12=G, G13=G, G23=G, density=rho)
    br = branches(LegendrePlate(layers_of([(c, 0.0, h)]), 6), float(np.max(f)) * 1.05)
    return br.at(0, 2 * np.pi * f)[1], br.at(2, 2 * np.pi * f)[1]


def pair_cg(a: np.ndarray, f0: float) -> float:
    """c_g (m/s) from the envelope peaks at 0 and 45 mm only (the two records labid is given)."""
    t = a[:, 0]
    fs = 1.0 / float(np.median(np.diff(t)))
    sos = signal.butter(4, [0.8 * f0, 1.2 * f0], "bandpass", fs=fs, output="sos")
    tp = []
    for j in (1, 35):
        e = np.abs(signal.hilbert(signal.sosfiltfilt(sos, a[:, j] - np.mean(a[:, j]))))
        k = int(signal.find_peaks(e, height=0.3 * e.max())[0][0])
        la, lb, lc = np.log(e[k - 1:k + 2])
        tp.append(t[k] + 0.5 * (la - lc) / (la - 2 * lb + lc) / fs)
    return 0.045 / (tp[1] - tp[0])


def _column(mm: float) -> int:
    """The matrix column (1-35) of the position ``mm`` along the line."""
    return 1 + int(np.argmin(np.abs(POS - mm * 1e-3)))


def _rig_for(rig_text: str, f0: float, fs: float, n: int, pair: tuple[float, float]) -> str:
    """The rig with the burst's centre frequency, rate and samples, and P00 / P45 moved to the
    pair's positions (mm; distances from the assumed source 60 mm before position 0)."""
    txt = (rig_text.replace("frequency_hz = 500.0e3", f"frequency_hz = {f0:.1f}")
           .replace("rate_hz = 62.5e6", f"rate_hz = {fs:.6g}").replace("samples = 4026", f"samples = {n}"))
    if pair != (0.0, 45.0):
        a, b = (0.06 + p * 1e-3 for p in pair)
        txt = (txt.replace("x = 0.46\n", f"x = {0.40 + a:.4f}\n").replace("distance_m = 0.06\n", f"distance_m = {a:.4f}\n")
               .replace("x = 0.505\n", f"x = {0.40 + b:.4f}\n").replace("distance_m = 0.105\n", f"distance_m = {b:.4f}\n"))
    return txt


def main() -> None:
    print(f"machine: {machine()}")
    crosstalk._bound = _traced_bound(crosstalk._bound)
    if not MIRROR.exists():
        print(f"records not found: fetch github:eriknbd/Lamb_wave_analisis (mirror {MIRROR})")
        return
    raw = subprocess.run(["git", "--git-dir", str(MIRROR), "show", f"{COMMIT}:{FILE}"], check=True,
                         capture_output=True).stdout
    mats = loadmat(io.BytesIO(raw))
    print("\nindependent estimates, m/s: 35-position line (0-45 mm) and the 0 / 45 mm pair; "
          "Rayleigh-Lamb A0 / S0 at 1.0 | 1.5 mm:")
    keys = ("fss_0250kHz", "fss_0340kHz", "fss_0500kHz", "fss_0640kHz")
    est, pair_est = {}, {}
    for key in keys:
        f0 = float(key[4:8]) * 1e3
        v, rms = line_cg(mats[key], f0)
        est[f0], pair_est[f0] = v, pair_cg(mats[key], f0)
        a1, s1 = reference(1.0e-3, np.array([f0]))
        a15, s15 = reference(1.5e-3, np.array([f0]))
        print(f"  {f0 / 1e3:.0f} kHz: line {v:.0f} (rms {rms * 1e9:.0f} ns), pair {pair_est[f0]:.0f}; A0 {a1[0]:.0f} | "
              f"{a15[0]:.0f}, S0 {s1[0]:.0f} | {s15[0]:.0f}")
    fl = np.array(sorted(est))
    rig_text = (HERE / "erik_line_rig.toml").read_text()
    rows = []
    pairs = PAIRS if "--pairs" in sys.argv[1:] else PAIRS[:1]
    for key, pair in ((k, p) for k in keys for p in pairs):
        f0 = float(key[4:8]) * 1e3
        a = mats[key]
        for spec in ("erik_al_nominal_low.toml", "erik_al_nominal_high.toml"):
            with tempfile.TemporaryDirectory() as tmp:
                d = Path(tmp)
                rig = d / "rig.toml"        # the burst's own centre frequency (the file says 500 kHz)
                fs = 1.0 / float(np.median(np.diff(a[:, 0])))    # 41.7 MHz for 250 kHz, else 62.5
                rig.write_text(_rig_for(rig_text, f0, fs, a.shape[0], pair))
                write_csv(d / "P00.csv", "P00", a[:, _column(pair[0])])
                write_csv(d / "P45.csv", "P45", a[:, _column(pair[1])])
                if len(pairs) > 1:
                    print(f"\npositions {pair[0]:g} / {pair[1]:g} mm:", end="")
                code, out, wi, ci = cli(["import", str(d / "P00.csv"), str(d / "P45.csv"), "--rig", str(rig),
                                         "--specimen", str(HERE / spec), "--out", str(d / "run.h5"), "--rate",
                                         f"{fs:.6g}", "--pretrigger", "0", "--units", "P00=V,P45=V", "--quiet"])
                if code:
                    print(f"\n{f0 / 1e3:.0f} kHz {spec}: import failed ({code}): {out.strip()[-300:]}")
                    continue
                BOUNDS.clear()
                code, out, wa, ca = cli(["analyze", str(d / "run.h5"), "--out", str(d / "f.json")])
                print(f"\n{f0 / 1e3:.0f} kHz, {spec}: analyze {wa:.1f} s wall / {ca:.1f} s CPU (exit {code})")
                print("  crosstalk coupling bound: " + ", ".join(
                    f"{r * 1e3:.0f} mm {min(c):.2g}-{max(c):.2g}" for r, c in sorted(BOUNDS.items())))
                if "set --wave-band " in out:       # as a user would: the band the records hold
                    wb = out.split("set --wave-band ")[1].split()[0].rstrip(".;,")
                    code, out, wa, ca = cli(["analyze", str(d / "run.h5"), "--out", str(d / "f.json"),
                                             "--wave-band", wb])
                    lo, hi = (float(x) for x in wb.split(","))
                    v, rms = line_cg(a, 0.5 * (lo + hi), (hi - lo) / (hi + lo))
                    print(f"  again with --wave-band {wb}: analyze {wa:.1f} s wall / {ca:.1f} s CPU (exit {code}); "
                          f"line estimate in that band {v:.0f} m/s (rms {rms * 1e9:.0f} ns)")
                for ln in out.splitlines():
                    if ln.startswith(("warning", "dropped", "features")):
                        print("  " + ln[:200])
                if code:
                    continue
                doc = json.loads((d / "f.json").read_text())
                for n in doc.get("analysis", {}).get("notes", []):
                    if "one packet in the records" in n or "packet in the records where" in n:
                        print("  note: " + n[:260])
                for w in doc.get("waves", []):
                    for fi, vi, si in zip(w["frequency_hz"], w["group_velocity_m_s"], w["sigma_m_s"]):
                        ref = float(np.interp(fi, fl, [est[f] for f in fl]))
                        rows.append((f0, spec, w["mode"], fi, vi, si, ref, pair_est[f0], pair))
                        print(f"  {w['mode']} {fi / 1e3:.0f} kHz {vi:.0f} +- {si:.0f}: {100 * (vi / ref - 1):+.1f} % of the "
                              f"line estimate ({ref:.0f}, interpolated), {100 * (vi / pair_est[f0] - 1):+.1f} % of the "
                              f"0 / 45 mm pair's ({pair_est[f0]:.0f})")
    print("\nsummary: positions mm | burst | nominal | mode | f kHz | labid m/s +- sigma | vs line | vs 0/45 pair | "
          "|err| / sigma (line)")
    for f0, spec, m, fi, vi, si, ref, pr, pp in rows:
        print(f"  {pp[0]:g}/{pp[1]:g} | {f0 / 1e3:.0f} | {spec.split('_')[-1][:-5]} | {m} | {fi / 1e3:.0f} | {vi:.0f} +- {si:.0f} | "
              f"{100 * (vi / ref - 1):+.1f} % | {100 * (vi / pr - 1):+.1f} % | {abs(vi - ref) / si:.1f}")


if __name__ == "__main__":
    main()
