"""The sweep's S0 at a burst's spectral edge: bias split into its sources (issue 24, session 29).

The rig of bench_unknown_plate.py ``sweep_far`` (bench/rigs/cfrp_pzt_sweep_2dir_far.toml), ONE
burst of it (default 100 kHz) on the plate the file -40 % describes (plate = file x 1/0.6),
INDEPENDENT records (bench/independent/legendre_safe.py's transfer through the rig's chain);
reference = the TRUE plate's S0 group velocity from legendre_safe. S0 along 0 deg is measured
source (the recorded drive) to the 40 cm sensor pair's sum.

Variants (comma list, applied to the rig text / the transfer):
  quiet   noise 0.1 uV (was 1 mV)            clean   also a 24-bit ADC (was 12)
  bare    also no crosstalk, no sensor high-pass (the chain left: anti-alias on every channel)
  s0      the plate transfer's S0 alone (no A0, SH0)
so ``clean,bare,s0`` is (a) a pure S0 record with the burst's spectrum; ``clean,s0`` (b) + the chain;
``clean`` (c) + the other modes; ``quiet`` + the 12-bit ADC undithered; none: the noisy rig.

Per wavelet the pipeline measured S0 0 deg with (stage 2, every shot, ``pipeline._velocity``
traced): per analysis frequency the instantaneous frequency of the far pick, the delay error
against the true plate's group velocity AT that instantaneous frequency (% of the velocity, the
error a reassigned point carries), and the recorded drive's spectrum level there (dB below its
peak, at the instantaneous and at the analysis frequency). Then the burst's reported points.

Run: OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_s0_edge.py [VARIANTS] [burst=HZ] [shots=N] [seed=N]
     [wavelet=cmor2-5] [lo=85e3] [hi=130e3] [pickle=FILE]
(pickle=FILE: the burst's shots of a pickled list of a sweep's Records instead of new ones)
     OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_s0_edge.py mc [VARIANTS] [burst=HZ] [shots=16] [draws=0-9]
     [noise=1e-3]   (noise-free records + numpy noise and a 12-bit ADC per draw: the points' mean error per region)
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.bench_unknown_plate import HERE, independent_transfer, records, reference  # noqa: E402
from bench.s0_trace import by_wavelet, s0_picks  # noqa: E402
from engine.waves import Wavelet  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from labid.workflows import analysis  # noqa: E402
from labid.workflows.analysis import AnalysisSettings  # noqa: E402
from mock_hw import waves as mock_waves  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402

SWEEP = HERE / "rigs" / "cfrp_pzt_sweep_2dir_far.toml"
SCALE = 1 / 0.6


def rig_text(variants: set[str]) -> str:
    """The sweep rig's text with the variants applied (module docstring)."""
    text = SWEEP.read_text()
    if variants & {"quiet", "clean", "bare"}:
        text = text.replace("noise_v = 1.0e-3", "noise_v = 1.0e-7")
    if variants & {"clean", "bare"}:
        text = text.replace("adc_bits = 12", "adc_bits = 24")
    if "bare" in variants:
        text = text.replace("crosstalk_db = -60.0\n", "").replace("highpass_hz = 1.0e3\n", "")
    return text


def s0_only(*a, **k):
    """legendre_safe's transfer with its S0 term alone."""
    return {m: v for m, v in independent_transfer(*a, **k).items() if m == "S0"}


def burst_records(variants: set[str], fb: float, n: int, seed: int, scale: float = SCALE):
    """(rig, records): ``n`` shots of the ``fb`` burst alone, independent transfer."""
    rig = rig_from_text(rig_text(variants), f"{SWEEP} ({','.join(sorted(variants)) or 'as is'})")
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", scale),)),
                  wave_source=replace(rig.wave_source, burst=rig.wave_source.burst.at(fb)))
    spec = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    if "s0" in variants:
        with mock_waves.transfer_model("legendre_safe_S0", s0_only):
            dev_recs = records_with(rig, spec, n, seed)
        return rig, spec, dev_recs
    return rig, spec, records(rig, spec, n, seed, "independent")


def records_with(rig, spec, n, seed):
    """``bench_unknown_plate.records`` under the transfer model already set (simulated branch)."""
    return records(rig, spec, n, seed, "simulated")


def spectrum_db(x: np.ndarray, fs: float, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The record's amplitude spectrum at ``f`` in dB below its peak, and d ln|X| / d ln f."""
    n = 1 << 16
    X = np.abs(np.fft.rfft(x - np.mean(x), n))
    ff = np.fft.rfftfreq(n, 1 / fs)
    a = np.interp(f, ff, X)
    db = 20 * np.log10(a / X[(ff > 0.5 * f.min())].max())
    slope = np.gradient(np.log(a), np.log(f))
    return db, slope


def trace(rig, spec, recs, wavelet: str | None, lo: float, hi: float) -> list[str]:
    """Per wavelet and analysis frequency in [lo, hi]: the S0 0 deg delay error (see the module)."""
    true = truth_laminate(spec.laminate, rig.sim.truth_scale)
    settings = AnalysisSettings()
    if wavelet:
        w = Wavelet.from_name(wavelet)
        settings = AnalysisSettings(wavelet=(w.bandwidth, w.center))
    c0 = time.process_time()
    notes: list[str] = []
    with s0_picks() as log:
        feats = analysis._wave_features_one(recs, rig, spec, settings, notes)[0]
    fs = recs[0].timing.rate_hz
    fg = np.linspace(0.3 * lo, 1.5 * hi, 400)
    cg = reference(true, 0.0, fg)["S0"]       # one table of the true plate, interpolated below
    lines = [f"  analysis {time.process_time() - c0:.1f} s CPU; " + "; ".join(
        n for n in notes if "wavelet whose" in n and n.startswith("direction 0"))[:300]]
    for name, ent in by_wavelet(log).items():
        D, V, FI, SNR, X = (np.array([getattr(e, k) for e in ent]) for k in ("delay", "valid", "finst", "snr_db",
                                                                            "source_record"))
        F = ent[0].freqs
        db, slope = spectrum_db(X.mean(axis=0), fs, F)
        sel = np.flatnonzero((F >= lo) & (F <= hi) & (V.sum(axis=0) > 0))
        if not sel.size:
            continue
        lines.append(f"  {name} ({D.shape[0]} shots): f kHz | finst kHz | err % at finst (shots' mean) | "
                     f"drive spectrum dB (at finst) | at f | SNR dB")
        for i in sel:
            m = V[:, i]
            fi = float(np.nanmean(FI[m, i]))
            v = 0.4 / D[m, i]
            ref = float(np.interp(fi, fg, cg))
            e = 100 * (np.mean(v) / ref - 1)
            dbi, _ = spectrum_db(X.mean(axis=0), fs, np.array([fi, fi * 1.01]))
            lines.append(f"    {F[i] / 1e3:6.1f} | {fi / 1e3:6.1f} | {e:+6.2f} | {dbi[0]:6.1f} | {db[i]:6.1f} | "
                         f"{np.median(SNR[m, i]):.0f}")
    for w in (w for w in feats if w["mode"] == "S0" and w["direction_deg"] == 0.0):
        f, v, s = (np.array(w[k]) for k in ("frequency_hz", "group_velocity_m_s", "sigma_m_s"))
        ref = reference(true, 0.0, f)["S0"]
        lines.append("  points: " + ", ".join(f"{a / 1e3:.1f} kHz {100 * (b / r - 1):+.3f} % (sigma {100 * e / r:.3f} %)"
                                              for a, b, e, r in zip(f, v, s, ref)))
    return lines


def with_noise(recs, noise_v: float, seed: int, bits: int = 12):
    """Copies of ``recs`` with white noise of ``noise_v`` (V at the ADC input) added to every
    channel and quantised to ``bits`` over each channel's range, as ``mock_hw.rig`` does (numpy draws,
    SeedSequence([seed, shot]))."""
    out = []
    for k, r in enumerate(recs):
        rng = np.random.default_rng(np.random.SeedSequence([seed, 7919, k]))
        data = {}
        for c in r.channels:
            lsb = 2.0 * c.range_v / 2.0 ** bits
            data[c.name] = np.rint((r.data[c.name] + noise_v * rng.standard_normal(r.data[c.name].size)) / lsb) * lsb
        out.append(replace(r, data=data))
    return out


def monte_carlo(variants: set[str], fb: float, n: int, draws: range, noise_v: float = 1e-3) -> list[str]:
    """The burst's S0 0 deg points over noise draws: noise-free records of ``variants`` (made once,
    ``n`` shots) plus numpy white noise of ``noise_v`` and a 12-bit ADC per draw; per draw the points,
    then per frequency region (points within 3 % of each other) the mean error, its standard error,
    the mean reported sigma and the rms of err / sigma."""
    rig, spec, clean = burst_records(variants | {"clean"}, fb, n, 0)
    true = truth_laminate(spec.laminate, rig.sim.truth_scale)
    fg = np.linspace(0.3 * fb, 3.5 * fb, 600)
    cg = reference(true, 0.0, fg)["S0"]
    pts, lines = [], []
    for k in draws:
        c0 = time.process_time()
        feats = analysis._wave_features_one(with_noise(clean, noise_v, k), rig, spec, AnalysisSettings(), [])[0]
        got = [(f, v / np.interp(f, fg, cg) - 1, s / np.interp(f, fg, cg)) for w in feats
               if w["mode"] == "S0" and w["direction_deg"] == 0.0
               for f, v, s in zip(w["frequency_hz"], w["group_velocity_m_s"], w["sigma_m_s"])]
        pts += [(k, *p) for p in got]
        lines.append(f"  draw {k} ({time.process_time() - c0:.1f} s CPU): " + ", ".join(
            f"{f / 1e3:.1f} kHz {100 * e:+.2f} % ({100 * s:.2f})" for f, e, s in got))
        print(lines[-1], flush=True)
    P = np.array([p[1:] for p in pts]) if pts else np.zeros((0, 3))
    order = np.argsort(P[:, 0]) if len(P) else []
    regions: list[list[int]] = []
    for i in order:
        if regions and P[i, 0] <= 1.03 * P[regions[-1][0], 0]:
            regions[-1].append(i)
        else:
            regions.append([i])
    for g in regions:
        e, s = P[g, 1], P[g, 2]
        se = e.std(ddof=1) / np.sqrt(e.size) if e.size > 1 else np.nan
        lines.append(f"  region {P[g, 0].min() / 1e3:.1f}-{P[g, 0].max() / 1e3:.1f} kHz: {e.size} points of "
                     f"{len(draws)} draws, mean err {100 * e.mean():+.2f} % (s.e. {100 * se:.2f}), mean sigma "
                     f"{100 * s.mean():.2f} %, z rms {np.sqrt(np.mean((e / s) ** 2)):.2f}, within 1 %: "
                     f"{int(np.sum(np.abs(e) <= 0.01))} / {e.size}")
    return lines


def main(argv) -> None:
    kw = dict(a.split("=", 1) for a in argv if "=" in a)
    if argv and argv[0] == "mc":     # mc [VARIANTS] [burst=HZ] [shots=N] [draws=A-B] [noise=V]
        variants = set(next((a for a in argv[1:] if "=" not in a), "").split(",")) - {""}
        a, b = (int(x) for x in kw.get("draws", "0-9").split("-"))
        print("\n".join(monte_carlo(variants, float(kw.get("burst", 100e3)), int(kw.get("shots", 16)),
                                    range(a, b + 1), float(kw.get("noise", 1e-3)))[-8:]), flush=True)
        return
    variants = set(next((a for a in argv if "=" not in a), "").split(",")) - {""}
    fb, n, seed = float(kw.get("burst", 100e3)), int(kw.get("shots", 2)), int(kw.get("seed", 0))
    c0 = time.process_time()
    rig, spec, recs = burst_records(variants, fb, 0 if "pickle" in kw else n, seed)
    if "pickle" in kw:     # the burst's shots of a pickled sweep run (list of Records, e.g. 80 shots)
        import pickle  # noqa: PLC0415
        recs = [r for r in pickle.loads(Path(kw["pickle"]).read_bytes()) if r.meta["burst_frequency_hz"] == fb]
        n, seed = len(recs), recs[0].meta["seed"]
    print(f"burst {fb / 1e3:g} kHz, variants {sorted(variants) or 'none'}, {n} shots, seed {seed}: records "
          f"{time.process_time() - c0:.1f} s CPU, load {os.getloadavg()[0]:.1f}", flush=True)
    print("\n".join(trace(rig, spec, recs, kw.get("wavelet"), float(kw.get("lo", 85e3)), float(kw.get("hi", 130e3)))),
          flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
