"""labid.inputs.features: the features JSON of CONTRACT section 2 (read / validate / write)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from labid.inputs import features as F
from labid.base.errors import UserError

# the example of CONTRACT section 2, completed
EXAMPLE = {
    "specimen": "specimen.toml",
    "modal": {
        "frequencies_hz": [37.3, 85.8, 110.9],
        "sigma_hz": [0.05, 0.05, 0.05],
        "mode_shapes": {"points": [[0.02, 0.02], [0.31, 0.02]],
                        "values": [[1.0, -0.5], [0.2, 1.0], [1.0, 1.0]]},
    },
    "waves": [
        {"mode": "A0", "direction_deg": 0.0, "frequency_hz": [5000.0, 10000.0],
         "group_velocity_m_s": [812.0, 1103.0], "sigma_m_s": [10.0, 10.0]},
    ],
    "rig": {
        "temperature_c": 23.0,
        "accelerometers": [{"x": 0.02, "y": 0.02, "mass_kg": 0.002}],
        "supports": [{"x": 0.0, "y": 0.30}],
        "wave_path_m": 0.375,
        "sensor_length_m": 0.01,
    },
}


def test_contract_example_round_trip(tmp_path: Path):
    p = tmp_path / "f.json"
    F.write_features(p, EXAMPLE)
    assert json.loads(p.read_text()) == EXAMPLE
    assert F.read_features(p) == EXAMPLE


def test_null_velocity_is_nan_and_written_back_as_null(tmp_path: Path):
    doc = json.loads(json.dumps(EXAMPLE))
    doc["waves"][0]["group_velocity_m_s"] = [812.0, float("nan")]
    p = tmp_path / "f.json"
    F.write_features(p, doc)
    assert json.loads(p.read_text())["waves"][0]["group_velocity_m_s"] == [812.0, None]
    back = F.read_features(p)
    assert math.isnan(back["waves"][0]["group_velocity_m_s"][1])


def test_specimen_path_relative_to_the_json_file(tmp_path: Path, monkeypatch):
    spec = tmp_path / "specs" / "plate.toml"
    spec.parent.mkdir()
    from importlib import resources
    spec.write_text(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text())
    out = tmp_path / "results" / "f.json"
    out.parent.mkdir()
    monkeypatch.chdir(tmp_path)
    doc = F.write_features(out, {"modal": EXAMPLE["modal"]}, specimen_path="specs/plate.toml")
    assert doc["specimen"] == "../specs/plate.toml"
    monkeypatch.chdir(out.parent.parent.parent)  # somewhere else: still found from the JSON's folder
    s = F.specimen_of(F.read_features(out), out.parent, str(out))
    assert s.length == pytest.approx(0.33)
    assert F.specimen_of({"specimen": "aluminium"}).laminate.thickness == pytest.approx(3.175e-3)


def test_inline_specimen_table(tmp_path: Path):
    import tomllib
    from importlib import resources
    table = tomllib.loads(resources.files("labid.data").joinpath("aluminium_3175.toml").read_text())
    p = tmp_path / "f.json"
    F.write_features(p, {"specimen": table, "waves": EXAMPLE["waves"]})
    s = F.specimen_of(F.read_features(p), tmp_path, str(p))
    assert s.laminate.thickness == pytest.approx(3.175e-3)
    bad = json.loads(json.dumps(table))
    del bad["plate"]["width"]
    with pytest.raises(UserError, match="plate.width"):
        F.validate_features({"specimen": bad}, "x.json")


@pytest.mark.parametrize("edit, key, value", [
    (lambda d: d["modal"]["frequencies_hz"].__setitem__(1, -3.0), "modal.frequencies_hz[1]", "-3.0"),
    (lambda d: d["modal"].__setitem__("sigma_hz", [0.1]), "modal.sigma_hz", "1 values"),
    (lambda d: d["modal"]["mode_shapes"]["values"][2].append(0.0), "modal.mode_shapes.values[2]", "expected 2"),
    (lambda d: d["waves"][0].__setitem__("mode", "B0"), "waves[0].mode", "'B0'"),
    (lambda d: d["waves"][0]["group_velocity_m_s"].__setitem__(0, "fast"), "waves[0].group_velocity_m_s[0]", "'fast'"),
    (lambda d: d["waves"][0].__setitem__("frequency_hz", [1.0]), "waves[0].group_velocity_m_s", "2 values"),
    (lambda d: d["rig"]["accelerometers"][0].__setitem__("mass_kg", -1.0), "rig.accelerometers[0].mass_kg", "-1.0"),
    (lambda d: d["rig"]["supports"][0].pop("y"), "rig.supports[0].y", "missing"),
    (lambda d: d["rig"].__setitem__("wave_path_m", 0), "rig.wave_path_m", "0"),
    (lambda d: d.__setitem__("waves", {"mode": "A0"}), "waves", "expected a list"),
])
def test_errors_name_file_key_and_value(tmp_path: Path, edit, key, value):
    doc = json.loads(json.dumps(EXAMPLE))
    edit(doc)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(UserError) as e:
        F.read_features(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}: {key}:"), msg
    assert value in msg
    assert "\n" not in msg


def test_unreadable_files(tmp_path: Path):
    with pytest.raises(UserError, match="file not found"):
        F.read_features(tmp_path / "none.json")
    p = tmp_path / "broken.json"
    p.write_text("{\"modal\": [")
    with pytest.raises(UserError, match="not valid JSON"):
        F.read_features(p)


def test_identification_reads_what_we_write(tmp_path: Path):
    # the consumer of the file accepts it: a modal + waves problem on the built-in CFRP plate
    from labid import services
    from labid.workflows.identification import problem_from_features
    doc = json.loads(json.dumps(EXAMPLE))
    p = tmp_path / "f.json"
    F.write_features(p, doc, specimen_path="cfrp")
    prob = problem_from_features(services.load_features_file(p), base_dir=p.parent, src=str(p))
    assert len(prob.blocks) == 2


# -- the one parser: document <-> engine.features.Features -------------------------
def test_parse_gives_the_engine_form_and_document_gives_it_back():
    doc = json.loads(json.dumps(EXAMPLE))
    doc["specimen"] = "cfrp"
    doc["waves"][0]["group_velocity_m_s"] = [812.0, None]
    parsed = F.parse_features(doc)
    ft = parsed.features
    assert parsed.specimen.name == ft.specimen_name and ft.length == parsed.specimen.length
    assert ft.modal.frequency_hz.tolist() == [37.3, 85.8, 110.9]
    assert ft.modal.shapes.tolist() == [[1.0, -0.5], [0.2, 1.0], [1.0, 1.0]]
    w = ft.waves[0]
    assert (w.mode, w.direction_deg, w.frequency_hz.tolist()) == ("A0", 0.0, [5000.0, 10000.0])
    assert w.group_velocity_m_s[0] == 812.0 and math.isnan(w.group_velocity_m_s[1])
    assert ft.rig.accelerometers == ((0.02, 0.02),) and ft.rig.accelerometer_masses == (0.002,)
    assert ft.rig.masses() == [(0.02, 0.02, 0.002)]
    assert (ft.rig.wave_path_m, ft.rig.sensor_length_m, ft.rig.temperature_c) == (0.375, 0.01, 23.0)
    assert parsed.notes == ()
    back = F.features_document(ft, "cfrp")
    again = F.parse_features(back).features
    for a, b in ((ft.modal.frequency_hz, again.modal.frequency_hz), (ft.modal.sigma_hz, again.modal.sigma_hz),
                 (ft.modal.points, again.modal.points), (ft.waves[0].sigma_m_s, again.waves[0].sigma_m_s)):
        assert a.tolist() == b.tolist()
    assert again.rig == ft.rig
    v = back["waves"][0]["group_velocity_m_s"]
    assert v[0] == 812.0 and math.isnan(v[1])      # written as null by write_features


def test_parse_assumes_sigmas_with_a_note():
    doc = {"specimen": "cfrp", "modal": {"frequencies_hz": [100.0, 200.0]},
           "waves": [{"mode": "A0", "frequency_hz": [1e4], "group_velocity_m_s": [900.0]}]}
    parsed = F.parse_features(doc)
    assert parsed.features.modal.sigma_hz.tolist() == pytest.approx([0.1, 0.2])   # 0.1 %
    assert parsed.features.waves[0].sigma_m_s.tolist() == pytest.approx([9.0])    # 1 %
    assert parsed.notes == ("modal.sigma_hz absent: assuming 0.1% of the values",
                            "waves[0].sigma_m_s absent: assuming 1.0% of the values")


def test_diagnosis_reads_a_file_with_an_unmeasured_velocity(tmp_path: Path):
    """A null velocity (what labid analyze writes for a frequency it cannot pick) is read
    back as NaN; the diagnosis drops that point instead of rejecting the file."""
    from labid.workflows.diagnosis import gap_features_and_notes
    doc = json.loads(json.dumps(EXAMPLE))
    doc["specimen"] = "cfrp"
    doc["waves"][0]["group_velocity_m_s"] = [812.0, None]
    p = tmp_path / "f.json"
    F.write_features(p, doc)
    problem, _ = gap_features_and_notes(F.read_features(p), tmp_path, str(p))
    w = problem.waves[0]
    assert w.frequency_hz.tolist() == [5000.0] and w.group_velocity_m_s.tolist() == [812.0]
