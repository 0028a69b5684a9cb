"""``labid dispersion`` (CONTRACT section 3) against the exact Rayleigh-Lamb table."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from labid.cli.main import main

AL_TOML = """
name = "Al 1 mm (ORACLES)"
[plate]
length = 0.5
width = 0.5
[materials.Al]
density = 2700.0
E = 70.0e9
nu = 0.33
[layup]
material = "Al"
angles_deg = [0]
ply_thickness = 1.0e-3
"""
# ORACLES.md, f h = 0.1, 0.5, 1, 2 MHz mm
TABLE = {
    "A0": ([954.234, 1878.339, 2326.643, 2675.330], [1783.696, 2908.787, 3137.051, 3126.912]),
    "S0": ([5393.172, 5374.785, 5308.589, 4759.445], [5391.689, 5335.510, 5118.634, 3066.727]),
}


def test_dispersion_json_matches_rayleigh_lamb(tmp_path):
    spec = tmp_path / "al.toml"
    spec.write_text(AL_TOML)
    out = tmp_path / "d.json"
    png = tmp_path / "d.png"
    assert main(["dispersion", str(spec), "--fmax", "2e6", "--n", "20", "--json", str(out),
                 "--plot", str(png)]) == 0
    res = json.loads(out.read_text())
    labels = [m["label"] for m in res["modes"]]
    assert labels[:3] == ["A0", "S0", "SH0"] and {"A1", "SH1"} <= set(labels)
    by = {m["label"]: m for m in res["modes"]}
    grid = np.arange(1, 21) * 2e6 / 20
    for lbl, (cp, cg) in TABLE.items():
        m = by[lbl]
        np.testing.assert_allclose(m["frequency_hz"], grid)          # exists everywhere
        idx = [0, 4, 9, 19]                                          # 0.1, 0.5, 1, 2 MHz
        np.testing.assert_allclose(np.array(m["phase_velocity_m_s"])[idx], cp, rtol=1e-5)
        np.testing.assert_allclose(np.array(m["group_velocity_m_s"])[idx], cg, rtol=1e-5)
    # a higher mode lists only the grid points above its cut-off, no nulls
    a1 = by["A1"]
    assert len(a1["frequency_hz"]) == len(a1["group_velocity_m_s"]) == len(a1["phase_velocity_m_s"])
    assert 0 < len(a1["frequency_hz"]) < 20 and min(a1["frequency_hz"]) > a1["cutoff_hz"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_builtin_cfrp_and_direction(tmp_path):
    out = tmp_path / "c.json"
    assert main(["dispersion", "cfrp", "--fmax", "2e5", "--n", "10", "--direction-deg", "90",
                 "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["direction_deg"] == 90.0 and [m["label"] for m in res["modes"]] == ["A0", "S0", "SH0"]
    s0 = next(m for m in res["modes"] if m["label"] == "S0")
    assert 3000 < s0["group_velocity_m_s"][0] < 7000


def test_bad_fmax_is_a_user_error(tmp_path, capsys):
    for bad in ("0", "-5", "nan"):
        assert main(["dispersion", "cfrp", "--fmax", bad]) == 2
        err = capsys.readouterr().err
        assert "--fmax" in err and len(err.strip().splitlines()) == 1
    # the real entry point: exit code 2, one line, no traceback
    r = subprocess.run([sys.executable, "-m", "labid.cli.main", "dispersion", str(tmp_path / "missing.toml"),
                        "--fmax", "1e5"], capture_output=True, text=True)
    assert r.returncode == 2 and "missing.toml" in r.stderr and "Traceback" not in r.stderr
