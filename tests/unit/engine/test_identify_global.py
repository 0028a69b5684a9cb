"""Issue 12: global convergence from datasheet starts (the Ritz surrogate's global stage)
and default parameters by identifiability."""
from __future__ import annotations

import numpy as np
import pytest

from engine.identify.surrogate import RitzSurrogate
from engine.plate import PlateModel
from labid.workflows.identification import problem_from_features, run, synthetic_features
from labid.inputs.specimen import load_specimen

TRUE = {"E1": 136.7e9, "E2": 9.0e9, "nu12": 0.30, "G12": 5.0e9, "G13": 5.08e9, "G23": 3.16e9}


def test_ritz_surrogate_is_exact_at_its_start_and_an_upper_bound_within_the_peaks_sigma():
    """The basis holds the FE modes of the start (there the Ritz frequencies equal the FE
    ones to 1e-5: nearly dependent directions, eigenvalues of V'MV below 1e-12 of the
    largest, are dropped) and one shift-invert block per raised constant; elsewhere the
    Ritz values are upper bounds (Rayleigh-Ritz) within 3e-4 (measured 1.8e-4 at E2 + 30 %,
    2.1e-4 in between; a fifth of the peaks' 0.1 % sigma). The start's modes alone are
    7.7e-4 off at E2 + 30 %."""
    spec = load_specimen("cfrp")
    model = PlateModel.build(spec.laminate, spec.length, spec.width)
    start = dict(TRUE)
    sur = RitzSurrogate(model, start, ("E1", "E2", "G12"), 12)
    np.testing.assert_allclose(sur.frequencies_hz(start), model.solve(12, params=start).frequencies_hz, rtol=1e-5)
    mid = {**start, "E1": start["E1"] * 0.8, "G12": start["G12"] * 1.15}
    for p in ({**start, "E2": start["E2"] * 1.3}, {**start, "G12": start["G12"] * 1.3}, mid):
        fe = model.solve(12, params=p).frequencies_hz
        ritz = sur.frequencies_hz(p)
        assert np.all(ritz >= fe * (1 - 1e-9)) and np.all(ritz <= fe * (1 + 3e-4))


@pytest.mark.slow
def test_datasheet_starts_reach_the_optimum_of_the_true_start():
    """30 reference-mesh modes of the CFRP plate: E1, E2, G12 from four starts 25-30 % off
    in different directions end where the true start ends (within 0.1 std)."""
    doc = synthetic_features("cfrp", n_modes=30, waves=())
    doc["specimen"] = "cfrp"
    prob = problem_from_features(doc)
    names = ("E1", "E2", "G12")
    ref = run(prob, names, {n: TRUE[n] for n in names})
    assert ref.fit["consistent"]
    for f in ((0.7, 1.3, 0.75), (1.3, 0.7, 1.25), (0.75, 0.75, 0.7), (1.28, 1.3, 1.3)):
        est = run(prob, names, {n: TRUE[n] * k for n, k in zip(names, f)})
        assert est.fit["consistent"], f
        np.testing.assert_allclose(est.values, ref.values, atol=0, rtol=0.1 * float(np.max(ref.std / ref.values)))


@pytest.mark.slow
def test_modal_only_defaults_hold_what_frequencies_cannot_see():
    """Modal data only, default parameters, datasheet start: nu12 and G23 (invisible to
    the frequencies of a thin plate, relative std > 30 % at the start) are held under a
    weak prior, reported as held and not identified; E1, E2, G12 stay within 2 std."""
    doc = synthetic_features("cfrp", n_modes=30, waves=())
    doc["specimen"] = "cfrp"
    prob = problem_from_features(doc)
    start = {"E1": 110e9, "E2": 7e9, "nu12": 0.25, "G12": 4e9, "G13": 4e9, "G23": 2.5e9}
    out = run(prob, None, start).to_dict()
    assert {"nu12", "G23"} <= set(out["held"])
    for n in out["held"]:
        assert out["parameters"][n]["identified"] is False
    for n in ("E1", "E2", "G12"):
        assert n not in out["held"]
        p = out["parameters"][n]
        assert abs(p["value"] - TRUE[n]) <= 2 * p["std"], (n, p)
