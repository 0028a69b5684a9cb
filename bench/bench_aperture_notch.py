"""A0 near the wave source's aperture zeros on the preamp sweep rig (issue 24, session 30).

A PZT disc of radius a excites a guided mode through J1(k a) / (k a): at k a = 3.83, 7.02 the
mode's spectrum has a zero, and the CWT ridge splits into two lobes there. For each direction,
prints where those zeros fall for A0 on the true plate and on the specimen file (labid's SAFE
wavenumbers), then analyses the rig's records (independent: legendre_safe through the rig's
chain, or pickled ones) with the specimen file as nominal and prints A0's points against the
true plate (bench_unknown_plate.run_case).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_aperture_notch.py [stiff|soft] [seed=N] [shots=N] [recs=PATH.pkl]
(stiff: the file 40 % too stiff, the plate x 1/1.4; shots: per sweep, 5 bursts; recs: records pickled by
/tmp/lead29/pre/final.py-style drivers, a list of Record)
"""
from __future__ import annotations

import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from bench.bench_unknown_plate import HERE, run_case  # noqa: E402
from engine.safe import mode_velocities  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402

RIG = HERE / "rigs" / "cfrp_pzt_sweep_2dir_far_pre.toml"
ZEROS = (3.8317, 7.0156)          # the first zeros of J1


def aperture_zeros(lam, direction: float, radius_m: float, f=np.linspace(30e3, 400e3, 371)) -> list[float]:
    """Frequencies (Hz) where A0's k a meets a zero of J1 along ``direction`` (deg)."""
    ka = mode_velocities(lam, f, direction_deg=direction)["A0"][0] * radius_m
    return [float(np.interp(z, ka, f)) for z in ZEROS if np.nanmin(ka) < z < np.nanmax(ka)]


def main(argv) -> None:
    opts = dict(a.split("=", 1) for a in argv if "=" in a)
    file = "soft" if "soft" in argv else "stiff"
    seed, shots = int(opts.get("seed", 0)), int(opts.get("shots", 80))
    scale = {"soft": 1 / 0.6, "stiff": 1 / 1.4}[file]
    print(f"machine: {machine()}")
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = rig_from_text(RIG.read_text(), str(RIG))
    radius = 0.5 * rig.wave_source.diameter_m
    true_lam = truth_laminate(large.laminate, (("*", scale),))
    for d in (0.0, 90.0):
        print(f"A0 along {d:g} deg, aperture zeros (PZT {2e3 * radius:g} mm): true plate "
              + ", ".join(f"{z / 1e3:.0f}" for z in aperture_zeros(true_lam, d, radius)) + " kHz; the file "
              + ", ".join(f"{z / 1e3:.0f}" for z in aperture_zeros(large.laminate, d, radius)) + " kHz")
    recs = pickle.load(open(opts["recs"], "rb"))[:shots] if "recs" in opts else None
    run_case(f"preamp sweep, file {file}", rig, large, shots, scale, "independent", seed=seed, recs=recs, trace=False)


if __name__ == "__main__":
    main(sys.argv[1:])
