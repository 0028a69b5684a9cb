"""Specimen files (CONTRACT section 1): reading and one-line errors."""
import subprocess
import sys
import textwrap

import pytest

from labid.base.errors import UserError
from labid.inputs.specimen import load_specimen

CONTRACT_EXAMPLE = textwrap.dedent("""
    name = "CFRP [0/+45/-45]2s, 1.6 mm"
    [plate]
    length = 0.33
    width  = 0.33
    [materials.T300]
    density = 1560.0
    E1 = 136.7e9
    E2 = 9.0e9
    nu12 = 0.30
    G12 = 5.0e9
    G13 = 5.08e9
    G23 = 3.16e9
    [layup]
    material = "T300"
    angles_deg = [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0]
    ply_thickness = 1.3333e-4
""")


def write(tmp_path, text, name="spec.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_contract_example(tmp_path):
    s = load_specimen(write(tmp_path, CONTRACT_EXAMPLE))
    assert s.name.startswith("CFRP")
    assert len(s.laminate.plies) == 12
    assert s.laminate.thickness == pytest.approx(12 * 1.3333e-4)
    m = s.laminate.plies[0].material
    assert (m.E1, m.G23, m.e3) == (136.7e9, 3.16e9, 9.0e9)
    assert [p.angle_deg for p in s.laminate.plies][:3] == [0, 45, -45]
    assert s.mass == pytest.approx(0.33 * 0.33 * 12 * 1.3333e-4 * 1560.0)


def test_builtin_equals_contract_example(tmp_path):
    assert load_specimen("cfrp").laminate == load_specimen(write(tmp_path, CONTRACT_EXAMPLE)).laminate


def test_isotropic_and_plies_tables(tmp_path):
    s = load_specimen(write(tmp_path, textwrap.dedent("""
        [plate]
        length = 0.5
        width = 0.4
        [materials.Al]
        density = 2700.0
        E = 71.04e9
        nu = 0.33
        [[plies]]
        material = "Al"
        angle_deg = 0
        thickness = 1e-3
        [[plies]]
        material = "Al"
        angle_deg = 90
        thickness = 2e-3
    """)))
    assert s.laminate.thickness == pytest.approx(3e-3)
    m = s.laminate.plies[0].material
    assert m.isotropic and m.G12 == pytest.approx(71.04e9 / 2.66)


@pytest.mark.parametrize("edit, key, expect", [
    (("length = 0.33\n", ""), "plate.length", "missing"),
    (("ply_thickness = 1.3333e-4", "ply_thickness = -1.3333e-4"), "layup.ply_thickness", "positive"),
    (("nu12 = 0.30", "nu12 = 4.5"), "materials.T300", "positive definite"),
    (('material = "T300"', 'material = "T800"'), "layup.material", "not defined"),
    (("E2 = 9.0e9", 'E2 = "nine"'), "materials.T300.E2", "expected a number"),
])
def test_bad_files_name_key(tmp_path, edit, key, expect):
    p = write(tmp_path, CONTRACT_EXAMPLE.replace(*edit))
    with pytest.raises(UserError) as ei:
        load_specimen(p)
    msg = str(ei.value)
    assert str(p) in msg and key in msg and expect in msg
    assert "\n" not in msg


def test_cli_exit_code_2_one_line(tmp_path):
    """A bad specimen on the command line: exit 2, one line on stderr, no traceback."""
    p = write(tmp_path, CONTRACT_EXAMPLE.replace("ply_thickness = 1.3333e-4", "ply_thickness = -1"))
    for args in (["dispersion", str(p), "--fmax", "1e5"], ["modes", str(p)]):
        r = subprocess.run([sys.executable, "-m", "labid.cli.main", *args], capture_output=True, text=True)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "layup.ply_thickness" in lines[0] and "Traceback" not in r.stderr


def test_cli_bad_option_exit_2():
    r = subprocess.run([sys.executable, "-m", "labid.cli.main", "no-such-command"], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
