"""Wave measurement on simulated records as labs have them (issue 14): accuracy and cost.

Cases (simulated rig, ``mock_hw.waves``: edge reflections, sensor response, crosstalk,
noise, ADC), each through ``labid.workflows.analysis.wave_features``:

1. the issue's pitch-catch setup (1 m x 1 m x 3 mm aluminium, 180 kHz 5-cycle burst from
   a PZT, sensors 120 and 420 mm away on the diagonal, 5 MHz, 4 shots), excitation recorded;
2. the same with a +-35 % window (the S0 edge reflections fall in it);
3. the same triggered on the near sensor, excitation still recorded;
4. the same triggered on the near sensor without the source record;
5. the built-in CFRP rig (pencil lead 4 cm from an edge, MFCs at 5 and 20 cm, 3 shots);
6. the aluminium hammer rig of tests/test_analyze.py (strain 0.375 m away, 8 shots).

Per case and mode: valid frequencies, independent points, error range against SAFE
(``engine.safe.group_velocity``), sigma range, largest |error| / sigma, drop reasons, and
the wall and CPU time of the analysis.

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_pitch_catch.py
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from engine import safe, waves  # noqa: E402
from labid.workflows.acquisition import AcquisitionSession  # noqa: E402
from labid.workflows.analysis import AnalysisSettings, wave_features  # noqa: E402
from labid.inputs.rig import read_rig_text, rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen, specimen_from_dict  # noqa: E402
from mock_hw.rig import SimulatedDevice  # noqa: E402

AL3 = {"name": "Al 1 m x 1 m x 3 mm", "plate": {"length": 1.0, "width": 1.0},
       "materials": {"Al": {"density": 2700.0, "E": 71.04e9, "G": 25.32e9}},
       "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": 3.0e-3}}
TRIG = ('trigger = { channel = "exc", level_v = 0.3, slope = "rising" }',
        'trigger = { channel = "s1", level_v = 0.05, slope = "rising" }')
NOSRC = ('channel = "exc"          # the channel that records the excitation voltage\n', "")
HAMMER_RIG = """
[wave_source]
kind = "hammer"
x = 0.30
y = 0.50
contact_s = 2.0e-5
force_n = 20.0
[devices.fast]
role = "wave"
max_rate_hz = 5.0e6
rate_hz = 1.0e6
samples = 2000
pretrigger = 100
noise_v = 1.0e-4
trigger = { channel = "hammer_hf", level_v = 0.01, slope = "rising" }
[[devices.fast.channels]]
name = "hammer_hf"
kind = "force"
sensitivity = 2.25e-3
[[devices.fast.channels]]
name = "strain1"
sensitivity = 1.0
distance_m = 0.375
volts_per_strain = 2.0e5
"""


def records(rig, spec, n, seed=0):
    dev = SimulatedDevice(rig, spec, "wave", None, seed)
    d = rig.device("wave")
    dev.configure(d.channels, d.timing, d.trigger)
    session = AcquisitionSession.__new__(AcquisitionSession)
    return [session._read(dev, d) for _ in range(n)]


def case(name, rig, spec, n, settings=AnalysisSettings(), direction=None):
    recs = records(rig, spec, n)
    notes: list[str] = []
    t, c = time.perf_counter(), time.process_time()
    feats, curves, _, _, info = wave_features(recs, rig, spec, settings, notes)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    print(f"\n{name}  (analysis {wall:.2f} s wall, {cpu:.2f} s CPU)")
    wl = next((n_ for n_ in notes if "wavelet" in n_), "")
    if wl:
        print(f"  {wl}")
    if info.get("empty"):
        print(f"  {info['empty']}")
    for key in sorted(info.get("dropped", {})):
        mode, d = key.split("_")
        g = curves.get(key)
        drop = ", ".join(f"{k} {v}" for k, v in sorted(info["dropped"][key].items(), key=lambda x: -x[1]))
        if g is None:
            print(f"  {mode}: not reported; dropped: {drop}")
            continue
        ok = g.valid
        cg = safe.group_velocity(spec.laminate, g.frequencies_hz[ok], mode, float(d))
        e = g.velocity_m_s[ok] / cg - 1
        s = g.sigma_m_s[ok] / cg
        ind = next((len(w["frequency_hz"]) for w in feats if w["mode"] == mode), 0)
        print(f"  {mode}: {ok.sum()} frequencies {g.frequencies_hz[ok][0] / 1e3:.0f}-"
              f"{g.frequencies_hz[ok][-1] / 1e3:.0f} kHz, {ind} independent; error {100 * e.min():+.2f} .. "
              f"{100 * e.max():+.2f} %, sigma {100 * s.min():.2f} .. {100 * s.max():.2f} %, "
              f"max |error|/sigma {np.max(np.abs(e) / s):.1f}; dropped: {drop}")


def main() -> None:
    print(f"machine: {machine()}")
    t0, c0 = time.perf_counter(), time.process_time()
    al3 = specimen_from_dict(AL3, "bench")
    text, _ = read_rig_text("pzt-aluminium")
    edit = lambda *e: rig_from_text(__import__("functools").reduce(lambda s, ab: s.replace(*ab), e, text), "bench")
    case("1. pitch-catch, excitation recorded", edit(), al3, 4)
    case("2. the same, +-35 % window", edit(), al3, 4, AnalysisSettings(gate_margin=0.35))
    case("3. triggered on the near sensor, excitation recorded", edit(TRIG), al3, 4)
    case("4. triggered on the near sensor, no source record", edit(TRIG, NOSRC), al3, 4)
    case("5. built-in CFRP rig: pencil lead 4 cm from an edge, MFCs at 5 and 20 cm",
         rig_from_text(read_rig_text("default")[0], "bench"), load_specimen("cfrp"), 3)
    case("6. aluminium 3.175 mm, 20 us hammer, strain 0.375 m away (1 m plate)",
         rig_from_text(HAMMER_RIG, "bench"), load_specimen("aluminium"), 8)
    print(f"\ntotal wall {time.perf_counter() - t0:.1f} s, CPU {time.process_time() - c0:.1f} s")


if __name__ == "__main__":
    main()
