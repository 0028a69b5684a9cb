"""Threads: the headline workloads with library-default threads, pinned, and labid's choice.

Each workload runs as its own process (the way users run it) in three settings:

* ``default``  -- what the maths libraries do by themselves: one BLAS thread per core
  (``LABID_THREADS`` = cores, the same as no setting at all before labid owned its threads);
* ``pinned``   -- ``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1`` set by the user;
* ``labid``    -- no variable at all: labid's own choice (``labid.base.threads``).

and, with ``--busy``, again beside a CPU hog of this script's own (one spinning
process per core). Wall and CPU (user + sys of the child) are reported with the
load average, since the machines are shared. Results go to stdout as a Markdown
table for ``bench/RESULTS.md``.

    python bench/bench_threads.py [--busy] [--repeat N] [--suite]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench._machine import machine  # noqa: E402
from labid.base.threads import STANDARD_VARS  # noqa: E402

LABID = [sys.executable, "-m", "labid.cli.main"]


def _env(setting: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in STANDARD_VARS and k != "LABID_THREADS"}
    env["QT_QPA_PLATFORM"], env["MPLBACKEND"] = "offscreen", "Agg"
    if setting == "default":
        env["LABID_THREADS"] = str(os.cpu_count() or 1)
    elif setting == "pinned":
        env["OMP_NUM_THREADS"] = env["OPENBLAS_NUM_THREADS"] = "1"
    return env


def _timed(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """(wall s, CPU s of the child and its children) of one run."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.read().decode()[-400:]}")
    return wall, ru.ru_utime + ru.ru_stime


def _hog(stop) -> None:
    x = 0
    while not stop.is_set():
        for _ in range(100000):
            x += 1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--busy", action="store_true", help="also run beside a CPU hog (one process per core)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--suite", action="store_true", help="also time the test suite (minutes)")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="labid_bench_threads_"))
    # the demo's features file, made once
    subprocess.run([*LABID, "demo", "--out", str(work / "demo")], env=_env("labid"), check=True,
                   stdout=subprocess.DEVNULL)
    feats = str(work / "demo" / "features.json")
    workloads = {
        "labid demo": [*LABID, "demo", "--out", str(work / "d")],
        "labid identify (demo features)": [*LABID, "identify", feats],
        "labid identify --starts 8 (2 workers)": [*LABID, "identify", feats, "--starts", "8"],
        "labid diagnose (demo features)": [*LABID, "diagnose", feats],
        "labid modes cfrp --n 30": [*LABID, "modes", "cfrp", "--n", "30"],
        "labid dispersion cfrp --fmax 2e5": [*LABID, "dispersion", "cfrp", "--fmax", "2e5"],
    }
    if args.suite:
        workloads["test suite (pytest -q)"] = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider"]
    print(f"Machine: {machine()}")
    print(f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")
    conditions = ["idle"] + (["busy"] if args.busy else [])
    for cond in conditions:
        stop = mp.Event()
        hogs = [mp.Process(target=_hog, args=(stop,), daemon=True) for _ in range(os.cpu_count() or 1)] \
            if cond == "busy" else []
        for h in hogs:
            h.start()
        try:
            print(f"### {cond}" + (f" (beside {len(hogs)} spinning processes)" if hogs else "")
                  + f"; load average at start {os.getloadavg()[0]:.1f}\n")
            print("| workload | default: wall / CPU (s) | pinned: wall / CPU (s) | labid: wall / CPU (s) |")
            print("|---|---|---|---|")
            for name, cmd in workloads.items():
                cells = []
                for setting in ("default", "pinned", "labid"):
                    runs = [_timed(cmd, _env(setting), ROOT) for _ in range(args.repeat)]
                    wall, cpu = min(r[0] for r in runs), min(r[1] for r in runs)
                    cells.append(f"{wall:.1f} / {cpu:.1f}")
                print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
            print()
        finally:
            stop.set()
            for h in hogs:
                h.join()


if __name__ == "__main__":
    main()
