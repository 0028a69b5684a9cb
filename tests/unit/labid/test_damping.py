"""Damping as a result (issue 16): loss factors per mode and family, in the features and UFF55.

References from outside the code: the simulated rig's injected damping (every mode's
viscous ratio is ``sim.modal_damping`` + eta_visco / 2, mock_hw.vibration), so the loss
factor is 2 * 0.005 + eta_visco; the peak picker's known accuracy on this rig is 10 % per
mode (tests/test_analyze.py, tests/test_modal.py). The first mode of a free square
isotropic plate is the (1,1) twisting mode (Leissa, NASA SP-160, Table 4.71).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from labid.cli.main import main
from labid.workflows.damping import UNLABELLED, damping_summary, family_labels, family_of, loss_factors
from labid.inputs.specimen import load_specimen

ETA_VISCO = 0.006
ETA = 2 * 0.005 + ETA_VISCO


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    d = tmp_path_factory.mktemp("damping")
    run = d / "run.h5"
    assert main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "3", "--waves", "0",
                 "--effects", f"viscoelastic={ETA_VISCO}", "--quiet"]) == 0
    out = d / "features.json"
    assert main(["analyze", str(run), "--out", str(out), "--quiet"]) == 0
    return run, json.loads(out.read_text())


@pytest.mark.slow
def test_injected_loss_factor_recovered_per_mode_and_family(analysed):
    _, feats = analysed
    dmp = feats["damping"]
    eta = np.array([m["loss_factor"] for m in dmp["modes"]])
    z = np.array(feats["modal"]["damping_ratio"])
    assert eta == pytest.approx(2 * z, rel=1e-15)
    assert eta.size >= 30
    assert dmp["all"]["median_loss_factor"] == pytest.approx(ETA, rel=0.02)
    assert np.mean(np.abs(eta / ETA - 1) < 0.10) >= 0.8      # the picker's 10 %, most modes
    fams = dmp["families"]
    assert {"bending x (m,0)", "bending y (0,n)", "twisting (m,n)"} <= set(fams)
    for name, f in fams.items():
        assert f["n"] == len(f["modes"])
        if name != UNLABELLED and f["n"] >= 3:
            assert f["median_loss_factor"] == pytest.approx(ETA, rel=0.05), name
            assert f["scatter"] == pytest.approx(np.std(eta[f["modes"]], ddof=1))
    assert dmp["modes"][0]["label"] == "(1,1) torsion"


@pytest.mark.slow
def test_uff55_round_trip_carries_the_loss_factor(analysed, tmp_path):
    pyuff = pytest.importorskip("pyuff")
    run, feats = analysed
    uff = tmp_path / "run.uff"
    assert main(["export", str(run), "--uff", str(uff), "--csv", str(tmp_path / "csv"), "--quiet"]) == 0
    modes = [s for s in pyuff.UFF(str(uff)).read_sets() if s["type"] == 55]
    dm = feats["damping"]["modes"]
    assert len(modes) == len(dm)
    for s, m in zip(modes, dm):        # UFF55 keeps 6 digits (E13.5)
        assert s["modal_damp_his"] == pytest.approx(m["loss_factor"], rel=5e-6)
        assert s["modal_damp_vis"] == pytest.approx(m["damping_ratio"], rel=5e-6)
        assert s["id3"].strip() == m["label"]
    text = (tmp_path / "csv" / "features_modal.csv").read_text().splitlines()
    assert text[0].endswith("loss_factor,family")
    assert float(text[1].split(",")[5]) == dm[0]["loss_factor"]


def test_square_plate_first_mode_is_twisting():
    al = load_specimen("aluminium")          # 1 m x 1 m x 3.175 mm: f1 about 10.2 Hz
    labels = family_labels([10.2, 14.98, 19.8], al)
    assert labels[0] == "(1,1) torsion" and family_of(labels[0]) == "twisting (m,n)"
    # a peak far from every model mode is not labelled; no specimen: nothing labelled
    assert family_labels([10.2, 3.0], al)[1] == UNLABELLED
    assert family_labels([10.2], None) == [UNLABELLED]


def test_summary_statistics_and_definitions():
    assert loss_factors([0.01, None, math.nan])[0] == 0.02
    assert math.isnan(loss_factors([None])[0])
    assert family_of("(3,0)") == "bending x (m,0)" and family_of("(0,2)/(2,0)") == "bending y (0,n)"
    s = damping_summary({"frequencies_hz": [10.0, 20.0, 30.0], "damping_ratio": [0.01, 0.02, 0.04]})
    assert s["all"] == {"n": 3, "median_loss_factor": 0.04, "scatter": pytest.approx(np.std([0.02, 0.04, 0.08],
                                                                                              ddof=1))}
    assert s["families"][UNLABELLED]["modes"] == [0, 1, 2] and s["labelled_by"] is None
    assert damping_summary({"frequencies_hz": [10.0]}) is None


@pytest.mark.slow
def test_hand_edited_picks_refresh_the_damping_section_and_the_report_shows_it(analysed, tmp_path):
    import shutil

    from labid.report import certificate as report
    from labid import services
    from engine import modal

    run0, feats = analysed
    run = tmp_path / "run.h5"
    shutil.copy(run0, run)
    m = feats["modal"]
    keep = list(range(0, len(m["frequencies_hz"]), 2))          # drop every other pick by hand
    peaks = [modal.Peak(frequency_hz=m["frequencies_hz"][i], damping_ratio=m["damping_ratio"][i],
                        sigma_hz=m["sigma_hz"][i], snr_db=30.0, confidence=1.0, manual=True) for i in keep]
    doc = services.save_picks(run, peaks)
    eta = [d["loss_factor"] for d in doc["damping"]["modes"]]
    assert eta == pytest.approx([2 * m["damping_ratio"][i] for i in keep], rel=1e-15)
    html = report.build_report(run)
    assert "Modal loss factor" in html and "median η" in html
