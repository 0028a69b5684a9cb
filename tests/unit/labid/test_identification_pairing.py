"""Issue 12: measured peaks paired with predicted modes inside the fit, with missing modes
and spurious peaks allowed (engine.forward.pairing), reported per peak with its family."""
from __future__ import annotations

import numpy as np
import pytest

from engine.forward.pairing import MISS, SPURIOUS, assign
from labid.workflows.identification import problem_from_features, run, synthetic_features

TRUE = {"E1": 136.7e9, "E2": 9.0e9, "G12": 5.0e9}


def test_assign_skips_a_mode_with_a_node_at_the_sensor_and_sets_aside_a_stray_peak():
    """Exact predicted frequencies 100..190 Hz; peaks: all but mode 3 (node at the sensor,
    visibility 0.01) plus a stray peak at 157 Hz, 3.5 % from any mode."""
    fp = 100.0 + 10.0 * np.arange(10)
    vis = np.ones(10)
    vis[3] = 0.01
    meas = np.sort(np.append(np.delete(fp, 3), 157.0))
    a = assign(meas, 1e-3 * meas, fp, vis, tau=0.003)
    expect = [0, 1, 2, 4, 5, -1, 6, 7, 8, 9]
    assert a.index.tolist() == expect
    assert a.skipped.tolist() == [3]
    # the same list, but mode 3 fully visible at the sensor: skipping it now costs MISS,
    # and the total says so (likelihoods compared with their penalties)
    b = assign(meas, 1e-3 * meas, fp, np.ones(10), tau=0.003)
    assert b.index.tolist() == expect
    assert b.cost - a.cost == pytest.approx(MISS * (1 - (0.01 / 0.25) ** 2), rel=1e-9)
    assert a.cost == pytest.approx(SPURIOUS + MISS * (0.01 / 0.25) ** 2, rel=1e-9)


@pytest.mark.slow
def test_hand_built_peak_list_with_two_modes_removed_is_paired_in_the_fit():
    """The first 20 modes of the CFRP plate (reference mesh) with modes 3 and 11 removed
    and a stray peak at 777 Hz, from a start 8-12 % off: every peak paired with its own
    mode, the stray one unexplained, the two removed modes listed as unpaired, constants
    within 2 std and the fit consistent."""
    doc = synthetic_features("cfrp", n_modes=20, waves=())
    doc["specimen"] = "cfrp"
    m = doc["modal"]
    keep = [i for i in range(20) if i not in (3, 11)]
    f = [m["frequencies_hz"][i] for i in keep] + [777.0]
    s = [m["sigma_hz"][i] for i in keep] + [0.777]
    m["frequencies_hz"], m["sigma_hz"] = f, s
    prob = problem_from_features(doc)
    est = run(prob, ("E1", "E2", "G12"), {"E1": 125e9, "E2": 9.8e9, "G12": 4.5e9})
    out = est.to_dict()
    assert [r["mode_index"] for r in out["pairing"]] == keep + [None]
    assert [r["peak"] for r in out["pairing"]] == list(range(19))
    assert out["pairing"][-1]["family"] is None and out["pairing"][0]["family"] == "(1,1) torsion"
    assert {3, 11} <= {u["mode_index"] for u in out["unpaired_modes"]}
    assert out["fit"]["consistent"] and out["identified"]
    assert out["fit"]["dof"] == 18 - 3          # the stray peak is set aside, not counted
    for n, p in out["parameters"].items():
        assert abs(p["value"] - TRUE[n]) <= 2 * p["std"], (n, p)


@pytest.mark.slow
def test_a_label_in_the_features_file_forces_the_pairing():
    """Peaks of modes 0..9 with mode 4 removed; the peak of mode 5 is labelled in the file as
    mode 4 (a user's wrong label): the fit must pair it as told, so that peak's predicted
    frequency is mode 4's (the labels reach the pairing; unlabelled peaks keep their own)."""
    doc = synthetic_features("cfrp", n_modes=10, waves=())
    doc["specimen"] = "cfrp"
    m = doc["modal"]
    keep = [i for i in range(10) if i != 4]
    m["frequencies_hz"] = [m["frequencies_hz"][i] for i in keep]
    m["sigma_hz"] = [m["sigma_hz"][i] for i in keep]
    free = run(problem_from_features(doc), ("E1", "E2", "G12"), dict(TRUE)).to_dict()
    assert [r["mode_index"] for r in free["pairing"]] == keep
    m["mode_index"] = [None] * 4 + [4] + [None] * 4
    forced = run(problem_from_features(doc), ("E1", "E2", "G12"), dict(TRUE)).to_dict()
    assert forced["pairing"][4]["mode_index"] == 4
