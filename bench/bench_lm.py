"""The project's own Levenberg-Marquardt (engine.fit.lm) against scipy.optimize.least_squares.

    OMP_NUM_THREADS=1 .venv/bin/python bench/bench_lm.py [--starts N]

Both minimise the same whitened misfit (engine.fit.Problem, theta = log p / p_start,
no prior) from the same starts; a forward solve is one SAFE dispersion (waves) or one
plate eigenproblem (modal), counted at the forward model. least_squares: 'trf', a
trial point the model rejects (unphysical constants) returns a residual of 1e6 per
point, default tolerances and tight ones (ftol = xtol = gtol = 1e-12).

Cases: the paper's Table 2 (aluminium, A0 2.5-50 kHz, 20 points, 1 % seeded noise,
E and G from the fifteen published starts; finite-difference Jacobians), and the
CFRP modal-only six-constant problem (10 modes, noise free, analytic Jacobians) from
N random starts within +-50 % of the truth (seed 1, as bench_identify's study).
A "good fit" has chi^2/n < 1 (noise-free modal data: the truth).
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from bench._machine import machine  # noqa: E402
from engine.fit import Coords, Problem, check_start, estimate  # noqa: E402
from engine.forward import modal_block, wave_block  # noqa: E402
from engine.plate import PlateModel  # noqa: E402
from engine.safe import group_velocity  # noqa: E402
from labid.workflows.identification.multistart import random_starts  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402

GPA = 1e9
TABLE2_STARTS = [(120, 50), (115, 45), (110, 50), (105, 55), (100, 40), (95, 55), (90, 50), (85, 35),
                 (80, 30), (75, 35), (70, 25), (65, 30), (65, 35), (60, 30), (55, 35)]
SIX = ("E1", "E2", "nu12", "G12", "G13", "G23")


class Counting:
    """A plate model whose eigen solves are counted."""

    def __init__(self, model):
        self.model, self.solves = model, 0

    def solve(self, *a, **kw):
        self.solves += 1
        return self.model.solve(*a, **kw)

    def eigen_sensitivities(self, *a, **kw):
        return self.model.eigen_sensitivities(*a, **kw)

    def shapes_at(self, *a, **kw):
        return self.model.shapes_at(*a, **kw)


def _physical(mat, start) -> bool:
    try:
        mat.with_params(**start).check()
    except ValueError:
        return False
    return True


def scipy_fit(blocks, names, start, analytic: bool, tight: bool):
    """least_squares on the whitened residual of ``blocks``: (params, cost, status)."""
    p0 = check_start(names, start)
    coords = Coords(names, p0, "log")
    prob = Problem(blocks, coords)
    n = sum(len(b.observed) for b in blocks)

    def fun(th):
        try:
            return prob.residual(th)
        except ValueError:
            return np.full(n, 1e6)

    def jac(th):
        try:
            return np.vstack(prob.block_jacobians(th)[1])
        except ValueError:
            return np.zeros((n, len(names)))

    tol = dict(ftol=1e-12, xtol=1e-12, gtol=1e-12) if tight else {}
    res = least_squares(fun, coords.theta(p0), jac=jac if analytic else "2-point", **tol)
    return coords.as_dict(res.x), 2.0 * res.cost, res.status


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--starts", type=int, default=20, help="random starts of the modal case")
    a = ap.parse_args()
    print(machine())

    # -- Table 2, finite differences -------------------------------------------------
    al = load_specimen("aluminium")
    f = np.linspace(2.5e3, 50e3, 20)
    cg = group_velocity(al.laminate, f, "A0")
    obs = cg * (1 + 0.01 * np.random.default_rng(1).standard_normal(f.size))
    calls = [0]
    blk = wave_block(al.laminate, f, obs, 0.01 * cg)
    inner = blk.predict

    def counted(p):
        calls[0] += 1
        return inner(p)
    blk = replace(blk, predict=counted)
    rows = []
    for label, runner in (("own LM", None), ("least_squares", False), ("least_squares tight", True)):
        calls[0] = 0
        t0, c0 = time.perf_counter(), time.process_time()
        vals, chi = [], []
        for E, G in TABLE2_STARTS:
            st = {"E": E * GPA, "G": G * GPA}
            if runner is None:
                est = estimate([blk], ("E", "G"), st, prior=None)
                vals.append(est.params)
                chi.append(sum(r["chi2"] for r in est.residuals.values()))
            else:
                p, c2, _ = scipy_fit([blk], ("E", "G"), st, analytic=False, tight=runner)
                vals.append(p)
                chi.append(c2)
        rows.append((label, calls[0], time.perf_counter() - t0, time.process_time() - c0,
                     max(v["E"] for v in vals) / min(v["E"] for v in vals) - 1, max(chi) - min(chi)))
    print("\nTable 2 (aluminium A0, 1 % noise), 15 paper starts:")
    print("| estimator | forward solves | wall (s) | CPU (s) | spread of E over starts | spread of chi^2 |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]:.1f} | {r[3]:.1f} | {r[4]:.1e} | {r[5]:.1e} |")

    # -- CFRP modal, analytic Jacobians --------------------------------------------------
    spec = load_specimen("cfrp")
    truth = spec.laminate.plies[0].material.params()
    base = PlateModel.build(spec.laminate, spec.length, spec.width)
    fr = base.solve(10).frequencies_hz
    model = Counting(base)
    mblk, fwd = modal_block(model, fr, 1e-3 * fr)
    mat = spec.laminate.plies[0].material
    starts = [st for st in random_starts({n: truth[n] for n in SIX}, SIX, 2 * a.starts, spread=0.5, seed=1)
              if _physical(mat, st)][:a.starts]
    print(f"\nCFRP modal-only six constants, {len(starts)} random starts (+-50 %):")
    print("| estimator | plate solves | wall (s) | CPU (s) | good fits (chi^2/n < 1) | max rel. error of good fits |")
    print("|---|---|---|---|---|---|")
    for label, runner in (("own LM", None), ("least_squares", False), ("least_squares tight", True)):
        model.solves = 0
        t0, c0 = time.perf_counter(), time.process_time()
        good, err = 0, 0.0
        for st in starts:
            fwd.reset_tracking()
            if runner is None:
                est = estimate([mblk], SIX, st, prior=None, max_iter=60)
                p, c2 = est.params, sum(r["chi2"] for r in est.residuals.values())
            else:
                p, c2, _ = scipy_fit([mblk], SIX, st, analytic=True, tight=runner)
            if c2 / len(fr) < 1.0:
                good += 1
                err = max(err, max(abs(p[n] / truth[n] - 1) for n in SIX))
        print(f"| {label} | {model.solves} | {time.perf_counter() - t0:.1f} | {time.process_time() - c0:.1f} | "
              f"{good}/{len(starts)} | {err:.1e} |")


if __name__ == "__main__":
    main()
