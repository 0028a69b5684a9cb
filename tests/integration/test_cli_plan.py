"""``labid plan`` (issue 25): its outputs, the rig file it writes, the ranking of candidate
rigs, the thin-plate scaling law of its budget, and one line with exit 2 for bad input.

Small problems (aluminium 1 m plate, 7 x 7 candidates, 2 draws, 20 modes) keep it cheap."""
from __future__ import annotations

import json
import math

import pytest

from labid.cli.main import main
from labid.inputs.rig import load_rig, read_rig_text

SMALL = ["--grid", "7", "--draws", "2", "--max-modes", "20"]


def _rig_with(tmp_path, name: str, accs, tap) -> str:
    """The built-in rig with its three accelerometers and the hammer moved."""
    text, _ = read_rig_text(None)
    import tomlkit
    doc = tomlkit.parse(text)
    doc["hammer"]["x"], doc["hammer"]["y"] = tap
    chans = [c for c in doc["devices"]["vib"]["channels"] if c["kind"] == "accelerometer"]
    for c, (x, y) in zip(chans, accs):
        c["x"], c["y"] = x, y
    p = tmp_path / name
    p.write_text(tomlkit.dumps(doc))
    return str(p)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plan")
    # a rig with the tap at the plate's centre and the sensors on its centre lines: every mode
    # antisymmetric about a centre line vanishes at the tap, so it must rank last
    bad = _rig_with(tmp, "bad.toml", [(0.5, 0.25), (0.25, 0.5), (0.5, 0.75)], (0.5, 0.5))
    good = _rig_with(tmp, "good.toml", [(0.05, 0.07), (0.93, 0.11), (0.62, 0.94)], (0.17, 0.31))
    out = tmp / "plan.json"
    rc = main(["plan", "aluminium", "--want", "E,G", *SMALL, "--compare", bad, good, "--json", str(out),
               "--write-rig", str(tmp / "planned.toml"), "--plot", str(tmp / "plan.png"), "-q"])
    assert rc == 0
    return json.loads(out.read_text()), tmp


def test_plan_json_holds_the_layouts_and_predictions(planned):
    doc, _ = planned
    rec = doc["recommended"]
    assert len(rec["accelerometers"]) == 3 and set(rec["hammer"]) == {"x", "y"}
    assert set(rec["constants"]) == {"E", "G"}
    for c in rec["constants"].values():
        assert 0 < c["type_a_rel"] <= c["std_rel"] <= c["std_rel_worst"] * (1 + 1e-12)
    assert doc["fitted"] == ["E", "G"] and doc["waves"]["recommended"] is False
    assert doc["identify"].endswith("--params E,G")
    assert [r["label"] for r in doc["rigs"]] == ["built-in default rig", "compare 1", "compare 2"]


def test_compared_rigs_are_ranked_and_the_plan_beats_them(planned):
    doc, _ = planned
    bad, good = doc["rigs"][1], doc["rigs"][2]
    assert good["rank"] == 1 and bad["rank"] == 2
    assert bad["modes_seen"]["nominal"] < good["modes_seen"]["nominal"]
    assert doc["recommended"]["criterion"] <= min(r["criterion"] for r in doc["rigs"]) + 1e-9


def test_written_rig_is_a_valid_rig_with_the_plan(planned):
    doc, tmp = planned
    rig = load_rig(tmp / "planned.toml")
    rec = doc["recommended"]
    assert (rig.hammer.x, rig.hammer.y) == pytest.approx((rec["hammer"]["x"], rec["hammer"]["y"]), abs=1e-4)
    got = [(c.x, c.y) for c in rig.accelerometers]
    assert got == [pytest.approx((a["x"], a["y"]), abs=1e-4) for a in rec["accelerometers"]]
    assert "# impact point of the vibration test" in (tmp / "planned.toml").read_text()   # comments kept
    assert (tmp / "plan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_budget_follows_the_thin_plate_scaling_law(tmp_path):
    """A thin free isotropic plate has f ~ h sqrt(E / rho) / a^2 (docs/uncertainty.md): with
    E and G fitted, a 1 % thickness error moves both by 2 %, a 1 % density error by 1 %
    (the specimen's defaults)."""
    out = tmp_path / "b.json"
    rc = main(["plan", "aluminium", "--want", "E,G", *SMALL, "--budget", "specimen", "--json", str(out), "-q"])
    assert rc == 0
    doc = json.loads(out.read_text())
    for n in ("E", "G"):
        c = doc["recommended"]["constants"][n]
        var = c["std_rel"] ** 2
        assert math.sqrt(c["shares"]["thickness"] * var) == pytest.approx(0.02, rel=0.02)
        assert math.sqrt(c["shares"]["density"] * var) == pytest.approx(0.01, rel=0.02)


@pytest.mark.parametrize("argv, key", [
    (["--grid", "100"], "--grid"),
    (["--want", "E1"], "--want"),
    (["--target-u", "abc"], "--target-u"),
    (["--prior", "E1=5%"], "--prior"),
    (["--budget", "notes.txt"], "--budget"),
    (["--draws", "0"], "--draws"),
])
def test_bad_options_are_one_line_exit_2(argv, key, capsys):
    assert main(["plan", "aluminium", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0] and err[0].startswith("labid plan: error:")


def test_rig_off_the_plate_is_one_line_exit_2(tmp_path, capsys):
    rig = _rig_with(tmp_path, "off.toml", [(0.05, 0.05), (0.2, 0.05), (0.05, 0.2)], (0.1, 0.1))
    assert main(["plan", "cfrp", "--rig", rig, "--compare", _rig_with(tmp_path, "far.toml",
                 [(0.05, 0.05), (0.2, 0.05), (0.05, 0.5)], (0.1, 0.1))]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "far.toml" in err[0] and "outside" in err[0]
