"""`labid identify` on a features file, the whole process and its identification alone, A/B.

    OMP_NUM_THREADS=1 .venv/bin/python bench/bench_identify_process.py DEMO_DIR [--before TREE] [--pairs 6]

DEMO_DIR holds ``features.json`` and its run file (``labid demo --seed 0 --workers 1 --out DEMO_DIR``).
Every run gets a fresh copy of DEMO_DIR (identify stores its result in the run file, and a
growing result history would cost each later run more). Each run is one process started from
a cwd with no labid package, PYTHONPATH = the tree: CPU = user + sys of the whole process
(``os.wait4``), and the CPU of ``labid.inference.identify`` (the identification flow:
problem, global stage, fits, verdict, budget) and of ``services.store_for_features`` (the result
written into the run file) measured inside it with ``time.process_time``.
With ``--before``, runs alternate ABBA (before, after, after, before, ...). The host's speed
drifts hour to hour: only back-to-back pairs compare. Prints one line per run and the medians.
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

WRAP = r"""
import sys, time
import labid.inference as inf
import labid.services as services
from labid.cli import main as climain
box = {}
def timing(tag, f):
    def timed(*a, **k):
        t = time.process_time(); r = f(*a, **k); box[tag] = time.process_time() - t; return r
    return timed
inf.identify = timing('cpu', inf.identify)
services.store_for_features = timing('store', services.store_for_features)
sys.argv = ['labid'] + sys.argv[1:]
try:
    climain.main()
except SystemExit:
    pass
sys.stderr.write(f"IDENTIFY_CPU {box.get('cpu', float('nan')):.4f} STORE_CPU {box.get('store', float('nan')):.4f}\n")
"""


def run_once(tree: Path, demo: Path, work: Path) -> tuple[float, float, float, dict, float]:
    """(process CPU s, identify CPU s, peak RSS MiB, --json document, CPU s of storing the result
    in the run file) of one run."""
    import json
    run = work / "run"
    shutil.rmtree(run, ignore_errors=True)
    shutil.copytree(demo, run)
    out = work / "out.json"
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "LABID_THREADS": "1"}
    with open(work / "stderr.txt", "w") as err:
        p = subprocess.Popen([sys.executable, "-c", WRAP, "identify", str(run / "features.json"), "--quiet",
                              "--json", str(out)], cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=err)
        _, status, ru = os.wait4(p.pid, 0)
    text = (work / "stderr.txt").read_text()
    if status != 0 or "IDENTIFY_CPU" not in text:
        raise SystemExit(f"{tree}: identify failed (status {status}):\n{text[-2000:]}")
    tail = text.rsplit("IDENTIFY_CPU", 1)[1].split()
    return ru.ru_utime + ru.ru_stime, float(tail[0]), ru.ru_maxrss / 1024.0, json.loads(out.read_text()), float(tail[2])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("demo", type=Path, help="a `labid demo --out` directory (features.json and its run file)")
    ap.add_argument("--before", type=Path, help="a tree run back to back with this one (git archive COMMIT)")
    ap.add_argument("--pairs", type=int, default=6)
    args = ap.parse_args(argv)
    trees = {"after": ROOT}
    if args.before:
        trees["before"] = args.before.resolve()
    rows: dict[str, list] = {k: [] for k in trees}
    with tempfile.TemporaryDirectory(prefix="bench_identify_") as tmp:
        work = Path(tmp)
        for i in range(args.pairs):
            order = list(trees) if i % 2 else list(trees)[::-1]   # ABBA: before first on even pairs
            for tag in order:
                cpu, ident, rss, doc, store = run_once(trees[tag], args.demo.resolve(), work)
                load = os.getloadavg()[0]
                rows[tag].append((cpu, ident, rss, doc, cpu - store))
                print(f"pair {i + 1} {tag:6s} process CPU {cpu:5.2f} s (without storing the result "
                      f"{cpu - store:5.2f} s)  identify CPU {ident:5.2f} s  peak RSS {rss:4.0f} MiB  load {load:.2f}",
                      flush=True)
    for tag, r in rows.items():
        print(f"{tag}: process CPU median {statistics.median(x[0] for x in r):.2f} s "
              f"(min {min(x[0] for x in r):.2f}; without storing the result: median "
              f"{statistics.median(x[4] for x in r):.2f}, min {min(x[4] for x in r):.2f}), identify CPU median {statistics.median(x[1] for x in r):.2f} s "
              f"(min {min(x[1] for x in r):.2f}), peak RSS median {statistics.median(x[2] for x in r):.0f} MiB")
    if "before" in rows:
        a, b = rows["before"], rows["after"]
        print("per pair after/before, process:", " ".join(f"{y[0] / x[0]:.2f}" for x, y in zip(a, b)),
              "; without storing:", " ".join(f"{y[4] / x[4]:.2f}" for x, y in zip(a, b)),
              "; identify:", " ".join(f"{y[1] / x[1]:.2f}" for x, y in zip(a, b)))
        pa, pb = a[-1][3]["parameters"], b[-1][3]["parameters"]
        worst = max(abs(pa[n]["value"] - pb[n]["value"]) / pa[n]["std"] for n in pa if pa[n].get("std"))
        print(f"constants: largest difference {worst:.2e} std (last pair); iterations "
              f"{a[-1][3]['iterations']} / {b[-1][3]['iterations']}; consistent "
              f"{a[-1][3]['fit'].get('consistent')} / {b[-1][3]['fit'].get('consistent')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
