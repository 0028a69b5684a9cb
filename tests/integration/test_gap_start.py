"""Gap diagnosis from identify's estimate (issue 13): one estimator, pairing as a cause.

Features come from the blind generator (bench/blind.py) on the default mesh,
modal data only; the constants identified are E1, E2, G12 (as
``labid identify --params E1,E2,G12``).
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

from bench.blind import draw_case
from labid.workflows.identification import estimation
from labid.workflows.diagnosis import run_diagnosis
from engine.gap import propose_pairing

NAMES = ("E1", "E2", "G12")


def _without_shapes(doc: dict, drop: tuple[int, ...] = ()) -> dict:
    d = copy.deepcopy(doc)
    md = d["modal"]
    n0 = len(md["frequencies_hz"])
    keep = [i for i in range(n0) if i not in drop]
    for k in list(md):
        if isinstance(md[k], list) and len(md[k]) == n0:
            md[k] = [md[k][i] for i in keep]
    for k in ("mode_shapes", "points", "shapes"):
        md.pop(k, None)
    return d


def test_features_identify_fits_consistently_give_none_from_the_same_estimate():
    doc = _without_shapes(draw_case(21, "clean", wave_sets=()).features)
    problem = estimation.problem_from_features(doc)
    est = estimation.run(problem, NAMES)
    chi2_identify = sum(r["chi2"] for r in est.residuals.values())
    res = run_diagnosis(doc, names=NAMES)
    assert res["identification"]["parameters"] == list(NAMES)
    # the diagnosis starts where identify ends: not bit for bit, since the plate's warm
    # eigen-solve (engine.plate.warm, certified to 1e-10) starts from the model's last solve
    # and two identifications in one process agree to ~1e-11 (2e-11 seen in CI); another fit
    # would end its own tolerance away (>= 1e-7)
    for n in NAMES:
        assert res["constants"]["before"][n] == pytest.approx(est.params[n], rel=1e-9)
    g = res["gap"]
    # same residuals, whitened with the measured sigmas plus a model allowance: chi^2 can only drop
    assert g["chi2_before"] <= chi2_identify * (1 + 1e-9)
    assert g["chi2_before"] < g["threshold_chi2"]
    assert res["verdict"] == "none" and res["where"] == []
    # identify's result dict handed over (as the demo does) gives the same diagnosis
    # (the handed dict is used as it is: its values exactly; against the diagnosis that
    # identified by itself, the same 1e-9 as above: CI saw 2e-11 between the two solves)
    handed = est.to_dict()
    again = run_diagnosis(doc, names=NAMES, estimate=handed)
    assert again["constants"]["before"] == {n: handed["parameters"][n]["value"] for n in NAMES}
    for n in NAMES:
        assert again["constants"]["before"][n] == pytest.approx(res["constants"]["before"][n], rel=1e-9)
    assert again["gap"]["chi2_before"] == pytest.approx(g["chi2_before"], rel=1e-9)


def test_propose_pairing_skips_a_missing_mode_and_leaves_a_stray_peak_unpaired():
    pred = np.array([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    meas = [10.1, 29.8, 40.2, 45.0 * 1.4, 50.3]   # mode 2 missing; 63 Hz is near mode 6 (60 Hz, 5 %)
    assert propose_pairing(meas, pred) == [0, 2, 3, 5, 4] or propose_pairing(meas, pred)[:3] == [0, 2, 3]
    assert propose_pairing([10.0, 14.0, 20.0], pred)[1] is None        # 14 Hz: 30 % from any mode


def test_a_missing_peak_is_named_and_explains_the_data():
    """Mode 3 (1-based) removed from a clean peak list: identify's pairing skips it inside
    the fit (issue 12), so the same residuals leave no gap (verdict none, constants within
    5 % of the truth), and `where` names the missing mode first."""
    case = draw_case(22, "clean", wave_sets=())
    f = case.features["modal"]["frequencies_hz"]
    doc = _without_shapes(case.features, drop=(2,))
    res = run_diagnosis(doc, names=NAMES)
    assert f[2] not in doc["modal"]["frequencies_hz"]
    assert res["verdict"] in ("none", "pairing")
    assert "predicted mode 3 near" in res["where"][0] and "no measured peak" in res["where"][0]
    assert res["gap"]["after"] < 1.5
    assert abs(res["constants"]["before"]["E1"] / case.truth_constants["E1"] - 1) < 0.05


def test_identify_s_own_assignment_is_used_and_unexplained_peaks_carry_no_residual():
    """A selection (predicted mode per peak, None = unexplained) as identify reports it:
    the paired peaks are predicted by those modes, the unexplained one has no residual."""
    from engine.gap import GapFit, GapForward
    from labid.workflows.diagnosis import gap_features
    case = draw_case(23, "clean", wave_sets=())
    doc = _without_shapes(case.features, drop=(2,))
    problem = gap_features(doc)
    sel = [0, 1, 3, 4, 5, 6, 7, 8, None]          # mode 3 has no peak; the last peak is unexplained
    fw = GapForward(problem, selection=sel)
    F = GapFit(problem, fw, (0.0, 0.0), names=NAMES)
    p = {**problem.nominal(), **case.truth_constants}
    pred = fw.predict(p, {})
    ref = GapForward(problem.__class__(problem.laminate, problem.length, problem.width, problem.rig,
                                       problem.modal.__class__(np.ones(10), np.ones(10), pairing="order")),
                     pairing="order").predict(p, {})
    assert np.allclose(pred[:8], ref[[0, 1, 3, 4, 5, 6, 7, 8]], rtol=1e-12)
    r = F.residual(p, {})
    assert r[8] == 0.0 and np.all(F.jacobian(p, {})[8] == 0.0)
    assert np.max(np.abs(r[:8])) < 5.0          # the truth with the right assignment: noise-level residuals


def test_cli_params_and_prior_are_checked_as_identify_checks_them(tmp_path, capsys):
    import json
    from labid.cli.main import main
    f = tmp_path / "f.json"
    f.write_text(json.dumps(_without_shapes(draw_case(24, "clean", wave_sets=()).features)))
    assert main(["diagnose", str(f), "--params", "E1,X", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--params" in err[0] and "'X'" in err[0]
    assert main(["diagnose", str(f), "--prior", "-1", "--quiet"]) == 2
    assert "--prior" in capsys.readouterr().err


@pytest.mark.slow
def test_mass_found_when_identify_sets_most_peaks_aside_and_a_mode_is_missing():
    """Issue 13, pairing inside each refit: 4.66 g unmodelled at each of 4 accelerometers,
    the 3rd mode missing from the list, peaks from a finer mesh than the diagnoser's.
    identify's likelihood pairing explains nothing cheaper than a bad fit (8 of 9 peaks
    set aside: inconsistent). Before: the diagnosis crashed (singular chi^2 test); with
    frequency order alone the mass refit stays in a wrong pairing (unattributed). Re-paired
    under the effect it finds the injected mass to 2 % and the gap closes to noise."""
    case = draw_case(3, "sensor_mass", outside=True, wave_sets=())
    doc = _without_shapes(case.features, drop=(2,))
    res = run_diagnosis(doc, names=list(NAMES))
    assert res["verdict"] == "sensor_mass", (res["verdict"], res["diagnosis_notes"])
    top = res["effects"][0]
    assert top["magnitude"] == pytest.approx(case.magnitude, rel=0.02)
    assert res["gap"]["after"] < 1.5 < 50 < res["gap"]["before"]
    assert res["identification"]["pairing_used"] == "re-paired under sensor_mass"
    assert any("pair differently" in n for n in res["diagnosis_notes"])


def test_cli_diagnose_from_identify_s_json_result(tmp_path, capsys):
    """``labid diagnose --estimate`` takes ``labid identify --json``'s result: the same
    start constants as identifying again; a result of other features is refused in one line."""
    import json
    from labid.cli.main import main
    f = tmp_path / "f.json"
    f.write_text(json.dumps(_without_shapes(draw_case(25, "sensor_mass", wave_sets=()).features)))
    ident, d1, d2 = tmp_path / "id.json", tmp_path / "d1.json", tmp_path / "d2.json"
    assert main(["identify", str(f), "--params", "E1,E2,G12", "--json", str(ident), "--quiet"]) == 0
    assert main(["diagnose", str(f), "--params", "E1,E2,G12", "--json", str(d1), "--quiet"]) == 0
    assert main(["diagnose", str(f), "--params", "E1,E2,G12", "--estimate", str(ident), "--json", str(d2),
                 "--quiet"]) == 0
    r1, r2 = json.loads(d1.read_text()), json.loads(d2.read_text())
    assert r2["constants"]["before"] == pytest.approx(r1["constants"]["before"], rel=1e-9)  # warm solves, above
    assert r2["verdict"] == r1["verdict"] == "sensor_mass"
    capsys.readouterr()
    other = tmp_path / "other.json"
    doc = _without_shapes(draw_case(25, "sensor_mass", wave_sets=()).features, drop=(1,))
    other.write_text(json.dumps(doc))
    assert main(["diagnose", str(other), "--params", "E1,E2,G12", "--estimate", str(ident), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pairing" in err[0] and "id.json" in err[0]
