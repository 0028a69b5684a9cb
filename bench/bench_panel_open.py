"""The panel opening the demo run (issue 26): CPU in the GUI thread, process CPU, wall time.

Each measurement is a fresh process (offscreen Qt): a ``MainWindow`` is built and shown,
then the clock starts and the run is opened as ``labid gui RUN.h5`` and File > Open do
(``open_run(path, background=True)``: read once in a worker thread, the views restored on
the GUI thread) and the event loop runs until every job of the window has ended (the
opening, the Waves tab's SAFE curves). Reported: GUI-thread CPU (``time.thread_time`` in the
main thread), whole-process CPU (``time.process_time``), wall, and how often the run file was
read: ``services.open_run`` calls, ``read_tree`` calls (structured result groups) and h5py
dataset reads. Target (issue 26): GUI-thread CPU <= 2 s.

``--code DIR`` runs the same measurement against another checkout (e.g. the commit before
issue 26, which opens synchronously in the GUI thread). The run: ``--run RUN.h5``, else
``bench/out/demo/demo_run.h5``, made by ``labid demo`` when absent (~1 min CPU).

    python bench/bench_panel_open.py [--run RUN.h5] [--repeat N] [--code DIR]
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

CHILD = r"""
import inspect, json, sys, time
import h5py
from PySide6.QtCore import QEventLoop, QTimer
from PySide6.QtWidgets import QApplication
import labid.services as services
import labid.store.runstore as runstore
counts = {"open_run": 0, "read_tree": 0, "h5py_reads": 0}
def counted(name, fn):
    def wrapper(*a, **k):
        counts[name] += 1
        return fn(*a, **k)
    return wrapper
services.open_run = counted("open_run", services.open_run)
import labid.store.tree as tree
_rt = tree.read_tree
def read_tree(g):
    counts["read_tree"] += 1
    return _rt(g)
tree.read_tree = read_tree
runstore.read_tree = read_tree
_gi = h5py.Dataset.__getitem__
def getitem(self, *a, **k):
    counts["h5py_reads"] += 1
    return _gi(self, *a, **k)
h5py.Dataset.__getitem__ = getitem
app = QApplication(["bench"])
from labid.gui.main_window import MainWindow
w = MainWindow(); w.resize(1366, 768); w.show(); app.processEvents()
counts.update(open_run=0, read_tree=0, h5py_reads=0)
c0, p0, t0 = time.thread_time(), time.process_time(), time.perf_counter()
background = "background" in inspect.signature(w.open_run).parameters
ok = w.open_run(sys.argv[1], background=True) if background else w.open_run(sys.argv[1])
idle = (lambda: w.idle()) if hasattr(w, "idle") else (lambda: w.job is None and not w._side_jobs)
loop = QEventLoop()
def check():
    if idle():
        loop.quit()
timer = QTimer(); timer.timeout.connect(check); timer.start(5)
loop.exec()
out = dict(gui_cpu_s=time.thread_time() - c0, process_cpu_s=time.process_time() - p0,
           wall_s=time.perf_counter() - t0, background=background, opened=bool(ok),
           run_label=w.run_label.text(), **counts)
print("RESULT " + json.dumps(out))
w.close()
"""


def demo_run() -> Path:
    out = ROOT / "bench" / "out" / "demo"
    run = out / "demo_run.h5"
    if not run.exists():
        subprocess.run([sys.executable, "-m", "labid.cli.main", "demo", "--out", str(out)], check=True,
                       cwd=ROOT, env=dict(os.environ, QT_QPA_PLATFORM="offscreen", MPLBACKEND="Agg"))
    return run


def measure(run: Path, code: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(code), QT_QPA_PLATFORM="offscreen", MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, "-c", CHILD, str(run)], capture_output=True, text=True, env=env,
                       cwd=code)
    line = next((x for x in p.stdout.splitlines() if x.startswith("RESULT ")), None)
    if line is None:
        raise SystemExit(f"the measurement failed:\n{p.stderr[-2000:]}")
    return json.loads(line[7:])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--code", type=Path, default=ROOT, help="checkout to measure (default: this one)")
    a = ap.parse_args()
    run = (a.run or demo_run()).resolve()
    from bench._machine import machine
    print(f"machine: {machine()}")
    print(f"run: {run} ({run.stat().st_size / 1e6:.1f} MB); code: {a.code}")
    rows = [measure(run, a.code.resolve()) for _ in range(a.repeat)]
    med = {k: statistics.median(r[k] for r in rows) for k in ("gui_cpu_s", "process_cpu_s", "wall_s")}
    r0 = rows[0]
    each = ", ".join(f"{r['gui_cpu_s']:.2f}" for r in rows)
    print(f"| opening | GUI-thread CPU s (median of {a.repeat}) | process CPU s | wall s | open_run calls | "
          "read_tree calls | h5py dataset reads |")
    print("|---|---|---|---|---|---|---|")
    print(f"| {'background' if r0['background'] else 'in the GUI thread'} | {med['gui_cpu_s']:.2f} "
          f"({each}) | {med['process_cpu_s']:.2f} | {med['wall_s']:.2f} | "
          f"{r0['open_run']} | {r0['read_tree']} | {r0['h5py_reads']} |")
    print(f"target: GUI-thread CPU <= 2 s: {'met' if med['gui_cpu_s'] <= 2.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
