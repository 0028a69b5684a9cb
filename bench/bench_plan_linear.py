"""Is a stored plan case's error the plan's linear model? (issue 25, wood-like E2 diagnosis)

    OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_plan_linear.py [--cases bench/plan_cases_wood25_s25.jsonl]
        [--constant E2] [--out bench/plan_linear_wood25_s25.jsonl]

For every accepted case of a ``bench_plan.py`` file (reference-mesh truth, full prior), the
case is re-created from its seed (same truth, masses, peaks and noise: asserted against the
stored truth) and the plan's linear model is applied to it, on the REFERENCE mesh (not the
identification's mesh): J = d ln f / d ln p at the truth (engine.plate eigen-sensitivities,
true masses on), W = 1 / sigma^2 of the case's own peaks, and the estimate's error is one
Gauss-Newton step  dp = (Jf' W Jf)^-1 Jf' W r  with r = ln f_measured - ln f(truth's fitted
constants, held constants at nominal, declared 2 g masses) solved exactly. Split into

* noise part: r = ln f_measured - ln f_true (its expected std: sqrt((Jf' W Jf)^-1) per case,
  what the plan's type A is), z = part / that std is N(0, 1) under the model;
* held + mass part: the rest.

Reported: the fit's error against this step (if they agree, the fit is linear: no pairing,
global-stage or non-linearity effect), the std of each part against its expectation, and
their sample correlation (0 in expectation: the draws are independent). ~1 s CPU per case.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import bench.bench_plan as bp  # noqa: E402
from bench._machine import machine  # noqa: E402
from engine.plate import PlateModel  # noqa: E402
from engine.plate.convergence import reference_mesh  # noqa: E402

HELD = ("nu12", "G13", "G23")


def one_case(spec, plan: dict, stored: dict, seed: int) -> dict:
    """The linear step for stored case ``stored`` (relative errors of the fitted constants)."""
    mat = spec.laminate.plies[0].material
    nom = mat.params()
    fitted = tuple(plan["fitted"])
    names = fitted + HELD
    keep: dict = {}

    def truth_modes(spec_, plan_, truth, masses):
        m = bp.PlateModel.build(spec_.laminate, spec_.length, spec_.width,
                                reference_mesh(spec_.length, spec_.width, spec_.laminate.thickness))
        m = m.with_point_masses([(x, y, mk) for (x, y), mk in zip(plan_["sensors"], masses)])
        modes = m.solve(90, params=truth)
        keep.update(model=m, modes=modes)
        return modes.frequencies_hz, lambda pts: m.shapes_at(modes, pts)

    rng = np.random.default_rng([seed, stored["k"]])
    truth = bp.draw_truth(mat, rng)
    assert all(abs(truth[n] / stored["truth"][n] - 1) < 1e-12 for n in truth), "case not reproduced"
    masses = bp.MASS_KG * (1 + bp.MASS_U * rng.standard_normal(len(plan["sensors"])))
    saved, bp.truth_modes = bp.truth_modes, truth_modes
    try:
        fm, sig, _ = bp.peaks(spec, plan, truth, masses, rng)
    finally:
        bp.truth_modes = saved
    seen = bp.TRUTH["modes"]
    model, modes = keep["model"], keep["modes"]
    d = model.eigen_sensitivities(modes, list(names), params=truth)          # d omega^2 / d p
    J = (d * np.array([truth[p] for p in names]) / (2 * modes.omega2[:, None]))[seen]
    f_true = modes.frequencies_hz[seen]
    declared = PlateModel.build(spec.laminate, spec.length, spec.width,
                                reference_mesh(spec.length, spec.width, spec.laminate.thickness))
    declared = declared.with_point_masses([(x, y, bp.MASS_KG) for x, y in plan["sensors"]])
    p_fit = dict(truth)
    p_fit.update({p: nom[p] for p in HELD})
    f_model = declared.solve(90, params=p_fit).frequencies_hz[seen]
    w = (f_true / sig) ** 2
    Jf = J[:, :len(fitted)]
    Finv = np.linalg.inv((Jf.T * w) @ Jf)
    step = Finv @ (Jf.T * w)
    total, noise = step @ np.log(fm / f_model), step @ np.log(fm / f_true)
    return {"k": stored["k"], "fit": {n: stored["err"][n] for n in fitted},
            "linear": dict(zip(fitted, map(float, total))), "noise": dict(zip(fitted, map(float, noise))),
            "noise_std": dict(zip(fitted, map(float, np.sqrt(np.diag(Finv)))))}


def summary(rows: list[dict], nm: str) -> list[str]:
    g = lambda part: np.array([r[part][nm] for r in rows])  # noqa: E731
    fit, lin, noise, sd = g("fit"), g("linear"), g("noise"), g("noise_std")
    held = lin - noise
    n = len(rows)
    se = 1 / math.sqrt(2 * (n - 1))
    return [f"  {nm}: {n} accepted cases; fit - linear step: rms {100 * np.sqrt(np.mean((fit - lin) ** 2)):.4f} %, "
            f"correlation {np.corrcoef(fit, lin)[0, 1]:.4f}",
            f"  spread: fits {100 * fit.std(ddof=1):.3f} %, linear step {100 * lin.std(ddof=1):.3f} %",
            f"  noise part {100 * noise.std(ddof=1):.3f} % against its expectation {100 * np.sqrt(np.mean(sd ** 2)):.3f} %"
            f" (z std {np.std(noise / sd, ddof=1):.2f} +- {se:.2f})",
            f"  held + mass part {100 * held.std(ddof=1):.3f} %; sample correlation of the two parts "
            f"{np.corrcoef(noise, held)[0, 1]:+.2f} (0 +- {1 / math.sqrt(n):.2f} expected)",
            f"  expected spread of the linear model at these draws: "
            f"{100 * math.sqrt(np.mean(sd ** 2) + held.var(ddof=1)):.3f} %"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="bench/plan_cases_wood25_s25.jsonl")
    ap.add_argument("--constant", default="E2")
    ap.add_argument("--seed", type=int, default=25)
    ap.add_argument("--out", default="bench/plan_linear_wood25_s25.jsonl")
    args = ap.parse_args(argv)
    print(machine(), flush=True)
    rows = [json.loads(x) for x in Path(args.cases).read_text().splitlines()]
    plan = next(r for r in rows if r["type"] == "plan")
    assert plan.get("truth_model", "reference") == "reference", "the linear step re-creates reference-mesh cases"
    spec = bp.specimen("wood") if plan["specimen"] == bp.WOOD["name"] else bp.specimen(plan["specimen"])
    out = Path(args.out)
    done = {json.loads(x)["k"]: json.loads(x) for x in out.read_text().splitlines()} if out.exists() else {}
    for r in rows:
        if r["type"] != "case" or not bp.accepted(r) or r["k"] in done:
            continue
        t = time.process_time()
        done[r["k"]] = one_case(spec, plan, r, args.seed)
        with out.open("a") as fh:
            fh.write(json.dumps(done[r["k"]]) + "\n")
        print(f"  {r['k']:3d} fit {100 * r['err'][args.constant]:+.3f} % linear "
              f"{100 * done[r['k']]['linear'][args.constant]:+.3f} % ({time.process_time() - t:.1f} s)",
              file=sys.stderr, flush=True)
    print("\n".join(summary([done[k] for k in sorted(done)], args.constant)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
