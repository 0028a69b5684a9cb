"""A gross point in a burst's curve: dropped and named, or hidden by scaling every sigma (issue 24,
session 30). Every burst curve (before the sweep's merge) and every merged curve, with the Birge
scale it got (``merge.misfit_scale``), each point's error and |err| / sigma against the TRUE plate
(bench/independent/legendre_safe.py, as bench_unknown_plate.py), and each point ``merge.gross_points``
dropped, with its truth. The rule itself never sees the true plate.

Records: independent (legendre_safe through the rig's chain), pickled per (rig, file, seed) under
--cache (made when missing; the same records serve a before / after comparison).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_gross_point.py OUT.jsonl CASE ... [--cache DIR]
CASE = RIG:FILE:SEED:SHOTS, RIG pre (cfrp_pzt_sweep_2dir_far_pre.toml, 80 shots made), far
(cfrp_pzt_sweep_2dir_far.toml, 80) or s0 (cfrp_pencil_2dir_s0.toml, 24); FILE soft (the file -40 %)
or stiff (+40 %); SHOTS the first n shots analysed (a sweep of 5 bursts: 80 = 16 per burst).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.bench_unknown_plate import HERE, LABELS, ORDER, records  # noqa: E402
from bench.independent.legendre_safe import branches, layers_of, plate_of  # noqa: E402
from engine.wavefeatures import merge  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from labid.workflows import wave_analysis  # noqa: E402
from labid.workflows.analysis import AnalysisSettings, wave_features  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402

RIGS = {"pre": ("cfrp_pzt_sweep_2dir_far_pre.toml", 80), "far": ("cfrp_pzt_sweep_2dir_far.toml", 80),
        "s0": ("cfrp_pencil_2dir_s0.toml", 24)}
SCALE = {"soft": 1 / 0.6, "stiff": 1 / 1.4}


class Trace:
    """Wraps ``merge.misfit_scale`` / ``gross_points`` and ``wave_analysis._merge_sweep`` to keep
    each curve's scale, each dropped point, each burst's curves."""

    def clear(self):
        self.scales, self.drops, self.bursts = [], [], []

    def __init__(self):
        self.clear()
        ms, gp, sweep = merge.misfit_scale, getattr(merge, "gross_points", None), wave_analysis._merge_sweep

        def misfit_scale(f, v, s, label="the curve", *a, **kw):
            k, line = ms(f, v, s, label, *a, **kw)
            self.scales.append((label, [float(x) for x in f], float(k)))
            return k, line

        def gross_points(f, v, s, label="the curve", *a, **kw):
            bad, line = gp(f, v, s, label, *a, **kw)
            self.drops += [(label, float(a_), float(b_), float(c_), int(np.size(f)))
                           for a_, b_, c_ in zip(np.asarray(f)[bad], np.asarray(v)[bad], np.asarray(s)[bad])]
            return bad, line

        def merge_sweep(parts, notes, *rest):
            self.bursts += [(f, w) for f, (feats, *_r) in parts for w in feats]
            return sweep(parts, notes, *rest)
        merge.misfit_scale, wave_analysis._merge_sweep = misfit_scale, merge_sweep
        if gp is not None:
            merge.gross_points = gross_points


def truth_at(lam, cache: dict, direction: float, mode: str, f) -> np.ndarray:
    """The true plate's group velocity (m/s); the branches tabulated once per direction to 420 kHz
    (within 1e-5 of bench_unknown_plate.reference, which tabulates to 1.05 x each curve's top)."""
    if direction not in cache:
        cache[direction] = branches(plate_of(layers_of(lam.plies, direction), ORDER), 420e3)
    return cache[direction].at(LABELS.index(mode), 2 * np.pi * np.asarray(f, float))[1]


def curve_row(lam, cache, w, scales) -> dict:
    f = [float(x) for x in w["frequency_hz"]]
    k = next((k for label, ff, k in scales if ff == f and label.startswith(w["mode"])), None)
    return {"mode": w["mode"], "direction": w["direction_deg"], "f": f, "v": w["group_velocity_m_s"],
            "s": w["sigma_m_s"], "ref": truth_at(lam, cache, w["direction_deg"], w["mode"], f).tolist(),
            "scale": k, "dropped": w.get("dropped", {})}


def run(case: str, cache_dir: Path, trace: Trace) -> dict:
    kind, fileoff, seed, n = case.split(":")
    name, made = RIGS[kind]
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    base = rig_from_text((HERE / "rigs" / name).read_text(), name)
    rig = replace(base, sim=replace(base.sim, truth_scale=(("*", SCALE[fileoff]),)))
    lam, cache = truth_laminate(large.laminate, rig.sim.truth_scale), {}
    pk = cache_dir / f"recs_{kind}_{fileoff}_{seed}_{made}.pkl"
    if not pk.exists():
        pk.write_bytes(pickle.dumps(records(rig, large, made, int(seed), "independent")))
    recs = pickle.loads(pk.read_bytes())[:int(n)]
    trace.clear()
    notes: list[str] = []
    c = time.process_time()
    feats, *_ = wave_features(recs, rig, large, AnalysisSettings(), notes)
    cpu = time.process_time() - c
    drops = []
    for label, f, v, s, size in trace.drops:
        mode, _, deg = label.split()[:3]
        drops.append({"label": label, "f": f, "v": v, "s": s, "n": size,
                      "ref": float(truth_at(lam, cache, float(deg), mode, [f])[0])})
    return {"case": case, "cpu_s": cpu, "load": os.getloadavg()[0], "drops": drops,
            "bursts": [dict(curve_row(lam, cache, w, trace.scales), burst=f) for f, w in trace.bursts],
            "merged": [curve_row(lam, cache, w, trace.scales) for w in feats]}


def main(argv) -> None:
    out, cases = argv[0], [a for a in argv[1:] if ":" in a]
    cache_dir = Path(argv[argv.index("--cache") + 1]) if "--cache" in argv else Path("/tmp/bench_gross_point")
    cache_dir.mkdir(parents=True, exist_ok=True)
    trace = Trace()
    for case in cases:
        row = run(case, cache_dir, trace)
        with open(out, "a") as fh:
            fh.write(json.dumps(row) + "\n")
        bad = [d for d in row["drops"] if abs(d["v"] / d["ref"] - 1) > 0.01 or abs(d["v"] - d["ref"]) > 5 * d["s"]]
        print(f"{case}: {row['cpu_s']:.1f} s CPU (load {row['load']:.2f}); dropped {len(row['drops'])} point(s), "
              f"{len(bad)} truly off (> 1 % or > 5 sigma from the true plate)", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
