"""Identification on realistic peak lists (issue 12). Not a test: prints a table and a summary.

    LABID_THREADS=1 OMP_NUM_THREADS=1 .venv/bin/python bench/bench_identify_real.py [--cases 200] [--seed 12]

Each case: one of nine free plates (CFRP [0/+-45]2s 1.6 mm at 330x330, 400x250, 500x200 mm;
a wood-like spruce plate 4.8 mm, E1/E2 = 14, G23 << G12, at 580x215, 400x300, 300x300 mm;
aluminium 3.175 mm at 1000x1000, 600x400, 500x200 mm), its true constants nominal. The
peak list is the first N modes (N drawn in 30..60) of the converged REFERENCE mesh
(engine.plate.convergence.reference_mesh, 2x the identification's elements per direction),
with Gaussian noise of the stated 0.1 % sigma; 0-3 modes per octave dropped as a single
response point drops them (the modes of smallest |w| at a random response point, from the
reference FE shapes; the point is declared in the features as the accelerometer); 0-2
spurious peaks at random frequencies in the band. The fit: E1, E2, G12 (aluminium: E, G)
from a start drawn uniformly within +-30 % of the truth on each, the others at nominal.

Recorded per case: every fitted constant within 2 std of the truth; "confidently wrong"
(some |error| > 3 std while the fit says consistent); consistent; CPU of the fit
(``labid.workflows.identification.run``: global stage, pairing, fits, verdict) and of the setup
(problem_from_features: the default model's fine-mesh correction).
"""
from __future__ import annotations

import argparse
import copy
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from bench._count import Counts  # noqa: E402
from bench._machine import machine  # noqa: E402
from engine.plate import PlateModel  # noqa: E402
from engine.plate.convergence import reference_mesh  # noqa: E402
from labid.workflows.identification import problem_from_features, run  # noqa: E402
from labid.inputs.specimen import load_specimen, specimen_from_dict  # noqa: E402

CFRP = load_specimen("cfrp")
WOOD = {"name": "wood-like spruce", "plate": {"length": 0.58, "width": 0.215},
        "materials": {"spruce": {"density": 400.0, "E1": 11.0e9, "E2": 0.78e9, "nu12": 0.35, "G12": 0.70e9,
                                 "G13": 0.65e9, "G23": 0.05e9, "E3": 0.5e9, "nu13": 0.40, "nu23": 0.40}},
        "layup": {"material": "spruce", "angles_deg": [0], "ply_thickness": 0.0048}}
AL = {"name": "aluminium", "plate": {"length": 1.0, "width": 1.0},
      "materials": {"Al": {"density": 2700.0, "E": 71.04e9, "G": 25.32e9}},
      "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": 3.175e-3}}


def _plates():
    out = []
    cf = {"name": "cfrp", "plate": {}, "materials": {"T300": {"density": 1560.0, "E1": 136.7e9, "E2": 9.0e9,
                                                              "nu12": 0.30, "G12": 5.0e9, "G13": 5.08e9,
                                                              "G23": 3.16e9}},
          "layup": {"material": "T300", "angles_deg": [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0],
                    "ply_thickness": 1.3333e-4}}
    for base, sizes in ((cf, ((0.33, 0.33), (0.40, 0.25), (0.50, 0.20))),
                        (WOOD, ((0.58, 0.215), (0.40, 0.30), (0.30, 0.30))),
                        (AL, ((1.0, 1.0), (0.60, 0.40), (0.50, 0.20)))):
        for L, W in sizes:
            d = copy.deepcopy(base)
            d["plate"] = {"length": L, "width": W}
            d["name"] = f"{base['name']} {L * 1e3:.0f}x{W * 1e3:.0f}"
            out.append(specimen_from_dict(d))
    return out


_REF: dict = {}


def reference(spec, n: int):
    """(model, modes) of the reference mesh, cached per plate."""
    if spec.name not in _REF:
        lam = spec.laminate
        model = PlateModel.build(lam, spec.length, spec.width, reference_mesh(spec.length, spec.width, lam.thickness))
        _REF[spec.name] = (model, model.solve(n))
    return _REF[spec.name]


def draw_case(k: int, rng: np.random.Generator, plates) -> tuple:
    spec = plates[k % len(plates)]
    iso = spec.laminate.plies[0].material.isotropic
    model, modes = reference(spec, 64)
    N = int(rng.integers(30, 61))
    f = modes.frequencies_hz[:N].copy()
    resp = np.array([rng.uniform(0.05, 0.95) * spec.length, rng.uniform(0.05, 0.95) * spec.width])
    grid = np.array([[x, y] for x in np.linspace(0, spec.length, 15) for y in np.linspace(0, spec.width, 15)])
    with np.errstate(invalid="ignore", divide="ignore"):   # in-plane modes: no transverse w
        vis = np.nan_to_num(np.abs(model.shapes_at(modes, resp[None, :]))[:N, 0]
                            / np.abs(model.shapes_at(modes, grid)).max(axis=1)[:N])
    drop: set[int] = set()
    lo = f[0]
    while lo < f[-1]:
        idx = np.flatnonzero((f >= lo) & (f < 2 * lo))
        k_drop = min(int(rng.integers(0, 4)), max(idx.size - 1, 0))
        drop |= set(idx[np.argsort(vis[idx])[:k_drop]].tolist())
        lo *= 2
    keep = np.array([i for i in range(N) if i not in drop])
    sig = 1e-3 * f[keep]
    meas = f[keep] * (1 + 1e-3 * rng.standard_normal(keep.size))
    n_sp = int(rng.integers(0, 3))
    sp = np.exp(rng.uniform(np.log(f[0]), np.log(f[-1]), n_sp))
    allf = np.concatenate([meas, sp])
    alls = np.concatenate([sig, 1e-3 * sp])
    o = np.argsort(allf)
    doc = {"modal": {"frequencies_hz": allf[o].tolist(), "sigma_hz": alls[o].tolist()},
           "rig": {"accelerometers": [{"x": float(resp[0]), "y": float(resp[1])}]}}
    mat = spec.laminate.plies[0].material.params()
    names = ("E", "G") if iso else ("E1", "E2", "G12")
    truth = {n: mat[n] for n in names}
    mat_obj = spec.laminate.plies[0].material
    while True:   # +-30 % on each, redrawn when unphysical (isotropic: nu = E/2G - 1 < 0.5)
        start = {n: truth[n] * float(rng.uniform(0.7, 1.3)) for n in names}
        try:
            mat_obj.with_params(**start).check()
            break
        except ValueError:
            continue
    return spec, doc, names, truth, start, {"N": N, "dropped": len(drop), "spurious": n_sp}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=200)
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--out", default=None, help="also write one JSON line per case (constants, stds, verdict)")
    args = ap.parse_args(argv)
    fh = open(args.out, "w") if args.out else None
    print(machine())
    plates = _plates()
    rng = np.random.default_rng(args.seed)
    rows = []
    t_all = time.perf_counter()
    counts = Counts().__enter__()         # plate solves per fit (bench only)
    for k in range(args.cases):
        spec, doc, names, truth, start, info = draw_case(k, rng, plates)
        t0 = time.process_time()
        prob = problem_from_features(doc, specimen=spec)
        t1 = time.process_time()
        n0 = sum(n for lab, (n, _) in counts.snapshot().items() if lab.startswith("plate solve"))
        b0 = counts.snapshot().get("surrogate shift-invert block", (0, 0.0))[0]
        est = run(prob, names, start)
        t2 = time.process_time()
        solves = sum(n for lab, (n, _) in counts.snapshot().items() if lab.startswith("plate solve")) - n0
        blocks = counts.snapshot().get("surrogate shift-invert block", (0, 0.0))[0] - b0
        z = {n: (est.params[n] - truth[n]) / est.std[i] for i, n in enumerate(est.names)}
        err = {n: est.params[n] / truth[n] - 1 for n in est.names}
        within2 = all(abs(v) <= 2 for v in z.values())
        cons = bool(est.fit["consistent"])
        wrong = cons and any(abs(v) > 3 for v in z.values())
        rows.append({"plate": spec.name, **info, "within2": within2, "consistent": cons, "wrong": wrong,
                     "identified": bool(est.fit["identified"]), "cpu_fit": t2 - t1, "cpu_setup": t1 - t0,
                     "max_err": max(abs(v) for v in err.values()), "chi2nu": est.fit["chi2_per_dof"],
                     "solves": solves, "blocks": blocks})
        r = rows[-1]
        if fh:
            fh.write(json.dumps({"case": k, **{kk: v for kk, v in r.items() if kk not in ("cpu_fit", "cpu_setup")},
                                 "params": est.params, "std": dict(zip(est.names, map(float, est.std))),
                                 "chi2": est.fit["chi2"], "cpu_fit": r["cpu_fit"]}) + "\n")
            fh.flush()
        print(f"{k:3d} {spec.name:<24} N={info['N']:2d} drop={info['dropped']:2d} spur={info['spurious']} "
              f"max|err| {100 * r['max_err']:6.2f} %  max|z| {max(abs(v) for v in z.values()):5.2f}  "
              f"chi2/nu {r['chi2nu']:8.3g} {'consistent' if cons else 'INCONSISTENT'}"
              f"{'  CONFIDENTLY WRONG' if wrong else ''}  fit {r['cpu_fit']:5.1f} s CPU, {solves} solves", flush=True)
    n = len(rows)
    print(f"\n{n} cases, wall {time.perf_counter() - t_all:.0f} s")
    print(f"truth within 2 std: {100 * sum(r['within2'] for r in rows) / n:.1f} %")
    print(f"confidently wrong (|err| > 3 std, consistent): {100 * sum(r['wrong'] for r in rows) / n:.1f} %")
    print(f"consistent: {100 * sum(r['consistent'] for r in rows) / n:.1f} %; identified: "
          f"{100 * sum(r['identified'] for r in rows) / n:.1f} %")
    print(f"plate solves per fit: median {statistics.median(r['solves'] for r in rows)}, "
          f"max {max(r['solves'] for r in rows)}; surrogate shift-invert blocks per fit: median "
          f"{statistics.median(r['blocks'] for r in rows)}")
    print(f"median CPU per fit {statistics.median(r['cpu_fit'] for r in rows):.2f} s "
          f"(+ setup {statistics.median(r['cpu_setup'] for r in rows):.2f} s); max {max(r['cpu_fit'] for r in rows):.1f} s")
    for fam in ("cfrp", "wood", "aluminium"):
        sub = [r for r in rows if r["plate"].startswith(fam)]
        if sub:
            print(f"  {fam}: {len(sub)} cases, within 2 std {100 * sum(r['within2'] for r in sub) / len(sub):.0f} %, "
                  f"confidently wrong {sum(r['wrong'] for r in sub)}, consistent "
                  f"{100 * sum(r['consistent'] for r in sub) / len(sub):.0f} %, median fit CPU "
                  f"{statistics.median(r['cpu_fit'] for r in sub):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
