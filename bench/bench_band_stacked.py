"""The wave band judged on the averaged shots (issue 24, session 29, h62): before / after on the
same records.

``labid.workflows.wave_analysis`` judges the band the far sensor's record supports
(``band.analysis_band``) on the first group of averaged shots (``shots.stack_shots``); it
judged it on one raw shot before (main 5617e76). Runs with either tree (copy this file into
the other tree's bench/ and run it from there: its own labid is imported).

Records: 'independent' = the rig's chain around the plate transfer of
bench/independent/legendre_safe.py (``bench_unknown_plate.records``), the file 40 % off the
plate (soft: plate = file x 1/0.6, stiff: x 1/1.4); the reference = the TRUE plate's group
velocity from the same independent model. They are made once and pickled
(``make``), so before and after read the very same records.

Run (from a cwd without a labid package; OMP_NUM_THREADS=1):
  python bench/bench_band_stacked.py make CASE soft|stiff SEED     # records -> $H62_RECS/...
  python bench/bench_band_stacked.py band CASE soft|stiff SEED     # the band per burst only (no picks)
  python bench/bench_band_stacked.py full CASE soft|stiff SEED     # the whole wave analysis
Each prints one JSON line (the band per burst; or per curve points, within 1 %, z rms, CPU).
CASE: sweep80 (5 bursts x 16 shots), sweep10 (x 2), edgelongraw (36 edge breaks, the 20 / 60 cm
rig without its preamps), twodirs0 (24 face breaks, MFCs 20 / 40 cm along 0 / 90 deg).
"""
from __future__ import annotations

import json
import os
import pickle
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))
from bench_unknown_plate import EDGE_BAND, records, run_case  # noqa: E402
from bench_wave_seeds import _rig  # noqa: E402
from engine.wavefeatures import pipeline as waves_pipeline  # noqa: E402
from labid.workflows.analysis import AnalysisSettings, wave_features  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402

RECS = Path(os.environ.get("H62_RECS", "/tmp/h62_recs"))
SCALES = {"soft": 1 / 0.6, "stiff": 1 / 1.4}
#: case -> (rig file (bench_wave_seeds._rig names), shots, settings)
CASES = {"sweep80": ("cfrp_pzt_sweep_2dir_far.toml", 80, AnalysisSettings()),
         "sweep10": ("cfrp_pzt_sweep_2dir_far.toml", 10, AnalysisSettings()),
         "edgelongraw": ("cfrp_pencil_edge_0_long.toml-gain20", 36, EDGE_BAND),
         "twodirs0": ("cfrp_pencil_2dir_s0.toml", 24, AnalysisSettings())}


def setup(case: str, scale: str):
    name, n, settings = CASES[case]
    spec = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = _rig(name, "noisy")
    return replace(rig, sim=replace(rig.sim, truth_scale=(("*", SCALES[scale]),))), spec, n, settings


def path(case: str, scale: str, seed: int) -> Path:
    return RECS / f"{case}_{scale}_{seed}.pkl"


def make(case: str, scale: str, seed: int) -> dict:
    rig, spec, n, _ = setup(case, scale)
    c = time.process_time()
    recs = records(rig, spec, n, seed, "independent")
    RECS.mkdir(parents=True, exist_ok=True)
    path(case, scale, seed).write_bytes(pickle.dumps(recs))
    return {"made": str(path(case, scale, seed)), "shots": n, "cpu_s": round(time.process_time() - c, 1)}


def band(case: str, scale: str, seed: int) -> dict:
    """The analysis band of each burst: ``measure_waves`` replaced by a stub that notes its grid."""
    rig, spec, _, settings = setup(case, scale)
    recs = pickle.loads(path(case, scale, seed).read_bytes())
    seen = []

    def stub(setup_, shots, freqs, ws):
        seen.append([setup_.source.frequency_hz, float(freqs[0]), float(freqs[-1]), len(shots)])
        return waves_pipeline.WaveResult((), {}, {}, None, None, ())
    real = waves_pipeline.measure_waves
    waves_pipeline.measure_waves = stub
    notes: list[str] = []
    try:
        wave_features(recs, rig, spec, settings, notes)
    finally:
        waves_pipeline.measure_waves = real
    return {"bands": seen, "empty": [n for n in notes if n.startswith("no velocity") or "no velocity" in n[:40]]}


def full(case: str, scale: str, seed: int) -> dict:
    rig, spec, _, settings = setup(case, scale)
    recs = pickle.loads(path(case, scale, seed).read_bytes())
    rows, cpu, notes = run_case(case, rig, spec, len(recs), SCALES[scale], "independent", settings, seed, recs,
                                trace=False)
    curves = {}
    for mode, d, npts, fmin, fmax, e, s, z, f in rows:
        curves[f"{mode}_{d:g}"] = {"points": int(npts), "within_1pct": int(np.sum(np.abs(e) <= 0.01)),
                                   "fmin_khz": round(fmin / 1e3, 1), "fmax_khz": round(fmax / 1e3, 1),
                                   "max_abs_err_pct": round(100 * float(np.max(np.abs(e))), 2),
                                   "z_rms": round(float(np.sqrt(np.mean(z ** 2))), 2),
                                   "off": [[round(a / 1e3), round(100 * b, 2), round(100 * c, 2)]
                                           for a, b, c in zip(f, e, s) if abs(b) > 0.01]}
    bands = [n for n in notes if n.startswith("wave band") or "wave band" in n[:30]]
    return {"curves": curves, "cpu_s": round(cpu, 1), "band_notes": bands}


def main(argv) -> None:
    verb, case, scale, seed = argv[0], argv[1], argv[2], int(argv[3])
    c, t = time.process_time(), time.perf_counter()
    out = {"make": make, "band": band, "full": full}[verb](case, scale, seed)
    print(json.dumps({"verb": verb, "case": case, "scale": scale, "seed": seed, "tree": str(HERE.parent),
                      "utc": time.strftime("%H:%M", time.gmtime()), "load": round(os.getloadavg()[0], 2),
                      "total_cpu_s": round(time.process_time() - c, 1),
                      "total_wall_s": round(time.perf_counter() - t, 1), **out}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
