"""Cost of the wave analysis of a tone-burst sweep (issue 24: a wave run's analysis <= 30 s CPU).

The run: bench/rigs/cfrp_pzt_sweep_2dir_far.toml (5 Hann bursts, PZT pair, two directions) on
bench/rigs/cfrp_large.toml, the simulated plate 1 / 0.6 x the file's moduli (the file 40 % soft),
N shots in all (N / 5 per burst; simulated records of labid's own simulator, seed 0). The records
are made once and pickled (``--records``); then ``labid.workflows.analysis.wave_features`` on
them, CPU = process time. ``--out`` writes the features and notes as JSON (sorted keys, floats as
Python prints them) so that two versions of the code can be compared byte for byte.

Run: OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_sweep_cost.py [N] [--records F.pkl] [--out F.json]
(for an A/B: LABID_SRC=/path/to/the/other/tree, from a cwd without a labid package).
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import time
from dataclasses import replace
from pathlib import Path

# LABID_SRC: the tree whose code is measured (an A/B runs this file against another checkout)
sys.path.insert(0, os.environ.get("LABID_SRC", str(Path(__file__).resolve().parents[1])))
from bench._machine import machine  # noqa: E402


def _plain(o):
    if isinstance(o, dict):
        return {k: _plain(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_plain(v) for v in o]
    return o.tolist() if hasattr(o, "tolist") else o


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("n", nargs="?", type=int, default=10)
    ap.add_argument("--records", help="pickle of the records (made and written when missing)")
    ap.add_argument("--out", help="JSON of the features and notes")
    a = ap.parse_args(argv)
    from bench.bench_unknown_plate import HERE, records
    from labid.inputs.rig import rig_from_text
    from labid.inputs.specimen import load_specimen
    from labid.workflows.analysis import AnalysisSettings, wave_features
    print(f"machine: {machine()}")
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = rig_from_text((HERE / "rigs" / "cfrp_pzt_sweep_2dir_far.toml").read_text(), "far")
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", 1 / 0.6),)))
    if a.records and os.path.exists(a.records):
        with open(a.records, "rb") as fh:
            recs = pickle.load(fh)
    else:
        recs = records(rig, large, a.n, 0, "simulated")
        if a.records:
            with open(a.records, "wb") as fh:
                pickle.dump(recs, fh)
    c, w = time.process_time(), time.perf_counter()
    notes: list = []
    feats, *_ = wave_features(recs, rig, large, AnalysisSettings(), notes)
    c, w = time.process_time() - c, time.perf_counter() - w
    print(f"wave analysis of {len(recs)} shots: {c:.1f} s CPU, {w:.1f} s wall; "
          f"{sum(len(f['frequency_hz']) for f in feats)} points; load now {os.getloadavg()[0]:.1f}")
    if a.out:
        with open(a.out, "w") as fh:
            json.dump({"feats": _plain(feats), "notes": notes}, fh, sort_keys=True, default=repr)


if __name__ == "__main__":
    main()
