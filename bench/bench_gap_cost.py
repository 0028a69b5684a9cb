"""CPU time and peak memory of ``labid diagnose`` (issue 13 targets), one process per case.

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/bench_gap_cost.py [--demo-features PATH]

Cases (features from bench/blind.py, default mesh, the diagnoser's own generator):
  modal3-clean   10 modes, no shapes (pairing by order), --params E1,E2,G12: no gap;
  modal3-mass    the same with 4 g extra at each accelerometer: a gap, candidates refitted;
  combined-clean 10 modes with shapes + 5 wave sets (46 velocities), six constants, --prior 0.3;
  demo           (with --demo-features) the features ``labid demo`` wrote, as the demo runs it.
Each case runs ``python -m labid.cli.main diagnose ... --quiet`` under ``/usr/bin/time -v``: user +
system CPU seconds and the maximum resident set size (MiB) of the whole process (interpreter,
numpy/scipy imports and the diagnosis). ``--identify`` adds ``labid identify`` on the demo's
features (with ``--demo-features``).

A/B (the host's speed drifts hour to hour: only back-to-back runs compare): ``--before DIR``
runs every case with that tree too (``git archive COMMIT | tar -x -C DIR``), alternating
before / after case by case, ``--repeat`` times; the table gives min and median CPU. Each run
gets its own copy of the features file (and of its run file: a diagnosis is stored there).
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import re
import shutil
import statistics
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


def measure(features: dict | Path, args: list[str], tmp: Path, tag: str, tree: Path = ROOT,
            command: str = "diagnose") -> dict:
    if isinstance(features, dict):
        f = tmp / f"{tag}.json"
        f.write_text(json.dumps(features))
    else:        # a copy of the features' folder: the command stores its result in their run file
        d = tmp / f"{tag}.dir"
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(features.parent, d)
        f = d / features.name
    out = tmp / f"{tag}.diag.json"
    out.unlink(missing_ok=True)
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "labid.cli.main", command, str(f), "--quiet",
           "--json", str(out)] + args
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", LABID_THREADS="1")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=str(tree))
    err = p.stderr

    def grab(key):
        m = re.search(rf"{re.escape(key)}:\s*([0-9.:]+)", err)
        return m.group(1) if m else "nan"
    res = json.loads(out.read_text()) if out.exists() else {}
    return {"case": tag, "exit": p.returncode, "cpu_s": float(grab("User time (seconds)"))
            + float(grab("System time (seconds)")), "wall": grab("Elapsed (wall clock) time (h:mm:ss or m:ss)"),
            "peak_mib": float(grab("Maximum resident set size (kbytes)")) / 1024.0,
            "verdict": res.get("verdict"),
            "n_refits": sum(1 for e in res.get("effects", []) if e["refitted"])}


def cases(demo: Path | None, identify: bool) -> list[tuple[str, dict | Path, list[str], str]]:
    """(tag, features, options, command) of each case."""
    three = ["--params", "E1,E2,G12"]
    out = [("modal3-clean", _no_shapes(draw_case(31, "clean", wave_sets=()).features), three, "diagnose"),
           ("modal3-mass", _no_shapes(draw_case(32, "sensor_mass", wave_sets=()).features), three, "diagnose"),
           ("combined-clean", draw_case(33, "clean").features, ["--prior", "0.3"], "diagnose")]
    if demo:
        out.append(("demo", demo, [], "diagnose"))
        if identify:
            out.append(("identify-demo", demo, [], "identify"))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--demo-features", type=Path)
    ap.add_argument("--identify", action="store_true", help="also labid identify on the demo's features")
    ap.add_argument("--before", type=Path, help="a tree to run back to back with this one (A/B)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--only", help="these cases only (comma-separated tags, e.g. modal3-clean)")
    a = ap.parse_args(argv)
    trees = ([("before", a.before.resolve())] if a.before else []) + [("after", ROOT)]
    rows: dict = {}
    print(f"load average at start: {os.getloadavg()[0]:.2f}", file=sys.stderr)
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        todo = cases(a.demo_features.resolve() if a.demo_features else None, a.identify)
        if a.only:
            todo = [c for c in todo if c[0] in a.only.split(",")]
        for _ in range(a.repeat):
            for tag, feats, args, command in todo:
                for name, tree in trees:
                    r = measure(feats, args, tmp, f"{tag}-{name}", tree, command)
                    rows.setdefault((tag, name), []).append(r)
                    print(f"{tag} {name}: {r['cpu_s']:.2f} s CPU, {r['peak_mib']:.0f} MiB, exit {r['exit']}",
                          file=sys.stderr, flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.2f}", file=sys.stderr)
    print("| case | tree | exit | verdict | refits | CPU s min / median | wall (last) | peak MiB (max) |")
    print("|---|---|---|---|---|---|---|---|")
    for tag, *_ in todo:
        for name, _ in trees:
            rs = rows[(tag, name)]
            cpu = [r["cpu_s"] for r in rs]
            r = rs[-1]
            print(f"| {tag} | {name} | {r['exit']} | {r['verdict']} | {r['n_refits']} | {min(cpu):.2f} / "
                  f"{statistics.median(cpu):.2f} | {r['wall']} | {max(x['peak_mib'] for x in rs):.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
