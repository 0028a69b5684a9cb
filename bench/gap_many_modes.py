"""False alarms with many modes from a finer-mesh generator: the discretisation allowance.

Clean blind cases (bench/blind.py, ``outside=True``: plate mesh 9 + edge rows, not the
diagnoser's 6) with 20 and 30 modes, no shapes (pairing by order), ``--params E1,E2,G12``;
each diagnosed with the per-mode discretisation error in the whitening
(``GapOptions.discretisation``, default) and without it.

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/gap_many_modes.py [--modes 20,30] [--seeds 41,42]
      [--default-only]   (only the default allowance, for a false-alarm count over more seeds)
"""
from __future__ import annotations

import argparse
import copy
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import bench.blind as blind  # noqa: E402
from engine.gap import GapOptions  # noqa: E402
from labid.base import progress  # noqa: E402
from labid.workflows.diagnosis import run_diagnosis  # noqa: E402
from labid.base.threads import configure  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--modes", default="20,30")
    ap.add_argument("--seeds", default="41,42")
    ap.add_argument("--default-only", action="store_true")
    a = ap.parse_args(argv)
    configure()
    progress.set_quiet(True)
    print("| modes | seed | allowance | verdict | chi^2 / threshold | CPU s |")
    print("|---|---|---|---|---|---|")
    for n in (int(v) for v in a.modes.split(",")):
        blind.N_MODES = n
        for seed in (int(v) for v in a.seeds.split(",")):
            c = blind.draw_case(seed, "clean", outside=True, wave_sets=())
            d = copy.deepcopy(c.features)
            d["modal"].pop("mode_shapes", None)
            for disc in ((True,) if a.default_only else (True, False)):
                t = time.process_time()
                r = run_diagnosis(d, options=GapOptions(discretisation=disc), names=("E1", "E2", "G12"))
                g = r["gap"]
                print(f"| {n} | {seed} | {'two meshes' if disc else 'constant only'} | {r['verdict']} | "
                      f"{g['chi2_before']:.1f} / {g['threshold_chi2']:.1f} | {time.process_time() - t:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
