"""The discretisation correction follows the estimate (issue 24, bench_independent_run.py).

Peaks from the 2x reference mesh (the simulated rig's plate, not identify's mesh) of the 1 m
CFRP plate of bench/rigs/cfrp_large.toml with three 2 g accelerometers, at constants 5-40 %
from the file's, plus Gaussian noise of the stated sigma. The identification model's modes
reorder between the file's constants and the true ones; a correction computed at the file's
constants and applied by mode rank then lands on neighbouring modes. Law checked: with the
model right within its stated error, the chi^2 of Gaussian noise does not exceed its
expectation nu by more than 3 sqrt(2 nu) (before the fix: chi^2 233 for nu = 28).
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from engine.plate import PlateModel
from engine.plate.convergence import reference_mesh
from labid.inputs.specimen import load_specimen
from labid.workflows.identification import problem_from_features, run, synthetic_features

ROOT = Path(__file__).resolve().parents[3]
MASSES = [(0.06, 0.06, 0.002), (0.94, 0.06, 0.002), (0.7, 0.88, 0.002)]
SCALE = {"E1": 0.95, "E2": 1.10, "G12": 1.15, "G13": 0.70, "G23": 1.40}
#: modes (0-based) of the first 40 that bench_independent_run.py's hammer run did not report
#: (the likelihood pairing's unpaired modes there): a peak list with gaps, as measured
MISSED = {1, 2, 14, 16, 18, 21, 31}


@pytest.fixture(scope="module")
def estimate():
    spec = load_specimen(str(ROOT / "bench" / "rigs" / "cfrp_large.toml"))
    nominal = spec.laminate.plies[0].material.params()
    truth = {**nominal, **{n: nominal[n] * s for n, s in SCALE.items()}}
    ref = PlateModel.build(spec.laminate, spec.length, spec.width,
                           reference_mesh(spec.length, spec.width, spec.laminate.thickness)).with_point_masses(MASSES)
    doc = synthetic_features(spec, n_modes=40, waves=(), noise=True, seed=1, params=truth,
                             modal_sigma_rel=1e-5, modal_model=ref)
    for k in ("frequencies_hz", "sigma_hz"):
        doc["modal"][k] = [v for i, v in enumerate(doc["modal"][k]) if i not in MISSED]
    doc["rig"] = {"accelerometers": [{"x": x, "y": y, "mass_kg": m} for x, y, m in MASSES]}
    est = run(problem_from_features(doc, specimen=spec), list(SCALE))
    return est, truth


@pytest.mark.slow
def test_chi2_of_gaussian_noise_within_its_spread_after_the_constants_moved(estimate):
    est, truth = estimate
    fit = est.fit
    nu = fit["dof"]
    assert nu == 33 - 5
    assert fit["chi2"] <= nu + 3.0 * math.sqrt(2.0 * nu), fit
    assert fit["consistent"]
    # the well-determined constants at the truth within 3 of their stds (and 0.1 %)
    for n in ("E1", "E2", "G12"):
        i = est.names.index(n)
        assert abs(est.values[i] - truth[n]) <= 3.0 * est.std[i], (n, est.values[i], truth[n], est.std[i])
        assert abs(est.values[i] / truth[n] - 1.0) < 1e-3
    assert any("at the estimate" in w for w in est.warnings)
