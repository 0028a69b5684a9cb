"""Issue 24, session 27 (h51): where a sweep's wrong S0 point along 0 deg comes from.

The rig of bench_unknown_plate.py ``sweep_far`` (independent records: legendre_safe's transfer
through the rig's chain; plate = file x 1/0.6, the file 40 % soft), 12 shots of one burst. Per
analysis frequency of one wavelet: the S0 source-to-sensor delay of each shot against the true
plate's (0.4 m / group velocity of legendre_safe), the shots' scatter and the mean sigma each
shot's pick reports; then the burst's S0 0 deg feature points from its first 2 shots and from
all 12 (``analysis._wave_features_one``, the code under test).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_sweep_shots.py [burst_hz] [wavelet]
(default 100e3 cmor1-1; wavelet "all": a table per wavelet; ~80-140 s CPU: the records'
transfer ~75 s, the analyses ~10-60 s)
"""
from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from bench.bench_unknown_plate import HERE, records, reference  # noqa: E402
from bench.s0_trace import by_wavelet, s0_picks  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from labid.workflows import wave_analysis as analysis  # noqa: E402  (the wave part: its _merge_sweep hook)
from labid.workflows.analysis import AnalysisSettings  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402


def table(wl_name, entries, true) -> None:
    """Per analysis frequency of one wavelet: the shots' mean delay error, scatter, mean sigma
    (``entries``: the wavelet's ``s0_trace.Pick`` of every shot)."""
    D, S, V, N, TF, SF, TS, SS, SNR, FI = (np.array([getattr(x, k) for x in entries]) for k in (
        "delay", "sigma", "valid", "noise_sigma", "far_t", "far_s", "src_t", "src_s", "snr_db", "finst"))
    F = entries[0].freqs
    exp = 0.4 / reference(true, 0.0, F)["S0"]
    print(f"{wl_name}, {D.shape[0]} shots, per analysis frequency: delay error of the shots' mean vs the true "
          "plate, the shots' scatter (std, ddof 1), the mean sigma a shot reports, their ratio; the same for "
          "the sigma's noise part (without the foreign packets' shift bound)")
    for i in np.flatnonzero(V.sum(axis=0) >= 6)[::3]:
        m = V[:, i]
        sc = D[m, i].std(ddof=1)
        print(f"  {F[i] / 1e3:6.1f} kHz  n {m.sum():2d}  mean {1e6 * (D[m, i].mean() - exp[i]):+5.2f} us  "
              f"scatter {1e6 * sc:4.2f} us  sigma {1e6 * S[m, i].mean():4.2f} us  ratio {sc / S[m, i].mean():4.2f}"
              f"  noise part {1e6 * N[m, i].mean():4.2f} us  ratio {sc / N[m, i].mean():4.2f}"
              f"  | far alone {1e6 * TF[m, i].std(ddof=1):4.2f} / {1e6 * SF[m, i].mean():4.2f} us"
              f"  source alone {1e6 * TS[m, i].std(ddof=1):4.2f} / {1e6 * SS[m, i].mean():4.2f} us"
              f"  far SNR {np.median(SNR[m, i]):.1f} dB, finst {np.median(FI[m, i]) / 1e3:.1f} kHz")


def main(argv) -> None:
    fb = float(argv[0]) if argv else 100e3
    wl_name = argv[1] if len(argv) > 1 else "cmor1-1"
    print(f"machine: {machine()}")
    c0 = time.process_time()
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    path = HERE / "rigs" / "cfrp_pzt_sweep_2dir_far.toml"
    rig = rig_from_text(path.read_text(), str(path))
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", 1 / 0.6),)))
    true = truth_laminate(large.laminate, rig.sim.truth_scale)
    n_burst = len(rig.wave_source.burst.sweep_hz)
    recs = [r for r in records(rig, large, 12 * n_burst, 0, "independent")
            if r.meta["burst_frequency_hz"] == fb]
    rig_f = replace(rig, wave_source=replace(rig.wave_source, burst=rig.wave_source.burst.at(fb)))
    # the noise part of a pick's sigma: before the foreign packets' shift bound (a systematic
    # term, the same on every shot) joins it in picks.arrivals_of's last step
    with s0_picks(wl_name, noise_part=True) as log:
        for n in (2, len(recs)):
            log.clear()
            feats = analysis._wave_features_one(recs[:n], rig_f, large, AnalysisSettings(), [])[0]
            for w in (w for w in feats if w["mode"] == "S0" and w["direction_deg"] == 0.0):
                f, v, s = (np.array(w[k]) for k in ("frequency_hz", "group_velocity_m_s", "sigma_m_s"))
                ref = reference(true, 0.0, f)["S0"]
                print(f"burst {fb / 1e3:g} kHz, {n} shots, S0 0 deg points: " + ", ".join(
                    f"{a / 1e3:.1f} kHz {100 * (b / r - 1):+.2f} % (sigma {100 * e / r:.2f} %)"
                    for a, b, e, r in zip(f, v, s, ref)))
    if not log:
        print(f"{wl_name}: not among the wavelets measured on all shots")
        return
    for name, entries in by_wavelet(log).items():
        table(name, entries, true)
    print(f"CPU {time.process_time() - c0:.1f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
