"""Wall and CPU time of `labid demo` (the README's timing; issue 17).

    python bench/bench_demo.py [--out DIR] [--runs N]

Runs ``python -m labid.cli.main demo --quiet --out DIR`` N times (default 1) in a child process
and prints, per run, the wall time, the child's CPU time (user + system, from
``resource.getrusage(RUSAGE_CHILDREN)``), its peak memory and the load average before
and after, with the machine line of ``bench/_machine.py``. CPU time is the fixed cost;
wall time depends on what else the machine runs.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402


def one_run(out: Path) -> dict:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "labid.cli.main", "demo", "--quiet", "--out", str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"wall_s": wall, "user_s": after.ru_utime - before.ru_utime, "sys_s": after.ru_stime - before.ru_stime,
            "peak_mb": after.ru_maxrss / 1024, "load_before": load0, "load_after": os.getloadavg()[0]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="demo output folder (default: a temporary one)")
    ap.add_argument("--runs", type=int, default=1)
    args = ap.parse_args()
    print(machine())
    print("| run | wall (s) | CPU user + sys (s) | peak memory (MB) | load 1-min before / after |")
    print("| --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as d:
        for i in range(args.runs):
            r = one_run(Path(args.out or d) / f"demo{i}")
            print(f"| {i + 1} | {r['wall_s']:.1f} | {r['user_s'] + r['sys_s']:.1f} ({r['user_s']:.1f} + "
                  f"{r['sys_s']:.1f}) | {r['peak_mb']:.0f} | {r['load_before']:.1f} / {r['load_after']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
