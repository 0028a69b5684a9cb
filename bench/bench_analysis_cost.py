"""CPU of the demo's analysis step (issue 29): ``analyze_store`` on the demo's run files.

    LABID_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/python bench/bench_analysis_cost.py RUN.h5 [RUN.h5 ...]
        [--repeat N] [--profile] [--dump DIR]

Times ``labid.workflows.analysis.analyze_store`` (what ``labid analyze`` and the demo's step
2/6 run, without writing anything) on each run file, read-only: CPU (process_time) and wall,
best of ``--repeat``, with the load; the CPU inside ``measure_waves`` (the wave features) apart. ``--profile``: a pyinstrument CPU profile of the first
run. ``--dump DIR``: each run's features as JSON (sorted keys) to compare two code versions
(before = main's tree on PYTHONPATH, after = this branch). Not a test.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

if "PYTHONPATH" not in os.environ:     # with PYTHONPATH (an A/B run): that tree's labid
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--dump", default=None)
    a = ap.parse_args()
    t0, w0 = time.process_time(), time.perf_counter()
    from labid.base import threads
    threads.configure(None)
    from labid.store import RunStore
    from labid.workflows.analysis import AnalysisSettings, analyze_store
    import labid
    from engine.wavefeatures import pipeline
    waves_cpu = [0.0]
    measure = pipeline.measure_waves

    def timed(*args, **kw):
        c = time.process_time()
        try:
            return measure(*args, **kw)
        finally:
            waves_cpu[0] += time.process_time() - c
    pipeline.measure_waves = timed
    print(f"labid from {Path(labid.__file__).parent}; imports {time.process_time() - t0:.2f} s CPU, "
          f"{time.perf_counter() - w0:.2f} s wall; load {os.getloadavg()[0]:.2f}")
    total = 0.0
    for k, run in enumerate(a.runs):
        best = None
        for _ in range(max(a.repeat, 1)):
            prof = None
            if a.profile and k == 0 and best is None:
                from pyinstrument import Profiler
                prof = Profiler(interval=0.002, async_mode="disabled")
                prof.start()
            waves_cpu[0] = 0.0
            c, w = time.process_time(), time.perf_counter()
            with RunStore(run, "r") as st:
                an = analyze_store(st, AnalysisSettings())
            c, w = time.process_time() - c, time.perf_counter() - w
            if prof is not None:
                prof.stop()
                print(prof.output_text(unicode=False, color=False, show_all=False))
            best = (c, w, waves_cpu[0]) if best is None or c < best[0] else best
        total += best[0]
        print(f"{Path(run).name}: analysis {best[0]:.2f} s CPU (wave features {best[2]:.2f}), {best[1]:.2f} s wall "
              f"(best of {max(a.repeat, 1)}); load {os.getloadavg()[0]:.2f}", flush=True)
        if a.dump:
            Path(a.dump).mkdir(parents=True, exist_ok=True)
            (Path(a.dump) / (Path(run).stem + ".json")).write_text(
                json.dumps(an.features, sort_keys=True, indent=1, default=str))
    print(f"total: {total:.2f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
