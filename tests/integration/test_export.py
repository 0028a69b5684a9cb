"""``labid export``: what it writes, pyuff reads back with the same values, and ``labid
import`` reads back into the same shots; the CSV tables hold the results' numbers."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import pyuff

from labid import services
from labid.cli.main import main
from labid.io.exporters import result_tables, uff_modes


@pytest.fixture(scope="module")
def analysed(tmp_path_factory) -> Path:
    """Two hammer hits and one wave shot on the simulated rig, analysed."""
    d = tmp_path_factory.mktemp("export")
    run = d / "run.h5"
    assert main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "2", "--waves", "1", "--quiet"]) == 0
    assert main(["analyze", str(run), "--out", str(d / "features.json")]) == 0
    return run


@pytest.fixture(scope="module")
def exported(analysed) -> tuple[Path, list[dict]]:
    uff = analysed.with_name("run.uff")
    assert main(["export", str(analysed), "--uff", str(uff), "--csv", str(analysed.with_name("csv"))]) == 0
    sets = pyuff.UFF(str(uff)).read_sets()
    return uff, sets


def rows(path: Path) -> list[dict]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_time_data_read_back_by_pyuff_equal_the_shots(analysed, exported):
    _, sets = exported
    t = [s for s in sets if s["type"] == 58 and s["func_type"] == 1]
    recs = services.shots(analysed, "hammer") + services.shots(analysed, "wave")
    assert len(t) == sum(len(r.channels) for r in recs)
    i = 0
    for r in recs:
        for c in r.channels:
            s = t[i]
            i += 1
            assert s["id1"].strip() == c.name and s["id2"].strip() == r.meta["shot"]
            np.testing.assert_array_equal(s["data"], r.scaled(c.name))            # binary: exact
            assert s["abscissa_inc"] == pytest.approx(1 / r.timing.rate_hz, rel=5e-6)   # E13.5
            assert s["abscissa_min"] == pytest.approx(-r.timing.pretrigger / r.timing.rate_hz, rel=5e-6)
            assert s["ordinate_axis_units_lab"].strip() == {"force": "N", "accelerometer": "m/s^2",
                                                            "voltage": "V"}[c.kind]


def test_frfs_and_modes_read_back_by_pyuff(analysed, exported):
    _, sets = exported
    spec = services.spectra_of_run(analysed)
    frf = [s for s in sets if s["type"] == 58 and s["func_type"] == 4]
    assert [s["id1"].strip() for s in frf] == [f"H1 {c}" for c in spec.channels]
    for k, s in enumerate(frf):
        np.testing.assert_array_equal(s["data"], spec.frf[k])
        assert s["rsp_dir"] == 3 and s["ref_node"] == 7      # hammer node: the rig's 6 channels + 1
    feats = services.stored_features(analysed)["modal"]
    modes = [s for s in sets if s["type"] == 55]
    assert len(modes) == len(feats["frequencies_hz"])
    for s, f, z in zip(modes, feats["frequencies_hz"], feats["damping_ratio"]):
        assert s["freq"] == pytest.approx(f, rel=5e-6) and s["modal_damp_vis"] == pytest.approx(z, rel=5e-6)
    shapes = feats["mode_shapes"]["values"]
    for s, v in zip(modes, shapes):      # E13.5: 6 digits
        np.testing.assert_allclose(s["r3"], v, rtol=5e-6, atol=5e-6 * np.max(np.abs(v)))
    nodes = next(s for s in sets if s["type"] == 15)
    pts = dict(zip(np.asarray(nodes["node_nums"], int), zip(nodes["x"], nodes["y"])))
    for n, (x, y) in zip(np.asarray(modes[0]["node_nums"], int), feats["mode_shapes"]["points"]):
        assert pts[n] == pytest.approx((x, y), abs=1e-6)


def test_exported_uff_imports_back_into_the_same_shots(analysed, exported, tmp_path):
    uff, _ = exported
    out = tmp_path / "back.h5"
    assert main(["import", str(uff), "--rig", "default", "--specimen", "cfrp", "--out", str(out),
                 "--map", "force=force,acc1=acc1,acc2=acc2,acc3=acc3"]) == 0
    a, b = services.shots(out, "hammer"), services.shots(analysed, "hammer")
    assert len(a) == len(b) == 2
    for x, y in zip(a, b):
        assert x.timing == y.timing
        for c in y.channels:
            np.testing.assert_allclose(x.data[c.name], y.data[c.name], rtol=4.5e-16, atol=0)


def test_uff55_carries_damping_when_given(tmp_path):
    sets = uff_modes([10.0, 20.5], nodes=[3, 4], shapes=[[1.0, -0.5], [0.2, 1.0]], damping_ratio=[0.01, 0.02],
                     loss_factor=[0.021, 0.039])
    path = tmp_path / "m.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    back = pyuff.UFF(str(path)).read_sets()
    assert [s["modal_damp_vis"] for s in back] == [0.01, 0.02]
    assert [s["modal_damp_his"] for s in back] == [0.021, 0.039]
    np.testing.assert_array_equal(back[1]["r3"], [0.2, 1.0])


def test_csv_features_hold_the_features_numbers(analysed, exported):
    d = analysed.with_name("csv")
    feats = services.stored_features(analysed)
    m = rows(d / "features_modal.csv")
    assert [float(r["frequency_hz"]) for r in m] == feats["modal"]["frequencies_hz"]
    assert [float(r["damping_ratio"]) for r in m] == feats["modal"]["damping_ratio"]
    if feats.get("waves"):
        w = rows(d / "features_waves.csv")
        assert [float(r["group_velocity_m_s"]) for r in w] == [v for c in feats["waves"]
                                                                for v in c["group_velocity_m_s"]]


def test_identify_and_diagnose_csv_tables(tmp_path):
    ident = {"parameters": {"E1": {"value": 1.3e11, "std": 2e9}, "nu12": {"value": 0.3, "std": 0.01}},
             "identifiability": {"parameters": {"E1": {"rel_std": 0.0154, "identified": True,
                                                       "constrained_by": ["modal", "waves"]}}}}
    (f,) = result_tables(ident, "identification", tmp_path)
    r = rows(Path(f))
    assert [(x["parameter"], float(x["value"]), float(x["std"]), x["unit"]) for x in r] == [
        ("E1", 1.3e11, 2e9, "Pa"), ("nu12", 0.3, 0.01, "1")]
    assert r[0]["constrained_by"] == "modal+waves" and float(r[1]["rel_std"]) == pytest.approx(0.01 / 0.3)
    diag = {"gap": {"before": 3.2, "after": 1.1, "significant": True}, "verdict": "sensor_mass", "where": ["modal"],
            "effects": [{"name": "sensor_mass", "magnitude": 0.003, "unit": "kg", "gap_after": 1.1, "score": 0.9}],
            "features": {"labels": ["mode 1", "mode 2"], "residual_before": [3.0, -1.0], "residual_after": [0.1, 0.2]}}
    files = result_tables(diag, "diagnosis", tmp_path)
    assert [Path(p).name for p in files] == ["diagnosis_summary.csv", "diagnosis_effects.csv",
                                            "diagnosis_residuals.csv"]
    s = {x["quantity"]: x["value"] for x in rows(tmp_path / "diagnosis_summary.csv")}
    assert s["before"] == "3.2" and s["verdict"] == "sensor_mass" and s["where"] == "modal"
    e = rows(tmp_path / "diagnosis_effects.csv")[0]
    assert (e["rank"], e["name"], float(e["magnitude"]), e["unit"]) == ("1", "sensor_mass", 0.003, "kg")
    res = rows(tmp_path / "diagnosis_residuals.csv")
    assert [(x["feature"], float(x["residual_before"])) for x in res] == [("mode 1", 3.0), ("mode 2", -1.0)]


@pytest.mark.slow
def test_identify_csv_option_writes_the_constants(tmp_path):
    from labid.workflows.identification import synthetic_features
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 5),))
    doc["specimen"] = "aluminium"
    f = tmp_path / "f.json"
    f.write_text(json.dumps(doc))
    assert main(["identify", str(f), "--json", str(tmp_path / "r.json"), "--csv", str(tmp_path / "t")]) == 0
    res = json.loads((tmp_path / "r.json").read_text())
    r = rows(tmp_path / "t" / "constants.csv")
    assert {x["parameter"]: float(x["value"]) for x in r} == {k: v["value"] for k, v in res["parameters"].items()}


def test_export_without_output_is_a_user_error(analysed, capsys):
    assert main(["export", str(analysed)]) == 2
    assert "expected --uff FILE and/or --csv DIR" in capsys.readouterr().err
