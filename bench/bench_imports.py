"""What each command imports, and its CPU: the lazy facade (issue 29) A/B against another tree.

Each sample is a fresh interpreter importing ``labid.cli.main`` and the command's module, then
what the command calls when it runs (``RUNS``: e.g. ``labid diagnose`` resolves
``services.run_diagnosis`` and imports the diagnosis): CPU of those imports
(``time.process_time``), the number of modules and which of the heavy packages (``HEAVY``)
are loaded. Trees alternate sample by sample (the host's speed drifts); min and median are
reported with the load average. Output: Markdown for ``bench/RESULTS.md``.

    python bench/bench_imports.py [--before DIR] [--repeat N] [--commands diagnose,identify,...]

``--before DIR``: a checkout to compare with (``git archive COMMIT | tar -x -C DIR``).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench._machine import machine  # noqa: E402

#: per command, what it imports at run time beyond its module (the facade's names it calls)
RUNS = {
    "diagnose": "from labid import services\nservices.run_diagnosis, services.store_for_features\n"
                "import labid.workflows.diagnosis, engine.gap",
    "identify": "from labid import services\nservices.run_identification, services.store_for_features",
    "analyze": "from labid import services\nservices.run_analysis, services.features_path",
    "report": "from labid import services\nservices.open_run, services.read_result, services.run_calibration\n"
              "import labid.store",
    "dispersion": "import engine.safe.curves",
    "modes": "",
}
#: packages whose presence the table shows (the ones the facade used to load for every command)
HEAVY = ("mock_hw", "labid.workflows.analysis", "labid.workflows.plan", "labid.workflows.acquisition",
         "labid.io", "labid.display", "h5py", "engine.modal", "engine.wavefeatures", "pywt", "tomlkit",
         "scipy.optimize", "scipy.signal", "scipy.stats", "scipy.linalg")

CODE = """import time, sys, json
t = time.process_time()
import labid.cli.main, labid.cli.{cmd}
{run}
cpu = time.process_time() - t
heavy = [h for h in {heavy!r} if h in sys.modules]
print(json.dumps({{"cpu": cpu, "n": len(sys.modules), "heavy": heavy}}))
"""


def sample(tree: Path, cmd: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", QT_QPA_PLATFORM="offscreen")
    code = CODE.format(cmd=cmd, run=RUNS[cmd], heavy=HEAVY)
    p = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(tree), capture_output=True, text=True)
    if p.returncode:
        raise SystemExit(f"{tree}: {cmd}: {p.stderr[-400:]}")
    return json.loads(p.stdout.splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--commands", default=",".join(RUNS))
    a = ap.parse_args(argv)
    trees = ([("before", a.before)] if a.before else []) + [("after", ROOT)]
    cmds = [c.strip() for c in a.commands.split(",") if c.strip()]
    print(f"machine: {machine()}; load before: {os.getloadavg()[0]:.2f}")
    res: dict = {}
    for _ in range(a.repeat):
        for cmd in cmds:
            for tag, tree in trees:
                res.setdefault((cmd, tag), []).append(sample(tree, cmd))
    print(f"load after: {os.getloadavg()[0]:.2f}\n")
    print("| command | tree | import CPU s min / median | modules | heavy packages loaded |")
    print("|---|---|---|---|---|")
    for cmd in cmds:
        for tag, _ in trees:
            rs = res[(cmd, tag)]
            cpu = [r["cpu"] for r in rs]
            print(f"| {cmd} | {tag} | {min(cpu):.3f} / {statistics.median(cpu):.3f} | {rs[0]['n']} | "
                  f"{', '.join(rs[0]['heavy']) or '-'} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
