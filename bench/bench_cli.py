"""Start-up cost of the command line: ``labid --help`` and a whole ``labid dispersion``.

Each command runs as its own process, ``--repeat`` times; wall and CPU (user +
sys of the child, from ``wait4``) are reported as min and median, with the load
average, since the machines are shared. Then ``python -X importtime`` of one
run lists the imports that cost most (cumulative, microseconds). Targets
(issue 11): ``labid --help`` <= 0.25 s CPU; ``labid dispersion cfrp --fmax 2e5``
<= 0.5 s CPU as a whole process. Output: Markdown for ``bench/RESULTS.md``.

    python bench/bench_cli.py [--repeat N]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench._machine import machine  # noqa: E402

CASES = {
    "labid --help": ["--help"],
    "labid dispersion cfrp --fmax 2e5": ["dispersion", "cfrp", "--fmax", "2e5", "--json", os.devnull],
    "labid modes cfrp --n 10": ["modes", "cfrp", "--n", "10", "--json", os.devnull],
}
TARGET = {"labid --help": 0.25, "labid dispersion cfrp --fmax 2e5": 0.5}


def _env() -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT), QT_QPA_PLATFORM="offscreen", MPLBACKEND="Agg")
    return env


def timed(args: list[str]) -> tuple[float, float]:
    """(wall s, CPU s) of one ``python -m labid.cli.main args`` process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "labid.cli.main", *args], env=_env(), cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"labid {' '.join(args)} failed: {proc.stderr.read().decode()[-400:]}")
    return wall, ru.ru_utime + ru.ru_stime


def importtime(args: list[str], top: int = 8) -> list[tuple[int, str]]:
    """The ``top`` costliest imports (cumulative us) of one run, outermost packages first."""
    p = subprocess.run([sys.executable, "-X", "importtime", "-m", "labid.cli.main", *args], env=_env(), cwd=ROOT,
                       capture_output=True, text=True)
    rows = []
    for ln in p.stderr.splitlines():
        if not ln.startswith("import time:") or "cumulative" in ln:
            continue
        _, self_us, cum_us, name = ln.replace("import time:", "|").split("|")
        depth = (len(name) - len(name.lstrip()) - 1) // 2          # one space after the bar
        if depth <= 1:
            rows.append((int(cum_us), name.strip()))
    return sorted(rows, reverse=True)[:top]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args()
    print(f"Machine: {machine()}\n")
    print("| command | wall min / median (s) | CPU min / median (s) | target CPU |")
    print("|---|---|---|---|")
    for name, args in CASES.items():
        timed(args)                                   # warm the file cache and .pyc files
        runs = [timed(args) for _ in range(a.repeat)]
        w, c = [r[0] for r in runs], [r[1] for r in runs]
        tgt = TARGET.get(name)
        print(f"| `{name}` | {min(w):.3f} / {statistics.median(w):.3f} | {min(c):.3f} / "
              f"{statistics.median(c):.3f} | {'<= %.2f' % tgt if tgt else '-'} |")
    print(f"\nload average at end {', '.join(f'{x:.1f}' for x in os.getloadavg())}\n")
    for name, args in CASES.items():
        top = importtime(args)
        print(f"`{name}`, costliest imports (cumulative ms, -X importtime): "
              + ", ".join(f"{n} {us / 1e3:.0f}" for us, n in top))
        print()


if __name__ == "__main__":
    main()
