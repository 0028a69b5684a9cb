"""Cost of ``labid identify`` on a features file: CPU, wall, peak RSS and forward-model calls.

    LABID_THREADS=1 .venv/bin/python bench/bench_speed.py FEATURES.json [--repeat 2] [--args "..."]

Not a test: prints one line per run of ``python -m labid.cli.main identify FEATURES.json ARGS``
(a child process: CPU = user + sys of the child, wall, peak RSS) and, from one run in this
process, the number of plate eigen-solves (``PlateModel.solve``: all, and repeats of a
parameter set already solved) and of SAFE group-velocity predictions, with their CPU.
Used for bench/RESULTS.md, section "Speed of identify and the demo (h2)"; the features
were those ``labid demo --out DIR`` writes (DIR/features.json, copied alone to another
folder so that identify finds no run file to write into).
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import io
import os
import resource
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench._machine import machine  # noqa: E402


def child_run(features: str, args: list[str], root: Path = ROOT) -> dict:
    """One ``labid identify`` in a child process: CPU (s), wall (s), peak RSS (MB)."""
    env = {**os.environ, "PYTHONPATH": str(root), "LABID_THREADS": os.environ.get("LABID_THREADS", "1")}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "labid.cli.main", "identify", features, "--quiet", *args], env=env,
                   check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"cpu": cpu, "wall": wall, "rss_mb": after.ru_maxrss / 1024.0}


def counted_run(features: str, args: list[str]) -> dict:
    """One ``labid identify`` in this process, counting plate solves and SAFE predictions."""
    import engine.plate.model as pm
    import engine.forward.waves as fw
    from labid.cli import main as cli

    seen: collections.Counter = collections.Counter()
    stats = {"solves": 0, "repeats": 0, "solve_cpu": 0.0, "safe": 0, "safe_cpu": 0.0}
    solve0, gv0 = pm.PlateModel.solve, fw.safe_group_velocity

    def solve(self, n_modes=10, params=None, material=None, sigma=None):
        key = (id(self), n_modes, tuple(sorted((params or {}).items())))
        seen[key] += 1
        stats["solves"] += 1
        stats["repeats"] += seen[key] > 1
        t = time.process_time()
        try:
            return solve0(self, n_modes, params, material, sigma)
        finally:
            stats["solve_cpu"] += time.process_time() - t

    def group_velocity(*a, **k):
        stats["safe"] += 1
        t = time.process_time()
        try:
            return gv0(*a, **k)
        finally:
            stats["safe_cpu"] += time.process_time() - t

    pm.PlateModel.solve = solve
    fw.safe_group_velocity = group_velocity     # what engine.forward.waves.wave_block calls
    t = time.process_time()
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            cli.main(["identify", features, "--quiet", *args])
    except SystemExit:
        pass
    finally:
        pm.PlateModel.solve, fw.safe_group_velocity = solve0, gv0
    stats["cpu"] = time.process_time() - t
    return stats


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("features")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--args", default="", help="further identify arguments, e.g. \"--start E1=110e9\"")
    ap.add_argument("--root", default=str(ROOT), help="labid source tree to measure (default: this one)")
    a = ap.parse_args()
    root = Path(a.root).resolve()
    sys.path.insert(0, str(root))
    args = shlex.split(a.args)
    print(machine())
    print(f"tree: {root}")
    for i in range(a.repeat):
        r = child_run(a.features, args, root)
        print(f"run {i + 1}: CPU {r['cpu']:.1f} s, wall {r['wall']:.1f} s, peak RSS {r['rss_mb']:.0f} MB, "
              f"load {os.getloadavg()[0]:.2f}")
    s = counted_run(a.features, args)
    print(f"in-process: CPU {s['cpu']:.1f} s; plate solves {s['solves']} ({s['repeats']} repeats), "
          f"{s['solve_cpu']:.1f} s; SAFE group-velocity predictions {s['safe']}, {s['safe_cpu']:.1f} s")


if __name__ == "__main__":
    main()
