"""CPU and accuracy of one plate solve, warm (engine/plate/warm.py) against ARPACK (issue 29).

    OMP_NUM_THREADS=1 .venv/bin/python bench/bench_warm_solve.py [--steps 8] [--ritz-order 14]

Per plate (the demo's CFRP 330x330 at 56 modes, the wood-like spruce 580x215 at 56, a square
aluminium 500x500 at 40: degenerate pairs) and per relative step d of every constant (a random
walk of ``--steps`` solves, log-normal steps of size d, as inside an LM fit): CPU of the solve on
the walking model (warm when certified, else ARPACK), CPU of the same solve on a fresh model
(ARPACK, no history), the largest relative difference of the eigenvalues, and how many were
answered warm. Then the outside check: the independent Rayleigh-Ritz plate
(bench/independent/ritz_plate.py, shares no code with engine.plate) at the demo plate's
constants and at the walk's last constants, against the warm and the ARPACK answers. Not a test.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from bench._machine import machine  # noqa: E402
from engine.laminate import Laminate, Material, Ply  # noqa: E402
from engine.plate import PlateModel  # noqa: E402
from engine.plate import warm as W  # noqa: E402

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9, density=1560.0, name="T300")
SPRUCE = Material(E1=11.0e9, E2=0.78e9, nu12=0.35, G12=0.70e9, G13=0.65e9, G23=0.05e9, density=400.0,
                  E3=0.5e9, nu13=0.40, nu23=0.40, name="spruce")
AL = Material.isotropic_from(71.04e9, 2700.0, G=25.32e9, name="Al")
CFRP_ANGLES = [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0]
PLATES = [("demo CFRP 330x330", Laminate(tuple(Ply(T300, a, 1.3333e-4) for a in CFRP_ANGLES)), 0.33, 0.33, 56,
           ("E1", "E2", "G12", "nu12", "G13", "G23")),
          ("wood-like 580x215", Laminate((Ply(SPRUCE, 0.0, 0.0048),)), 0.58, 0.215, 56,
           ("E1", "E2", "G12", "nu12", "G13", "G23")),
          ("square Al 500x500", Laminate((Ply(AL, 0.0, 3.175e-3),)), 0.5, 0.5, 40, ("E", "G"))]


def start_of(mat: Material, names) -> dict:
    return {k: {"E": mat.E1, "G": mat.G12}.get(k, getattr(mat, k, None)) for k in names}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--ritz-order", type=int, default=14)
    a = ap.parse_args()
    print(machine())
    rng = np.random.default_rng(29)
    print("| plate | step d | solves | answered warm | CPU per solve, walking model (ms, median) "
          "| CPU per solve, fresh model = ARPACK (ms, median) | max rel. eigenvalue difference |")
    print("|---|---|---|---|---|---|---|")
    last = {}
    for label, lam, L, Wd, n, names in PLATES:
        p0 = start_of(lam.plies[0].material, names)
        for d in (1e-5, 1e-4, 1e-3, 1e-2):
            model = PlateModel.build(lam, L, Wd)
            model.solve(n, params=p0)
            p, tw, tc, err = dict(p0), [], [], 0.0
            w0 = W.COUNTS["warm"]
            for _ in range(a.steps):
                p = {k: v * float(np.exp(d * rng.standard_normal())) for k, v in p.items()}
                t = time.process_time()
                got = model.solve(n, params=p)
                tw.append(time.process_time() - t)
                fresh = PlateModel.build(lam, L, Wd)
                t = time.process_time()
                ref = fresh.solve(n, params=p)
                tc.append(time.process_time() - t)
                err = max(err, float(np.max(np.abs(got.omega2 / ref.omega2 - 1.0))))
            nw = W.COUNTS["warm"] - w0
            print(f"| {label} | {d:g} | {a.steps} | {nw} | {1e3 * np.median(tw):.0f} | {1e3 * np.median(tc):.0f} "
                  f"| {err:.1e} |", flush=True)
            if label.startswith("demo"):
                last[d] = (p, got.frequencies_hz, ref.frequencies_hz)
    # the outside check: independent Ritz plate
    sys.path.insert(0, str(ROOT / "bench" / "independent"))
    from ritz_plate import Ply as RPly, RitzPlate
    print("\nIndependent Rayleigh-Ritz plate (order %d) against the FE default mesh, demo CFRP, 20 modes:"
          % a.ritz_order)
    for d, (p, fw, fc) in last.items():
        const = {k: p[k] for k in ("E1", "E2", "G12", "nu12", "G13", "G23")}
        plies = [RPly(const, 1560.0, ang, 1.3333e-4) for ang in CFRP_ANGLES]
        fr = RitzPlate(plies, 0.33, 0.33, order=a.ritz_order).solve(20).frequencies_hz
        print(f"  after the d = {d:g} walk: FE warm-walk / Ritz - 1: max |.| {np.max(np.abs(fw[:20] / fr - 1)):.3e}; "
              f"FE ARPACK / Ritz - 1: {np.max(np.abs(fc[:20] / fr - 1)):.3e}; "
              f"the two FE answers differ by {np.max(np.abs(fw[:20] / fc[:20] - 1)):.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
