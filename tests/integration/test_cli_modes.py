"""``labid modes`` (CONTRACT section 3): keys, exit codes, shapes."""
import json

import numpy as np
import pytest

from labid.cli.main import main

NAFEMS_FV12 = [1.622, 2.360, 2.922, 4.190, 4.190, 7.356, 7.356, 7.668]

FV12_TOML = """
name = "NAFEMS FV12"
[plate]
length = 10.0
width = 10.0
[materials.steel]
density = 8000.0
E = 200e9
nu = 0.3
[layup]
material = "steel"
angles_deg = [0]
ply_thickness = 0.05
"""


def _run(argv, tmp_path):
    out = tmp_path / "out.json"
    rc = main([*argv, "--json", str(out)])
    return rc, (json.loads(out.read_text()) if rc == 0 else None)


def test_modes_fv12_spec_file(tmp_path):
    spec = tmp_path / "fv12.toml"
    spec.write_text(FV12_TOML)
    rc, res = _run(["modes", str(spec), "--n", "8"], tmp_path)
    assert rc == 0
    f = res["frequencies_hz"]
    assert len(f) == 8 and f == sorted(f)
    np.testing.assert_allclose(f, NAFEMS_FV12, rtol=5e-3)


def test_modes_builtin_default_n_and_shapes(tmp_path):
    rc, res = _run(["modes", "cfrp", "--shapes", "--grid", "5x4"], tmp_path)
    assert rc == 0
    assert len(res["frequencies_hz"]) == 10
    ms = res["mode_shapes"]
    assert ms["grid"] == [5, 4] and len(ms["points"]) == 20
    assert np.array(ms["values"]).shape == (10, 20)
    pts = np.array(ms["points"])
    assert pts.min() == 0.0 and pts.max() == pytest.approx(0.33)


def test_modes_user_errors(tmp_path, capsys):
    for argv in (["modes", "cfrp", "--mesh", "8"], ["modes", "cfrp", "--mesh", "0x4"],
                 ["modes", "cfrp", "--n", "0"], ["modes", str(tmp_path / "missing.toml")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("labid modes: error:") and "\n" not in err


def test_modes_explicit_mesh(tmp_path):
    rc, res = _run(["modes", "cfrp", "--mesh", "3x3", "--n", "4"], tmp_path)
    assert rc == 0
    assert res["mesh"]["nx"] == 3 and not res["mesh"]["graded"]
