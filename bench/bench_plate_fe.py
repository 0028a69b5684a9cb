"""Benchmark of engine.plate on the 0.33 m square 12-ply CFRP plate.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python bench/bench_plate_fe.py [--no-study]``.
Prints a markdown section for bench/RESULTS.md:

* mesh convergence study (10 elastic modes vs a very fine graded mesh);
* at the default mesh: assembly (build) time, time per solve once assembled
  (new constants each time: recombination + factorisation + eigsh), time of
  the analytic sensitivities for 7 parameters, peak memory.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine  # noqa: E402

from engine.laminate import Laminate, Material, Ply  # noqa: E402
from engine.plate import DEFAULT_ELEMENTS, EDGE_LAYER, Mesh, PlateModel  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402

NAMES = ["E1", "E2", "nu12", "G12", "G13", "G23", "density"]


def timed(fn, repeat: int) -> tuple[float, float, float]:
    """(min wall, median wall, median CPU) seconds; CPU time is less disturbed by other jobs."""
    ts, cs = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        ts.append(time.perf_counter() - t)
        cs.append(time.process_time() - c)
    return min(ts), float(np.median(ts)), float(np.median(cs))


def study(spec) -> list[str]:
    L, W, t = spec.length, spec.width, spec.laminate.thickness
    ref_mesh = Mesh.graded(L, W, 14, [t / 4, t, 4 * t, 12 * t])
    ref = PlateModel.build(spec.laminate, L, W, ref_mesh).solve(10).frequencies_hz
    rows = ["| mesh | DOF | max err 10 modes (%) | mode 1 (Hz) | mode 10 (Hz) | solve (ms) |",
            "|---|---|---|---|---|---|"]
    cases = [(f"uniform {n}x{n}", Mesh.default(L, W, None, n)) for n in (4, 6, 8, 10, 14)]
    cases += [(f"{n} + edge row {e:g}t", Mesh.graded(L, W, n, [e * t])) for n, e in
              ((4, 2.0), (5, 2.0), (6, 1.0), (6, 2.0), (6, 3.0), (8, 2.0))]
    cases += [("6 + edges 1t, 4t", Mesh.graded(L, W, 6, [t, 4 * t])),
              ("reference: 14 + edges t/4, t, 4t, 12t", ref_mesh)]
    default = PlateModel.build(spec.laminate, L, W).mesh
    for name, mesh in cases:
        model = PlateModel.build(spec.laminate, L, W, mesh)
        best = timed(lambda: model.solve(10), 3)[0]
        f = model.solve(10).frequencies_hz
        err = 100 * np.max(np.abs(f / ref - 1))
        tag = " **(default)**" if mesh == default else ""
        rows.append(f"| {name}{tag} | {mesh.n_dof} | {err:.4f} | {f[0]:.3f} | {f[9]:.3f} "
                    f"| {best * 1e3:.0f} |")
    rows.append("")
    rows.append("Reference frequencies (Hz): " + ", ".join(f"{v:.3f}" for v in ref))
    return rows


def validation() -> list[str]:
    """FV12 and Leissa errors at the default mesh (ORACLES.md)."""
    steel = Material.isotropic_from(200e9, 8000.0, nu=0.3, name="steel")
    fv12 = np.array([1.622, 2.360, 2.922, 4.190, 4.190, 7.356, 7.356, 7.668])
    leissa = np.array([13.47, 19.60, 24.27, 34.80, 34.80, 61.09, 61.09, 63.69])
    f = PlateModel.build(Laminate((Ply(steel, 0.0, 0.05),)), 10.0, 10.0).solve(8).frequencies_hz
    rows = ["| case | relative errors of the 8 modes (%) |", "|---|---|",
            "| NAFEMS FV12 | " + " ".join(f"{e:+.3f}" for e in 100 * (f / fv12 - 1)) + " |"]
    for r in (0.001, 0.005, 0.02, 0.1):
        lam = Laminate((Ply(steel, 0.0, r),))
        D = 200e9 * r**3 / (12 * (1 - 0.09))
        om = np.sqrt(PlateModel.build(lam, 1.0, 1.0).solve(8).omega2)
        err = 100 * (om * np.sqrt(8000.0 * r / D) / leissa - 1)
        rows.append(f"| Leissa, h/a = {r:g} | " + " ".join(f"{e:+.3f}" for e in err) + " |")
    return rows


def perf(spec, repeat: int) -> list[str]:
    L, W = spec.length, spec.width
    tracemalloc.start()
    t = time.perf_counter()
    model = PlateModel.build(spec.laminate, L, W)
    t_build = time.perf_counter() - t
    _, peak_build = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()
    modes = model.solve(10)
    _, peak_solve = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rng = np.random.default_rng(0)
    base = spec.laminate.plies[0].material.params()

    def one_solve():
        p = {k: v * (1 + 0.05 * rng.standard_normal()) for k, v in base.items() if k in ("E1", "E2", "G12")}
        return model.solve(10, params=p)

    model.solve(10)
    t_solve = timed(one_solve, repeat)
    t_sens = timed(lambda: model.eigen_sensitivities(modes, NAMES), repeat)
    t_build2 = timed(lambda: PlateModel.build(spec.laminate, L, W), 3)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    m = model.mesh
    return [
        f"Default mesh: {m.nx}x{m.ny} elements ({DEFAULT_ELEMENTS} interior + edge rows of "
        f"{EDGE_LAYER:g} t), {m.n_dof} DOF, {model.matrices()[0].nnz} stored entries of K.",
        "",
        "| quantity | wall min | wall median | CPU median |",
        "|---|---|---|---|",
        f"| assembly: PlateModel.build (ms) | {t_build2[0] * 1e3:.1f} | {t_build2[1] * 1e3:.1f} "
        f"| {t_build2[2] * 1e3:.1f} |",
        f"| solve once assembled, 10 elastic modes, new constants each time (ms) | "
        f"{t_solve[0] * 1e3:.1f} | {t_solve[1] * 1e3:.1f} | {t_solve[2] * 1e3:.1f} |",
        f"| sensitivities, 7 parameters x 10 modes (ms) | {t_sens[0] * 1e3:.2f} | "
        f"{t_sens[1] * 1e3:.2f} | {t_sens[2] * 1e3:.2f} |",
        f"| sensitivities / solve (%) | {100 * t_sens[0] / t_solve[0]:.1f} | "
        f"{100 * t_sens[1] / t_solve[1]:.1f} | {100 * t_sens[2] / t_solve[2]:.1f} |",
        "",
        f"Peak traced memory (tracemalloc): build {peak_build / 2**20:.1f} MiB, solve "
        f"{peak_solve / 2**20:.1f} MiB; process max RSS {rss:.0f} MiB (includes numpy/scipy).",
        f"First build incl. reference element matrices: {t_build * 1e3:.0f} ms (under tracemalloc).",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-study", action="store_true", help="skip the convergence study")
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    spec = load_specimen("cfrp")
    lines = ["## engine.plate_fe (bench/bench_plate_fe.py)", "",
             f"Machine: {machine()} (shared machine; "
             "the min of repeated timings is the least disturbed figure).",
             f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Plate: {spec.name}, "
             f"{spec.length} x {spec.width} m.", ""]
    if not args.no_study:
        lines += ["### Validation at the default mesh", ""] + validation() + [""]
        lines += ["### Mesh convergence (10 elastic modes)", ""] + study(spec) + [""]
    lines += ["### Performance at the default mesh", ""] + perf(spec, args.repeat)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
