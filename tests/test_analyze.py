"""labid analyze: run file (simulated rig) -> features file and /results/analysis.

The references are the models the simulated rig was built from: the plate
FE modes of the specimen with the rig's accelerometer masses (engine.plate_fe)
and its SAFE A0 curve (engine.safe), with the rig's injected damping (0.5 %).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from labid.cli import main


@pytest.fixture(scope="module")
def run_file(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("analyze")
    run = d / "run.h5"
    rc = main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "3", "--waves", "2", "--quiet"])
    assert rc == 0
    return run


@pytest.fixture(scope="module")
def analysed(run_file: Path):
    out = run_file.with_name("features.json")
    res = run_file.with_name("result.json")
    rc = main(["analyze", str(run_file), "--out", str(out), "--json", str(res)])
    assert rc == 0
    return out, json.loads(out.read_text()), json.loads(res.read_text())


@pytest.mark.slow
def test_modal_features_match_the_plate_model(analysed):
    from engine.plate_fe import PlateModel
    from labid.specimen import load_specimen
    _, feats, result = analysed
    assert result == feats  # --json is the features document
    sp = load_specimen("cfrp")
    # the simulated plate carries the accelerometers the rig declares (reported in the features)
    masses = [(a["x"], a["y"], a["mass_kg"]) for a in feats["rig"]["accelerometers"]]
    assert len(masses) == 3
    fn = PlateModel.build(sp.laminate, sp.length, sp.width).with_point_masses(masses).solve(40).frequencies_hz
    f = np.array(feats["modal"]["frequencies_hz"])
    z = np.array(feats["modal"]["damping_ratio"])
    assert f.size >= 30  # of the 40 simulated modes (some at nodal lines of the hammer point)
    err = np.array([np.min(np.abs(fn / x - 1)) for x in f])
    assert np.median(err) < 1e-5 and np.all(err < 5e-4)
    assert np.all(np.abs(z / 0.005 - 1) < 0.10)
    ms = feats["modal"]["mode_shapes"]
    assert np.array(ms["values"]).shape == (f.size, len(ms["points"]))
    assert np.all(np.array(feats["modal"]["sigma_hz"]) > 0)


@pytest.mark.slow
def test_wave_features_match_the_safe_curve(analysed):
    from engine import safe
    from labid.specimen import load_specimen
    _, feats, _ = analysed
    a0 = [w for w in feats["waves"] if w["mode"] == "A0"]
    assert len(a0) == 1
    f = np.array(a0[0]["frequency_hz"])
    v = np.array(a0[0]["group_velocity_m_s"])
    s = np.array(a0[0]["sigma_m_s"])
    assert f.size >= 20
    cg = safe.group_velocity(load_specimen("cfrp").laminate, f, "A0")
    assert np.abs(v / cg - 1).max() < 0.01
    assert np.all(s > 0) and np.all(s < 0.05 * v)
    assert feats["rig"]["wave_path_m"] == pytest.approx(0.15)  # mfc1 0.05 m -> mfc2 0.20 m


@pytest.mark.slow
def test_results_stored_in_the_run_and_readable(analysed, run_file):
    from labid.features import read_features, specimen_of
    from labid.runstore import RunStore
    out, feats, _ = analysed
    doc = read_features(out)
    assert specimen_of(doc, out.parent, str(out)).laminate.thickness == pytest.approx(1.6e-3, rel=1e-3)
    with RunStore(run_file, "r") as st:
        g = st.read_group("analysis")
    assert json.loads(g["features"]["json"]) == feats
    assert g["spectrum"]["frequencies_hz"].shape == g["spectrum"]["indicator"].shape
    np.testing.assert_allclose(g["peaks"]["frequency_hz"], feats["modal"]["frequencies_hz"])
    assert g["arrivals"]["times_s"].size == g["arrivals"]["frequencies_hz"].size > 0
    # the report module finds the features where it looks for them
    from labid.report import FEATURES_GROUPS, decode_group, lookup
    assert decode_group(lookup({"analysis": g}, FEATURES_GROUPS)) == feats


def test_user_errors_exit_2(tmp_path: Path, capsys):
    assert main(["analyze", str(tmp_path / "missing.h5")]) == 2
    err = capsys.readouterr().err
    assert "missing.h5" in err and err.count("\n") == 1
    bad = tmp_path / "bad.h5"
    bad.write_text("not hdf5")
    assert main(["analyze", str(bad)]) == 2
    assert main(["analyze", str(bad), "--wave-band", "200e3,10e3,5"]) == 2
    with pytest.raises(SystemExit) as e:  # argparse: unknown option
        main(["analyze", str(bad), "--no-such-option"])
    assert e.value.code == 2


def test_bad_options_exit_2(run_file_empty: Path, capsys):
    for opt in (["--wave-band", "200e3,10e3"], ["--wavelet", "2"], ["--modal-fmax", "-5"]):
        assert main(["analyze", str(run_file_empty), *opt]) == 2
        err = capsys.readouterr().err
        assert opt[0] in err


@pytest.fixture
def run_file_empty(tmp_path: Path) -> Path:
    """A run file with the configuration but no shots."""
    from importlib import resources
    from labid.runstore import RunStore
    p = tmp_path / "empty.h5"
    with RunStore(p, "a") as st:
        st.write_config(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text(),
                        resources.files("labid.data").joinpath("rig_default.toml").read_text())
    return p


def test_run_without_shots_is_a_user_error(run_file_empty: Path, capsys):
    assert main(["analyze", str(run_file_empty)]) == 2
    assert "shots" in capsys.readouterr().err
