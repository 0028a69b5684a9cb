"""CPU time and peak memory of ``labid diagnose`` (issue 13 targets), one process per case.

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/bench_gap_cost.py [--demo-features PATH]

Cases (features from bench/blind.py, default mesh, the diagnoser's own generator):
  modal3-clean   10 modes, no shapes (pairing by order), --params E1,E2,G12: no gap;
  modal3-mass    the same with 4 g extra at each accelerometer: a gap, candidates refitted;
  combined-clean 10 modes with shapes + 5 wave sets (46 velocities), six constants, --prior 0.3;
  demo           (with --demo-features) the features ``labid demo`` wrote, as the demo runs it.
Each case runs ``python -m labid.cli.main diagnose ... --quiet`` under ``/usr/bin/time -v``: user +
system CPU seconds and the maximum resident set size (MiB) of the whole process (interpreter,
numpy/scipy imports and the diagnosis).
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.blind import draw_case  # noqa: E402


def _no_shapes(doc: dict) -> dict:
    d = copy.deepcopy(doc)
    d["modal"].pop("mode_shapes", None)
    return d


def measure(features: dict | Path, args: list[str], tmp: Path, tag: str) -> dict:
    if isinstance(features, dict):
        f = tmp / f"{tag}.json"
        f.write_text(json.dumps(features))
    else:
        f = features
    out = tmp / f"{tag}.diag.json"
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "labid.cli.main", "diagnose", str(f), "--quiet",
           "--json", str(out)] + args
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1", LABID_THREADS="1")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=str(ROOT))
    err = p.stderr

    def grab(key):
        m = re.search(rf"{re.escape(key)}:\s*([0-9.:]+)", err)
        return m.group(1) if m else "nan"
    res = json.loads(out.read_text()) if out.exists() else {}
    return {"case": tag, "exit": p.returncode, "cpu_s": float(grab("User time (seconds)"))
            + float(grab("System time (seconds)")), "wall": grab("Elapsed (wall clock) time (h:mm:ss or m:ss)"),
            "peak_mib": float(grab("Maximum resident set size (kbytes)")) / 1024.0,
            "verdict": res.get("verdict"), "n_refits": sum(1 for e in res.get("effects", []) if e["refitted"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--demo-features", type=Path)
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        three = ["--params", "E1,E2,G12"]
        rows.append(measure(_no_shapes(draw_case(31, "clean", wave_sets=()).features), three, tmp,
                            "modal3-clean"))
        rows.append(measure(_no_shapes(draw_case(32, "sensor_mass", wave_sets=()).features), three, tmp,
                            "modal3-mass"))
        rows.append(measure(draw_case(33, "clean").features, ["--prior", "0.3"], tmp, "combined-clean"))
        if a.demo_features:
            rows.append(measure(a.demo_features, [], tmp, "demo"))
    print("| case | exit | verdict | refits | CPU s | wall | peak MiB |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['exit']} | {r['verdict']} | {r['n_refits']} | {r['cpu_s']:.1f} | "
              f"{r['wall']} | {r['peak_mib']:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
