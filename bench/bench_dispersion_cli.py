"""Whole-process CPU of ``labid dispersion cfrp --fmax 1e6 --n 10``, A/B against another tree,
with the process floor (interpreter + numpy + the command's own modules, no SAFE work).

    python bench/bench_dispersion_cli.py --before DIR [--repeat N] [--pyc]

Each pair runs the two trees back to back (the host's speed drifts) from a cwd holding no labid
package, with CPU = user + sys of the child (``os.wait4``) and wall beside it. ``--pyc``: with a warm bytecode cache
(PYTHONPYCACHEPREFIX in /tmp; this machine's environment sets PYTHONDONTWRITEBYTECODE=1 and the
trees hold no __pycache__, so by default every labid module is compiled at every start, as the
rows without --pyc show). Output: Markdown for ``bench/RESULTS.md``.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CMD = ["-m", "labid.cli.main", "dispersion", "cfrp", "--fmax", "1e6", "--n", "10"]
FLOOR = {"python": "pass", "numpy": "import numpy",
         "imports": "import numpy, labid.cli.main, labid.cli.dispersion, engine.safe"}


def cpu(tree: Path, args: list[str], pyc: str | None) -> tuple[float, float]:
    """(CPU s, wall s) of one process: user + sys from ``os.wait4`` (microseconds; /usr/bin/time
    rounds to 10 ms, a third of the differences measured here)."""
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", LABID_THREADS="1")
    if pyc:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = pyc
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, *args], env=env, cwd=tempfile.gettempdir(),
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode:
        raise SystemExit(f"{tree}: {args} exited {p.returncode}")
    return ru.ru_utime + ru.ru_stime, wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--repeat", type=int, default=6)
    ap.add_argument("--pyc", action="store_true")
    a = ap.parse_args(argv)
    pyc = tempfile.mkdtemp(prefix="labid_pyc_") if a.pyc else None
    trees = {"before": a.before.resolve(), "after": ROOT}
    if pyc:                                       # warm the cache once per tree
        for t in trees.values():
            cpu(t, CMD, pyc)
    res: dict = {}
    wall: dict = {}
    print(f"load at start: {os.getloadavg()[0]:.2f}; bytecode cache: {'warm' if pyc else 'none'}")
    for i in range(a.repeat):
        for tag, t in (list(trees.items()) if i % 2 == 0 else list(trees.items())[::-1]):  # ABBA
            c, w = cpu(t, CMD, pyc)
            res.setdefault(tag, []).append(c)
            wall.setdefault(tag, []).append(w)
        for tag, code in FLOOR.items():
            c, w = cpu(ROOT, ["-c", code], pyc)
            res.setdefault("floor: " + tag, []).append(c)
            wall.setdefault("floor: " + tag, []).append(w)
    print(f"load at end: {os.getloadavg()[0]:.2f}\n")
    print("| process | CPU s min | median | max | wall s median | per-pair CPU ratio after / before (median) |")
    print("|---|---|---|---|---|---|")
    ratio = statistics.median(x / y for x, y in zip(res["after"], res["before"]))
    for tag, v in res.items():
        r = f"{ratio:.2f}" if tag == "after" else ""
        print(f"| {tag} | {min(v):.3f} | {statistics.median(v):.3f} | {max(v):.3f} | "
              f"{statistics.median(wall[tag]):.3f} | {r} |")
    print("\npairs (before, after) CPU s: " + ", ".join(f"({x:.2f}, {y:.2f})" for x, y in zip(res["before"], res["after"])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
