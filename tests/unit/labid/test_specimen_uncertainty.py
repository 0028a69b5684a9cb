"""A bad ``[uncertainty]`` entry of the specimen is refused where the specimen is read,
before any fit: exit 2, one line naming the file, the key, the value and what was expected."""
from __future__ import annotations

import json

import pytest

from labid.workflows.identification import flow
from labid.cli.main import main as cli_main
from labid.base.errors import UserError
from labid.inputs.specimen import load_specimen

SPEC = """name = "Al"
[plate]
length = 0.5
width = 0.35
[materials.Al]
density = 2700.0
E = 70e9
G = 26.3e9
[layup]
material = "Al"
angles_deg = [0]
ply_thickness = 5e-4
[uncertainty]
"""
#: (entry, key named, text the line must hold)
BAD = [("thickness = -1e-5", "uncertainty.thickness", "-1e-05"),
       ('thickness = "2e-5"', "uncertainty.thickness", "'2e-5'"),
       ("thickness = inf", "uncertainty.thickness", "inf"),
       ("density = 27.0\nmass = 0.005", "uncertainty.mass", "0.005"),
       ("thickness = true", "uncertainty.thickness", "True"),
       ("thikness = 2e-5", "uncertainty.thikness", "unknown key")]


@pytest.mark.parametrize("entry,key,value", BAD)
def test_bad_uncertainty_refused_when_read(tmp_path, entry, key, value):
    p = tmp_path / "spec.toml"
    p.write_text(SPEC + entry + "\n")
    with pytest.raises(UserError) as e:
        load_specimen(p)
    assert e.value.key == key and value in str(e.value) and "expected" in str(e.value)


@pytest.mark.parametrize("entry,key,value", BAD)
def test_identify_exits_2_before_any_fit(tmp_path, monkeypatch, capsys, entry, key, value):
    (tmp_path / "spec.toml").write_text(SPEC + entry + "\n")
    feats = {"specimen": "spec.toml", "modal": {"frequencies_hz": [100.0, 200.0, 300.0],
                                                "sigma_hz": [0.1, 0.1, 0.1]}}
    (tmp_path / "f.json").write_text(json.dumps(feats))
    fits = []
    monkeypatch.setattr(flow, "run", lambda *a, **k: fits.append(a) or pytest.fail("fit started"))
    rc = cli_main(["identify", str(tmp_path / "f.json")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and not fits
    assert len(err) == 1, err
    assert "spec.toml" in err[0] and key in err[0] and value in err[0] and "expected" in err[0]
    assert "Traceback" not in err[0]
