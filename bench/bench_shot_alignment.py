"""How far apart a run's shots are on their trigger, and what averaging them keeps (issue 24,
session 29: pencil breaks averaged without alignment cancel their own packet).

Per case: every shot's lag behind shot 0 on the reference channel (``shots.align_channel``: the
trigger sensor), measured by ``shots.shot_lags`` in the analysis band, against the simulator's
truth (``meta['sim_onset_s']``: the source onset relative to the trigger sample; a record whose
onset is d later has its content d later); then, for the groups ``stack_shots`` forms, the share
of the packet their mean keeps at a frequency, |sum_k X_k(f)| / sum_k |X_k(f)| (1 = nothing
cancelled; X: the DFT of the record less its mean, tapered over its first and last tenth: a
pencil break's quasi-static strain runs past the record's ends and its edge steps, which do not
move with the trigger, would dominate an untapered DFT), unaligned and aligned, on the
reference and on the far sensor.

Cases (records made once, or read from a pickle of ``bench_unknown_plate.records``):
  s0      bench/rigs/cfrp_pencil_2dir_s0.toml, 24 face breaks, independent records
          (bench/independent/legendre_safe.py), files -40 % (soft) and +40 % (stiff), seeds 0-2
  sweep   bench/rigs/cfrp_pzt_sweep_2dir_far.toml, 80 shots (16 per burst), independent, soft,
          seed 0: triggered on the drive (exc), so not aligned; lags per burst on x1 vs exc
  default the built-in rig (pencil, MFCs 5 / 20 cm, trigger on mfc1) on the built-in CFRP, simulated
          records: 3 shots (the demo's) and 100 (bench_wave_cost.py's, plate 0.714 x the file)

Run: OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_shot_alignment.py [s0] [sweep] [default]
"""
from __future__ import annotations

import pickle
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from bench.bench_unknown_plate import HERE, records  # noqa: E402
from engine.wavefeatures.shots import MAX_CURVES, align_shots, shot_lags, stack_shots  # noqa: E402
from labid.inputs.rig import read_rig_text, rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402

PICKLES = Path("/tmp/h63")


def _rig(path: str, scale: float | None):
    rig = rig_from_text((HERE / "rigs" / path).read_text(), f"bench/rigs/{path}") if path.endswith(".toml") \
        else rig_from_text(read_rig_text(path)[0], f"builtin:{path}")
    return rig if scale is None else replace(rig, sim=replace(rig.sim, truth_scale=(("*", scale),)))


def _recs(tag: str, make):
    pk = PICKLES / f"recs_{tag}.pkl"
    if pk.exists():
        return pickle.load(open(pk, "rb"))
    recs = make()
    PICKLES.mkdir(exist_ok=True)
    pickle.dump(recs, open(pk, "wb"))
    return recs


def kept(shots, ch: str, size: int, f: float, fs: float) -> np.ndarray:
    """Per group of ``size`` consecutive shots: |sum X_k(f)| / sum |X_k(f)| on channel ``ch``."""
    n = shots[0][ch].size
    t = np.arange(n) / fs
    m = n // 10                    # the records tapered over their first and last tenth, as shot_lags
    taper = np.ones(n)
    taper[:m] = taper[-m:][::-1] = np.sin(0.5 * np.pi * (np.arange(m) + 0.5) / m) ** 2
    X = np.array([np.sum((s[ch] - s[ch].mean()) * taper * np.exp(-2j * np.pi * f * t)) for s in shots])
    k = len(shots) // size
    X = X[:k * size].reshape(k, size)
    return np.abs(X.sum(axis=1)) / np.abs(X).sum(axis=1)


def report(name: str, recs, ref: str, far: str, band_hz, freqs_hz, trigger_aligned: bool = True, bursts: int = 1):
    fs = recs[0].timing.rate_hz
    band = (band_hz[0] / fs, band_hz[1] / fs)
    truth = np.array([r.meta["sim_onset_s"] for r in recs]) * fs
    c = time.process_time()
    for b in range(bursts):
        sub = list(range(b, len(recs), bursts))
        shots = [{ch.name: recs[j].scaled(ch.name) for ch in recs[j].channels} for j in sub]
        lags, rho = shot_lags(shots, ref, band)
        true = truth[sub] - truth[sub[0]]
        err = lags - true
        burst = f", burst {recs[sub[0]].meta.get('burst_frequency_hz', 0) / 1e3:.0f} kHz" if bursts > 1 else ""
        print(f"{name}{burst}: {len(shots)} shots on {ref}: true lags {true.min():+.2f} .. {true.max():+.2f} samples "
              f"(std {true.std():.2f}); measured - true: rms {np.sqrt(np.mean(err ** 2)):.3f}, max |.| "
              f"{np.abs(err).max():.3f} samples; correlation peak >= {rho.min():.4f}")
        if not trigger_aligned:
            continue
        size = max(1, len(shots) // MAX_CURVES) if len(shots) > MAX_CURVES else len(shots)
        if len(shots) > MAX_CURVES:
            _, note = stack_shots(shots, ref=ref, band=band)
            size = int(note.split("groups of ")[1].split(" ")[0])
        aligned, _ = align_shots(shots, ref, band)
        for f in freqs_hz:
            parts = []
            for ch in (ref, far):
                a, b2 = kept(shots, ch, size, f, fs), kept(aligned, ch, size, f, fs)
                parts.append(f"{ch} {a.mean():.3f} (min {a.min():.3f}, {20 * np.log10(a.min()):+.1f} dB) -> "
                             f"{b2.mean():.3f} (min {b2.min():.3f})")
            print(f"  groups of {size}, kept at {f / 1e3:.0f} kHz, unaligned -> aligned: " + "; ".join(parts))
    print(f"  ({time.process_time() - c:.1f} s CPU)")


def main(argv) -> None:
    print(f"machine: {machine()}")
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    cfrp = load_specimen("cfrp")
    pick = argv or ["s0", "sweep", "default"]
    if "s0" in pick:
        for off, scale in (("soft", 1 / 0.6), ("stiff", 1 / 1.4)):
            rig = _rig("cfrp_pencil_2dir_s0.toml", scale)
            for seed in range(3):
                recs = _recs(f"s0_{off}_{seed}", lambda: records(rig, large, 24, seed, "independent"))
                report(f"two_dir_s0 {off} seed {seed} (independent)", recs, "x1", "x2", (10e3, 200e3),
                       (20e3, 48e3, 100e3))
    if "sweep" in pick:
        rig = _rig("cfrp_pzt_sweep_2dir_far.toml", 1 / 0.6)
        recs = _recs("sweep_soft_0_80", lambda: records(rig, large, 80, 0, "independent"))
        for ch in ("exc", "x1"):
            report("sweep_far_80 soft seed 0 (independent), triggered on exc", recs, ch, "x2", (40e3, 300e3), (),
                   trigger_aligned=False, bursts=5)
    if "default" in pick:
        for n, scale, model in ((3, None, "simulated"), (100, 0.714, "simulated")):
            rig = _rig("default", scale)
            recs = _recs(f"default_{n}", lambda: records(rig, cfrp, n, 0, model))
            report(f"default rig, {n} shots (simulated{', plate 0.714 x the file' if scale else ''})", recs, "mfc1",
                   "mfc2", (10e3, 200e3), (20e3, 48e3, 100e3))


if __name__ == "__main__":
    main(sys.argv[1:])
