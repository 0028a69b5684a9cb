"""Cost of the thickness field (PlateModel.with_thickness_field) on the default CFRP mesh.

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/bench_taper.py

CPU per re-assembly of K and M data for new constants (PlateModel._data) and per
10-mode solve, nominal plate against the same plate with a 6 % linear taper;
the one-time cost of building the field (weights and weighted scatter).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.blind import _laminate, nominal_specimen_table  # noqa: E402
from engine.plate import PlateModel  # noqa: E402


def cpu(fn, n):
    t = time.process_time()
    for i in range(n):
        fn(i)
    return (time.process_time() - t) / n


def main() -> int:
    lam, L, W = _laminate(nominal_specimen_table())
    base = PlateModel.build(lam, L, W)
    p0 = next(iter(lam.materials.values())).params()
    t = time.process_time()
    tap = base.with_thickness_field(lambda x, y: 1.0 + 0.06 * (2.0 * x / L - 1.0))
    c, inert = tap.coefficients(p0)
    tap._data(c, inert)                  # builds the weighted scatter once
    build = time.process_time() - t
    print(f"mesh {base.mesh.nx} x {base.mesh.ny} elements, {base.mesh.n_dof} DOF; field build {build * 1e3:.1f} ms CPU")
    for name, m in (("nominal", base), ("taper 6 %", tap)):
        m.solve(10, params=p0)
        d = cpu(lambda i: m._data(c * (1 + 1e-3 * i), inert), 20)
        s = cpu(lambda i: m.solve(10, params={**p0, "E1": p0["E1"] * (1 + 1e-3 * (i + 1))}), 10)
        print(f"{name:10s} K, M data {d * 1e3:6.1f} ms CPU   solve(10) {s * 1e3:6.1f} ms CPU")
    f0 = base.solve(10, params=p0).frequencies_hz
    f1 = tap.solve(10, params=p0).frequencies_hz
    print("relative shift of the 10 modes:", np.array2string(f1 / f0 - 1, precision=5))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
