"""Convergence and cost of the independent Ritz plate (bench/independent/ritz_plate.py), and its
agreement with engine.plate at a fine mesh (issue 28).

Run:  OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_ritz.py

For the three specimens of the independent gap bench (bench/blind_independent.py) at their
nominal constants with the declared accelerometer masses: the largest relative change of the
10/20/30/40 lowest frequencies against order 20 with five edge-layer decay lengths (the
reference), per order with the default two, and the CPU time of one solve; then engine.plate at
its default mesh and at 12 and 18 elements against the order-16 Ritz frequencies.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine  # noqa: E402
from bench.blind_independent import ACCEL_MASS_KG, SPECIMENS, _rig  # noqa: E402
from bench.independent.ritz_plate import RitzPlate, plies_from_table  # noqa: E402
from engine.plate import Mesh, PlateModel  # noqa: E402
from labid.inputs.specimen import specimen_from_dict  # noqa: E402


def main() -> int:
    print(machine())
    print("| specimen | order | CPU s | max rel. change, 10 / 20 / 30 / 40 modes |")
    print("|---|---|---|---|")
    refs = {}
    for name, (table_of, *_rest) in SPECIMENS.items():
        table = table_of()
        plies, L, W = plies_from_table(table)
        masses = [(x, y, ACCEL_MASS_KG) for x, y in _rig(L, W)[0]]
        ref = RitzPlate(plies, L, W, order=20, masses=masses, layers=(0.25, 0.5, 1.0, 2.0, 4.0)).solve(40)
        refs[name] = ref.frequencies_hz
        for order in (10, 12, 14, 16):
            t = time.process_time()
            f = RitzPlate(plies, L, W, order=order, masses=masses).solve(40).frequencies_hz
            cpu = time.process_time() - t
            errs = " / ".join(f"{np.max(np.abs(f[:n] / ref.frequencies_hz[:n] - 1)):.1e}" for n in (10, 20, 30, 40))
            print(f"| {name} | {order} | {cpu:.2f} | {errs} |", flush=True)
    print()
    print("| specimen | engine mesh (elements along the longer side) | DOF | max rel. difference to Ritz, 10 / 20 / 40 modes |")
    print("|---|---|---|---|")
    for name, (table_of, *_rest) in SPECIMENS.items():
        table = table_of()
        sp = specimen_from_dict(table)
        L, W = sp.length, sp.width
        masses = [(x, y, ACCEL_MASS_KG) for x, y in _rig(L, W)[0]]
        for n in (None, 12, 18):
            mesh = None if n is None else Mesh.default(L, W, sp.laminate.thickness, n=n)
            m = PlateModel.build(sp.laminate, L, W, mesh).with_point_masses(masses)
            f = m.solve(40).frequencies_hz
            d = " / ".join(f"{np.max(np.abs(f[:k] / refs[name][:k] - 1)):.1e}" for k in (10, 20, 40))
            print(f"| {name} | {'default' if n is None else n} | {m.mesh.n_dof} | {d} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
