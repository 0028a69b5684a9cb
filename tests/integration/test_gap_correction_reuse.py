"""The diagnosis takes identify's discretisation correction at the estimate (issue 29): no second
fine-mesh solve when identify's re-correction was solved at the constants the gap starts from.

Features: bench/blind.py seed 31, clean, modal only without shapes (bench_gap_cost.py's
modal3-clean), constants E1, E2, G12. The counts come from bench/_count.py.
"""
from __future__ import annotations

import copy

import numpy as np

from bench._count import Counts
from bench.blind import draw_case
from engine.identify import stages
from engine.plate import PlateModel
from engine.plate.convergence import FINE_FACTOR, finer_mesh, mode_corrections
from labid.workflows.diagnosis import gap_features, run_diagnosis

NAMES = ("E1", "E2", "G12")


def _modal3_clean() -> dict:
    d = copy.deepcopy(draw_case(31, "clean", wave_sets=()).features)
    d["modal"].pop("mode_shapes", None)
    return d


def test_the_gap_reuses_identifys_correction_at_the_estimate():
    doc = _modal3_clean()
    stages._DISC_MEMO.clear()               # a fresh process: nothing memoised by other tests
    with Counts() as c:
        res = run_diagnosis(doc, names=NAMES)
    p = gap_features(doc)
    fine_dof = PlateModel.build(p.laminate, p.length, p.width,
                                finer_mesh(p.length, p.width, p.laminate.thickness, FINE_FACTOR)).mesh.n_dof
    fine = sum(n for k, n in c.n.items() if k == f"plate solve ({fine_dof} DOF)")
    # the gap's correction was solved at the estimate (close modes reorder) ...
    assert any("solved at the estimate" in n for n in res["diagnosis_notes"]), res["diagnosis_notes"]
    # ... and taken from identify's: the nominal correction and the one at the estimate, no third
    assert fine == 2, dict(c.n)
    assert res["verdict"] == "none"


def test_the_correction_asked_at_the_estimate_equals_one_of_the_rebuilt_laminate():
    """The gap asks the nominal plate solved at the estimate's constants (identify's form); its
    earlier form rebuilt the laminate with them. Same K and M bit for bit, and the ratios of a
    20-mode solve's first 14 equal a 14-mode solve's to round-off."""
    p = gap_features(_modal3_clean())
    at = {"E1": 134.9e9, "E2": 9.41e9, "G12": 5.03e9}
    lam = p.laminate.with_params(at, p.material)
    masses = p.rig.masses()
    coarse = PlateModel.build(p.laminate, p.length, p.width).with_point_masses(masses)
    rebuilt = PlateModel.build(lam, p.length, p.width).with_point_masses(masses)
    K0, M0 = coarse.matrices(at, p.material)
    K1, M1 = rebuilt.matrices(None, p.material)
    assert np.array_equal(K0.data, K1.data) and np.array_equal(M0.data, M1.data)
    mesh = finer_mesh(p.length, p.width, p.laminate.thickness, FINE_FACTOR)
    a = mode_corrections(coarse, PlateModel.build(p.laminate, p.length, p.width, mesh).with_point_masses(masses),
                         20, params=at, material=p.material)
    b = mode_corrections(rebuilt, PlateModel.build(lam, p.length, p.width, mesh).with_point_masses(masses),
                         14, material=p.material)
    assert np.allclose(a.ratio[:14], b.ratio, rtol=1e-9, atol=0)
    assert np.allclose(a.error_rel[:14], b.error_rel, rtol=1e-6, atol=1e-12)
