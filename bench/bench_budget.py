"""GUM uncertainty budget (labid.workflows.budget) against a Monte Carlo of the full forward model + fit.

Monte Carlo in the manner of GUM Supplement 1 (JCGM 101:2008): every draw takes the
type-B inputs from their distributions (normal, the budget's standard uncertainties) and
the measured features with their noise (normal, the stated sigmas), rebuilds the forward
model at the drawn inputs and RE-FITS the constants (engine.fit.estimate, Levenberg-
Marquardt, from the nominal start): no linearisation anywhere. The expanded uncertainty
of the Monte Carlo is the half-width of the probabilistically symmetric interval of the
same coverage as k = 2 (95.45 %); the GUM one is U = 2 u_c of labid.workflows.budget. The issue's
target: each within 10 %.

Cases (independent synthetic data computed by the forward models, isotropic aluminium
plate 500 x 350 x 2 mm, E = 70 GPa, G = 26.3 GPa, rho = 2700 kg/m^3):

* ``modal``: 8 natural frequencies (0.1 % sigma), E and G fitted; inputs thickness
  (1 %), length and width (1 mm), density (1 %). Plate FE on a uniform 6 x 4 mesh
  (the budget and the Monte Carlo use the same model, so the mesh does not matter for
  the comparison, only for speed).
* ``waves``: A0 and S0 group velocities, 8 frequencies each to 150 kHz (1 % sigma), path
  0.2 m; inputs thickness (1 %), density (1 %), sensor and source positions (1 mm each),
  path length (0.5 mm).

Usage: python -m bench.bench_budget [--draws N] [--case modal|waves|both]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from engine.fit import estimate
from engine.forward import modal_block, wave_block
from engine.plate import PlateModel
from labid.workflows.budget import budget_of_problem
from labid.workflows.identification.estimation import problem_from_features, run
from labid.inputs.specimen import specimen_from_dict
from labid.workflows.identification.synthetic import synthetic_features

from ._machine import machine

H, L, W, RHO = 2e-3, 0.5, 0.35, 2700.0
TRUE = {"E": 70e9, "G": 26.3e9}
MESH = (6, 4)
COVER = 0.9545          # the coverage of k = 2 for a normal distribution


def _specimen(unc: dict) -> dict:
    return {"name": "Al 500x350x2", "plate": {"length": L, "width": W},
            "materials": {"Al": {"density": RHO, "E": TRUE["E"], "G": TRUE["G"]}},
            "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": H}, "uncertainty": unc}


def _half_width(x: np.ndarray) -> float:
    lo, hi = np.quantile(x, [(1 - COVER) / 2, (1 + COVER) / 2])
    return 0.5 * (hi - lo)


def modal_case(n: int, rng: np.random.Generator) -> dict:
    unc = {"thickness": 0.01 * H, "length": 1e-3, "width": 1e-3, "density": 0.01 * RHO}
    sdoc = _specimen(unc)
    spec = specimen_from_dict(sdoc)
    model = PlateModel.build(spec.laminate, L, W, mesh=MESH)
    doc = synthetic_features(spec, n_modes=8, modal_sigma_rel=1e-3, waves=(), modal_model=model)
    doc["specimen"] = sdoc
    prob = problem_from_features(doc, modal_model=model)
    est = run(prob, ("E", "G"))
    gum = budget_of_problem(prob, est, doc)
    f0 = np.array(doc["modal"]["frequencies_hz"])
    sig = np.array(doc["modal"]["sigma_hz"])
    out = np.empty((n, 2))
    for i in range(n):
        h = H + unc["thickness"] * rng.standard_normal()
        a = L + unc["length"] * rng.standard_normal()
        b = W + unc["width"] * rng.standard_normal()
        rho = RHO + unc["density"] * rng.standard_normal()
        lam = spec.laminate.scaled_thickness(h / H).with_params({"density": rho})
        m = PlateModel.build(lam, a, b, mesh=MESH)
        blk, _ = modal_block(m, f0 + sig * rng.standard_normal(f0.size), sig)
        e = estimate([blk], ("E", "G"), TRUE)
        out[i] = e.values
    return {"gum": gum, "draws": out}


def waves_case(n: int, rng: np.random.Generator) -> dict:
    unc = {"thickness": 0.01 * H, "density": 0.01 * RHO, "sensor_position": 1e-3, "source_position": 1e-3,
           "path_length": 5e-4}
    sdoc = _specimen(unc)
    spec = specimen_from_dict(sdoc)
    waves = (("A0", 0.0, 150e3, 8), ("S0", 0.0, 150e3, 8))
    doc = synthetic_features(spec, n_modes=0, waves=waves, wave_sigma_rel=0.01)
    doc["specimen"] = sdoc
    d0 = 0.2
    doc["rig"] = {"wave_path_m": d0}
    prob = problem_from_features(doc)
    est = run(prob, ("E", "G"))
    gum = budget_of_problem(prob, est, doc)
    sets = doc["waves"]
    u_path = np.sqrt(unc["sensor_position"] ** 2 + unc["source_position"] ** 2 + unc["path_length"] ** 2)
    out = np.empty((n, 2))
    for i in range(n):
        h = H + unc["thickness"] * rng.standard_normal()
        d = d0 + u_path * rng.standard_normal()      # the three along-path inputs, summed
        rho = RHO + unc["density"] * rng.standard_normal()
        lam = spec.laminate.scaled_thickness(h / H).with_params({"density": rho})
        blocks = []
        for w in sets:
            cg = np.array(w["group_velocity_m_s"]) * d / d0        # observed = d / t
            s = np.array(w["sigma_m_s"])
            blocks.append(wave_block(lam, w["frequency_hz"], cg + s * rng.standard_normal(cg.size), s,
                                     mode=w["mode"], direction_deg=w["direction_deg"]))
        out[i] = estimate(blocks, ("E", "G"), TRUE).values
    return {"gum": gum, "draws": out}


def report(name: str, res: dict) -> list[str]:
    gum, x = res["gum"], res["draws"]
    lines = [f"{name}: {x.shape[0]} draws"]
    ok = True
    for j, p in enumerate(("E", "G")):
        c = gum["constants"][p]
        U_mc = _half_width(x[:, j])
        r = U_mc / c["U"]
        ok &= abs(r - 1) < 0.10
        lines.append(f"  {p}: GUM U = {c['U'] / 1e9:.4g} GPa (u_A {c['u_type_a'] / 1e9:.3g}, u_B "
                     f"{c['u_type_b'] / 1e9:.3g}); Monte Carlo U (95.45 % interval half-width) = {U_mc / 1e9:.4g} GPa, "
                     f"2 std = {2 * np.std(x[:, j], ddof=1) / 1e9:.4g} GPa, mean - value = "
                     f"{(np.mean(x[:, j]) - c['value']) / 1e9:.3g} GPa; MC/GUM = {r:.3f}")
    lines.append(f"  within 10 %: {'yes' if ok else 'NO'}")
    return lines


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--case", choices=("modal", "waves", "both"), default="both")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    print(machine())
    for name, fn in (("modal", modal_case), ("waves", waves_case)):
        if a.case not in (name, "both"):
            continue
        t0, c0 = time.perf_counter(), time.process_time()
        res = fn(a.draws, rng)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        for line in report(name, res):
            print(line)
        print(f"  wall {wall:.1f} s, CPU {cpu:.1f} s")


if __name__ == "__main__":
    main()
