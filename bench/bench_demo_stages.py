"""The demo's stages: CPU of the main process per step, forward-model work, the worker's CPU.

    LABID_THREADS=1 .venv/bin/python bench/bench_demo_stages.py [--out DIR] [--workers N]

Runs ``labid.cli.demo.run_demo`` in this process (imports done first, reported apart) and
prints, at every console line of the demo, the main process' CPU and wall since the last
line and the plate solves, sensitivities, model builds and SAFE calls it made
(bench/_count.py; the worker's are not seen), then the worker's CPU (its rusage, once
joined). With two workers the main process' CPU is the demo's critical path on an idle
2-core machine: the worker's jobs finish before the main process needs them when its CPU
is smaller than the main one's from the first submission on. Not a test.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    t0, w0 = time.process_time(), time.perf_counter()
    from bench._count import Counts
    from bench._machine import machine
    from labid.base import threads
    threads.configure(None)
    from labid.cli.demo import run_demo
    print(machine())
    print(f"imports: {time.process_time() - t0:.2f} s CPU, {time.perf_counter() - w0:.2f} s wall")
    out = a.out or tempfile.mkdtemp(prefix="bench_demo_")
    c = Counts().__enter__()
    prev = [c.snapshot(), time.process_time(), time.perf_counter()]
    start = time.process_time(), time.perf_counter()

    def report(line: str) -> None:
        snap, t, w = c.snapshot(), time.process_time(), time.perf_counter()
        work = Counts.line(Counts.diff(prev[0], snap))
        print(f"      main CPU {t - prev[1]:5.2f} s, wall {w - prev[2]:5.2f} s: {work}", flush=True)
        print(line, flush=True)
        prev[:] = [snap, t, w]

    res = run_demo(out, report=report, workers=a.workers)
    report("(end)")
    c.__exit__()
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"main process CPU {time.process_time() - start[0]:.2f} s (demo only), wall "
          f"{time.perf_counter() - start[1]:.1f} s; worker CPU {ch.ru_utime + ch.ru_stime:.2f} s; "
          f"demo's own 'seconds' {res['seconds']}; load {os.getloadavg()[0]:.1f}")
    print(f"total: {Counts.line(c.snapshot())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
