"""The pick <-> identify loop's rounds over noise seeds (issue 24 item 2, session 29 h64).

The run of bench_wave_cost.py (built-in rig, pencil-lead break, built-in CFRP specimen, the
simulated plate's moduli 0.714 x the file's: the file 40 % stiff; 100 wave shots, no hammer
hit), acquired once per noise seed (``labid acquire --seed S``: SIMULATED records), then
``labid analyze --iterate N`` (services.run_analysis): per round the constants the data
determined, their std when recorded, points added / lost, the convergence measures, the
note, and the analysis' CPU (process time) and wall time.

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_waveloop.py [--seeds 0,1] [--rounds 4]
(for the code before a change: ``cd /tmp && PYTHONPATH=/tmp/before python <this file>``:
the repository root is appended to sys.path, not put first).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parents[1]))
from labid import services  # noqa: E402
from labid.cli.main import main as labid  # noqa: E402

TRUTH = 0.714


def main(argv) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--waves", type=int, default=100)
    ap.add_argument("--no-stop", action="store_true", help="disable the stopping rules: all the rounds (item 2)")
    a = ap.parse_args(argv)
    if a.no_stop:
        from labid.workflows import waveloop  # noqa: PLC0415
        waveloop.TOL_STD = waveloop.TOL_CURVE = -1.0
    print(f"labid from {services.__file__}")
    for seed in [int(s) for s in a.seeds.split(",")]:
        with tempfile.TemporaryDirectory() as tmp:
            run = str(Path(tmp) / "run.h5")
            code = labid(["acquire", "--rig", "default", "--specimen", "cfrp", "--out", run, "--hits", "0",
                          "--waves", str(a.waves), "--truth", str(TRUTH), "--seed", str(seed), "--quiet"])
            w, c = time.perf_counter(), time.process_time()
            an = services.run_analysis(run, out=Path(tmp) / "f.json", iterate=a.rounds)
            w, c = time.perf_counter() - w, time.process_time() - c
            doc = an.features
            print(f"\nseed {seed} (acquire exit {code}): analyze --iterate {a.rounds}: {w:.1f} s wall, {c:.1f} s CPU")
            print("  truth: E1 %.1f, G13 %.3f, G23 %.3f GPa (file x %.3f)" % tuple(
                [x * TRUTH for x in _file_constants()] + [TRUTH]))
            for r in doc.get("analysis", {}).get("iterations", []):
                k = r["constants"]
                sd = r.get("std", {})
                cs = ", ".join(f"{n} {k[n] / 1e9:.3f}" + (f"+-{sd[n] / 1e9:.3f}" if n in sd else "")
                               for n in ("E1", "E2", "G12", "G13", "G23") if n in k)
                extra = "".join(f", {key} {r[key]:.2g}" for key in ("constants_shift_std", "curve_shift_sigma",
                                                                          "span_change")
                                if isinstance(r.get(key), (int, float)))
                print(f"  round {r['iteration']}: {cs} GPa; points {r.get('n_points')}; added {r.get('added')}, "
                      f"lost {r.get('lost')}, max_shift_sigma {r.get('max_shift_sigma', float('nan')):.2g}{extra}"
                      + (f"; stopped: {r['stopped']}" if r.get("stopped") else ""))
            for n in an.notes:
                if n.startswith("pick <-> identify"):
                    print("  " + n)


def _file_constants():
    from labid.inputs.specimen import load_specimen  # noqa: PLC0415
    p = load_specimen("cfrp").laminate.plies[0].material.params()
    return p["E1"] / 1e9, p["G13"] / 1e9, p["G23"] / 1e9


if __name__ == "__main__":
    main(sys.argv[1:])
