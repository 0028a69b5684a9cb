"""Import of published records (issue 16): ``labid import`` then ``labid analyze`` on real files.

1. Badiane et al., spruce plates 1, 5, 9 (/work/research/modal/badiane/raw/: the first
   0.74-0.76 s of one hammer record each, CSV ``force,acceleration``, 48 kHz), under
   ``bench/import_real/badiane_rig.toml`` and one specimen file per plate;
2. Vallen Systeme's steel_plate AE example (/work/research/waves/vallenae_steel_plate/: four
   CSV files ``time_us,amplitude_mV``, 5 MHz, each starting at its own time before the
   common zero), under ``bench/import_real/vallenae_rig.toml``: four files on a common
   trigger make one shot, aligned with ``--crop``.

What the rig and specimen files assume is written at their top. Prints, per record, what the
import took from the files and from the options, the analysis's peaks (Badiane, below 2 kHz)
or wave notes (vallenae), and wall and CPU time of each step.

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_import_real.py [OUT_DIR]
"""
from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._machine import machine  # noqa: E402
from labid.cli.main import main  # noqa: E402

HERE = ROOT / "bench" / "import_real"
BADIANE = Path("/work/research/modal/badiane/raw")
VALLENAE = Path("/work/research/waves/vallenae_steel_plate")
RECORDS = {1: "plate_1_frf_1_head.csv", 5: "plate_5_frf_1_head.csv", 9: "plate_9_frf_2_head.csv"}


def timed(argv: list[str]) -> tuple[int, str, str, float, float]:
    """Run ``labid argv`` in process: (exit code, stdout, stderr, wall s, CPU s)."""
    out, err = io.StringIO(), io.StringIO()
    w, c = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue(), time.perf_counter() - w, time.process_time() - c


def step(label: str, argv: list[str]) -> str:
    code, out, err, wall, cpu = timed(argv)
    print(f"  {label}: exit {code}, wall {wall:.2f} s, CPU {cpu:.2f} s")
    if code:
        print("   ", err.strip())
    return out


def main_() -> None:
    d = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="import_real_"))
    print(f"machine: {machine()}")
    for n, name in RECORDS.items():
        run = d / f"badiane_plate{n}.h5"
        run.unlink(missing_ok=True)
        print(f"Badiane plate {n} ({name}):")
        out = step("import", ["import", str(BADIANE / name), "--rig", str(HERE / "badiane_rig.toml"),
                              "--specimen", str(HERE / f"badiane_plate{n}.toml"), "--out", str(run),
                              "--map", "force=force,acceleration=acc1", "--units", "force=N,acc1=m/s^2",
                              "--pretrigger", "40"])
        print("   ", out.strip().replace("\n", "\n    "))
        out = step("analyze --modal-fmax 2000", ["analyze", str(run), "--out", str(run.with_suffix(".json")),
                                                 "--modal-fmax", "2000"])
        peaks = [ln.split() for ln in out.splitlines() if ln.startswith("peak")]
        print("    peaks (Hz, damping):", ", ".join(f"{p[1]} ({p[4]})" for p in peaks))
    run = d / "vallenae.h5"
    run.unlink(missing_ok=True)
    print("vallenae steel_plate, 4 AE channels:")
    files = [str(VALLENAE / f"steel_plate_ae_ch{k}.csv") for k in range(1, 5)]
    out = step("import --crop", ["import", *files, "--rig", str(HERE / "vallenae_rig.toml"), "--specimen",
                                 str(HERE / "vallenae_steel.toml"), "--out", str(run), "--crop", "--map",
                                 ",".join(f"steel_plate_ae_ch{k}:amplitude_mV=ch{k}" for k in range(1, 5))])
    print("   ", out.strip().replace("\n", "\n    "))
    out = step("analyze", ["analyze", str(run), "--out", str(run.with_suffix(".json"))])
    print("   ", out.strip().replace("\n", "\n    "))
    print(f"run files in {d}")


if __name__ == "__main__":
    main_()
