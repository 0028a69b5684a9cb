"""The wave records' noise estimate against the truth (issue 24, session 30: engine.wavefeatures.noise).

``noise_level(x, pre)`` (the time estimate: the quieter of the pre-trigger and the last quarter, by
the median 64-sample block std) and ``noise_level(x, pre, fs)`` (the same, replaced by the white
level of the scalogram rows over 0.2-0.45 x the rate when it reads over 1.2 x that and those rows
are white), on:
- numpy records: 1 mV white noise under a 15-150 kHz coda and a quasi-static swell filling the whole
  record (with a pre-trigger and without), plus broadband clicks; noise low-passed at 0.15 fs;
- independent records (bench/independent/legendre_safe.py through the rig's chain, as
  bench_unknown_plate.py "independent") of bench rig cfrp_pencil_2dir_s0 (pencil breaks triggered on
  the 20 cm MFC), files -40 % / +40 %: truth = the rig's noise_v and its ADC step, / sqrt(shots) for
  a group's mean; records made here (24 breaks, ~1 min) or read with --recs DIR
  (recs_s0_<soft|stiff>_<seed>.pkl, a list of records);
- real records: eriknbd/Lamb_wave_analisis @ a137a37a (all_data/test_Al_tren_2105.mat, no pre-trigger:
  truth = the median block std of the 45 mm record's samples before its first arrival, > 900) and
  Yeum et al. (chulminy/Lamb_Wave_Mode_Decomposition @ 18e4cffff, 4931 pre-trigger samples).
Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_noise_estimate.py [--recs DIR] [--seeds 0,1,2]
"""
from __future__ import annotations

import io
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.io import loadmat

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._machine import machine  # noqa: E402
from engine.wavefeatures.noise import noise_level, white_level  # noqa: E402

FS, N, PRE, STD = 2e6, 4096, 400, 1e-3


def _coda(rng):
    X = np.fft.rfft(rng.standard_normal(N))
    f = np.fft.rfftfreq(N, 1 / FS)
    X[(f < 15e3) | (f > 150e3)] = 0
    c = np.fft.irfft(X, N)
    t = np.arange(N) / FS
    return 20e-3 / np.std(c) * c * np.exp(-t / 4e-3) + 50e-3 * np.exp(-t / 1e-3)


def numpy_records(seeds=range(20)) -> None:
    print("\nnumpy (x the true 1 mV): min-max over", len(seeds), "seeds")
    t = np.arange(N)
    for label, pre, clicks in (("coda over the record, pre-trigger", PRE, 0), ("same, no pre-trigger", 0, 0),
                               ("coda + 4 broadband clicks", PRE, 4), ("coda + 8 broadband clicks", PRE, 8)):
        old, new = [], []
        for s in seeds:
            rng = np.random.default_rng(s)
            x = STD * rng.standard_normal(N) + _coda(rng)
            for k0 in rng.choice(np.arange(100, N - 100), clicks, replace=False):
                x = x + 0.05 * np.exp(-0.5 * ((t - k0) / 0.6) ** 2)
            old.append(noise_level(x, pre)[0] / STD)
            new.append(noise_level(x, pre, FS)[0] / STD)
        print(f"  {label}: time estimate {min(old):.2f}-{max(old):.2f}, now {min(new):.3f}-{max(new):.3f} "
              f"(mean {np.mean(new):.3f})")
    sos = signal.butter(4, 0.3, output="sos")
    got = []
    for s in seeds:
        v = signal.sosfilt(sos, np.random.default_rng(s).standard_normal(N + 500))[500:]
        v *= STD / np.std(v)
        got.append((noise_level(v, PRE)[0] / STD, noise_level(v, PRE, FS)[0] / STD, white_level(v, FS)))
    print(f"  noise low-passed at 0.15 fs: white level None on {sum(g[2] is None for g in got)} / {len(got)}; "
          f"estimate = time estimate on {sum(abs(g[0] - g[1]) < 1e-12 for g in got)} / {len(got)} "
          f"({min(g[1] for g in got):.2f}-{max(g[1] for g in got):.2f})")


def simulated(recs_dir: Path | None, seeds) -> None:
    from dataclasses import replace

    from bench.bench_unknown_plate import HERE, records
    from labid.inputs.rig import rig_from_text
    from labid.inputs.specimen import load_specimen

    base = rig_from_text((HERE / "rigs" / "cfrp_pencil_2dir_s0.toml").read_text(), "cfrp_pencil_2dir_s0")
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    dev = base.device("wave")
    print(f"\nindependent records, bench rig cfrp_pencil_2dir_s0 (x the truth; truth per shot "
          f"{np.hypot(2e-4, 10.0 / 2 ** 16 / np.sqrt(12)) * 1e3:.3f} mV: noise_v 0.2 mV and the ADC step / sqrt 12)")
    for fileoff, scale in (("soft", 1 / 0.6), ("stiff", 1 / 1.4)):
        for seed in seeds:
            pk = recs_dir / f"recs_s0_{fileoff}_{seed}.pkl" if recs_dir else None
            if pk is not None and pk.exists():
                recs = pickle.load(open(pk, "rb"))
            else:
                rig = replace(base, sim=replace(base.sim, truth_scale=(("*", scale),)))
                recs = records(rig, large, 24, seed, "independent")
            fs, pre = recs[0].timing.rate_hz, recs[0].timing.pretrigger
            truth = np.hypot(2e-4, 2 * 5.0 / 2 ** 16 / np.sqrt(12))
            row = []
            for ch in [c.name for c in dev.channels]:
                for k in (1, 2):
                    x = np.mean([r.scaled(ch) for r in recs[:k]], axis=0)
                    t = truth / np.sqrt(k)
                    row.append(f"{ch}/{k}: {noise_level(x, pre)[0] / t:.2f} -> {noise_level(x, pre, fs)[0] / t:.2f}")
            print(f"  {fileoff} seed {seed} (one shot / a pair's mean: time estimate -> now): " + ", ".join(row))


def real() -> None:
    mirror = Path("/work/.mirror/eriknbd+Lamb_wave_analisis/repo")
    if mirror.exists():
        raw = subprocess.run(["git", "--git-dir", str(mirror), "show",
                              "a137a37a041fd01d747478ae596fd5a2031f289e:all_data/test_Al_tren_2105.mat"],
                             check=True, capture_output=True).stdout
        mats = loadmat(io.BytesIO(raw))
        print("\nreal, eriknbd (no pre-trigger), mV: truth = the 45 mm record's first 900 samples' median block std")
        for key in ("fss_0250kHz", "fss_0340kHz", "fss_0500kHz", "fss_0640kHz"):
            a = mats[key]
            fs = 1.0 / float(np.median(np.diff(a[:, 0])))
            truth = noise_level(a[:900, 35], 900)[0]
            cells = []
            for col, mm in ((1, 0), (35, 45)):
                x = a[:, col]
                w = white_level(x, fs)
                cells.append(f"{mm} mm: tail {noise_level(x, 0)[0] * 1e3:.3f} -> {noise_level(x, 0, fs)[0] * 1e3:.3f} "
                             f"(white level {'not white' if w is None else format(w * 1e3, '.3f')})")
            print(f"  {key}: truth {truth * 1e3:.3f}; " + "; ".join(cells))
    else:
        print("eriknbd records not found: fetch github:eriknbd/Lamb_wave_analisis")
    from bench.bench_real_pitch_catch import MIRROR, record
    if MIRROR.exists():
        print("\nreal, Yeum et al. (pre-trigger 4931 samples, 5 MHz), mV:")
        for name in ("CH0CH1", "CH0CH2", "CH3CH1", "CH3CH2"):
            x = record(name, None)
            w = white_level(x, 5e6)
            print(f"  {name}: time estimate {noise_level(x, 4931)[0] * 1e3:.4f} -> {noise_level(x, 4931, 5e6)[0] * 1e3:.4f} "
                  f"(white level {'not white' if w is None else format(w * 1e3, '.4f')}; the pre-trigger's plain std "
                  f"{np.std(x[:3944]) * 1e3:.4f})")


def main(argv) -> None:
    print(f"machine: {machine()}")
    recs_dir = Path(argv[argv.index("--recs") + 1]) if "--recs" in argv else None
    seeds = [int(s) for s in argv[argv.index("--seeds") + 1].split(",")] if "--seeds" in argv else [0, 1, 2]
    numpy_records()
    real()
    simulated(recs_dir, seeds)


if __name__ == "__main__":
    main(sys.argv[1:])
