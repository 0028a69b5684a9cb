"""Cost of ``labid analyze`` on a 100-shot wave run (issue 24: <= 30 s CPU on one core).

The run: the built-in rig (pencil-lead break, MFCs at 5 and 20 cm) on the built-in CFRP
specimen, the simulated plate's moduli 0.714 x the file's (the file 40 % stiff), 100 wave
shots and no hammer hit (``labid acquire --waves 100 --hits 0 --truth 0.714``). Then
``labid analyze`` in this process (the CLI's own entry point), CPU = process time, and the
same with ``--iterate`` for scale (identification included).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_wave_cost.py [N_SHOTS]
"""
from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from labid.cli.main import main as labid  # noqa: E402


def timed(argv):
    out = io.StringIO()
    w, c = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = labid(argv)
    return code, out.getvalue(), time.perf_counter() - w, time.process_time() - c


def main(argv) -> None:
    n = int(argv[0]) if argv else 100
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        run = str(Path(tmp) / "run.h5")
        code, out, w, c = timed(["acquire", "--rig", "default", "--specimen", "cfrp", "--out", run, "--hits", "0",
                                 "--waves", str(n), "--truth", "0.714", "--quiet"])
        print(f"acquire {n} wave shots: exit {code}, {w:.1f} s wall, {c:.1f} s CPU")
        for extra in ([], ["--iterate"]):
            code, out, w, c = timed(["analyze", run, "--out", str(Path(tmp) / "f.json"), "--quiet", *extra])
            print(f"labid analyze {' '.join(extra)}: exit {code}, {w:.1f} s wall, {c:.1f} s CPU")
            for ln in out.splitlines():
                if ln.startswith(("A0", "S0", "pick", "features")):
                    print("  " + ln[:200])


if __name__ == "__main__":
    main(sys.argv[1:])
