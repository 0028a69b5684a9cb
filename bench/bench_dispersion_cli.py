"""Whole-process CPU of ``labid dispersion cfrp --fmax 1e6 --n 10``, A/B against another tree,
with the process floor (interpreter + numpy + the command's own modules, no SAFE work).

    python bench/bench_dispersion_cli.py --before DIR [--repeat N] [--pyc]

Each pair runs the two trees back to back (the host's speed drifts) from a cwd holding no labid
package, under ``/usr/bin/time`` (CPU = user + sys). ``--pyc``: with a warm bytecode cache
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
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CMD = ["-m", "labid.cli.main", "dispersion", "cfrp", "--fmax", "1e6", "--n", "10"]
FLOOR = {"python": "pass", "numpy": "import numpy",
         "imports": "import numpy, labid.cli.main, labid.cli.dispersion, engine.safe"}


def cpu(tree: Path, args: list[str], pyc: str | None) -> float:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", LABID_THREADS="1")
    if pyc:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = pyc
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    p = subprocess.run(["/usr/bin/time", "-f", "TIME %U %S", sys.executable, *args], env=env,
                       cwd=tempfile.gettempdir(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       text=True, check=True)
    u, s = next(ln for ln in p.stderr.splitlines() if ln.startswith("TIME ")).split()[1:]
    return float(u) + float(s)


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
    print(f"load at start: {os.getloadavg()[0]:.2f}; bytecode cache: {'warm' if pyc else 'none'}")
    for _ in range(a.repeat):
        for tag, t in trees.items():
            res.setdefault(tag, []).append(cpu(t, CMD, pyc))
        for tag, code in FLOOR.items():
            res.setdefault("floor: " + tag, []).append(cpu(ROOT, ["-c", code], pyc))
    print(f"load at end: {os.getloadavg()[0]:.2f}\n")
    print("| process | CPU s min | median | max | per-pair ratio after / before (median) |")
    print("|---|---|---|---|---|")
    ratio = statistics.median(x / y for x, y in zip(res["after"], res["before"]))
    for tag, v in res.items():
        r = f"{ratio:.2f}" if tag == "after" else ""
        print(f"| {tag} | {min(v):.2f} | {statistics.median(v):.2f} | {max(v):.2f} | {r} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
