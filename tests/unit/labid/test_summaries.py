"""Console summaries (labid.base.summary) and the commands' printed tables.

Numbers asserted come from outside the code: SI prefixes by definition, the
expanded uncertainty U = k x std (GUM, k = 2), the demo's true constants.
"""
from __future__ import annotations

import math

import pytest

from labid.base import summary


@pytest.mark.parametrize("value, unit, text", [
    (1.367e11, "Pa", "136.7 GPa"),        # the issue's own example
    (9.0e9, "Pa", "9.000 GPa"),
    (4.94e-4, "Hz", "494.0 µHz"),
    (12345.0, "Hz", "12.35 kHz"),
    (999.96e9, "Pa", "1.000 TPa"),        # rounding carries to the next prefix
    (-2.5e-3, "m", "-2.500 mm"),
    (0.0, "Hz", "0 Hz"),
    (0.3, "", "0.3"),
])
def test_engineering_notation(value, unit, text):
    assert summary.eng(value, unit) == text


def test_missing_values_print_a_dash():
    assert summary.eng(None, "Pa") == "—"
    assert summary.eng(math.nan, "Hz") == "—"


def test_units_by_constant_name():
    assert [summary.unit_of(n) for n in ("E1", "G12", "nu12", "density", "C11")] == \
        ["Pa", "Pa", "", "kg/m³", "Pa"]
    # the CSV's unit column: ASCII, '1' for a ratio
    assert [summary.unit_of(n, plain=True) for n in ("E1", "nu12", "density")] == ["Pa", "1", "kg/m^3"]


def test_expanded_uncertainty_is_k_times_std_in_the_value_prefix():
    assert summary.constant_cells("E1", 136.7e9, 0.8e9)[:3] == ("136.7 GPa", "0.80 GPa", "1.6 GPa")
    assert summary.constant_cells("nu12", 0.3, 0.004, k=3)[2] == "0.012"


def _rows(text):
    lines = text.splitlines()
    assert set(lines[1].replace(" ", "")) == {"-"}   # the rule under the head
    return lines[0], lines[2:]


def test_constants_table_rows_and_relative_u():
    head, rows = _rows(summary.constants_table(
        {"E1": {"value": 136.7e9, "std": 0.8e9}, "nu12": {"value": 0.3, "std": 0.01}},
        nominal={"E1": 140e9}))
    assert head.split()[:2] == ["constant", "value"] and "nominal" in head
    assert rows[0].split() == ["E1", "136.7", "GPa", "0.80", "GPa", "1.6", "GPa", "1.2", "%", "140.0", "GPa"]
    # rel U = 2 x 0.01 / 0.3 = 6.7 %
    assert rows[1].split() == ["nu12", "0.3", "0.01", "0.02", "6.7", "%", "—"]


def test_pairing_table_names_missing_peaks_and_modes():
    _, rows = _rows(summary.pairing_table([
        {"peak": 1, "measured_hz": 100.0, "mode_index": 1, "family": "(1,1) torsion", "predicted_hz": 101.0},
        {"peak": None, "measured_hz": None, "mode_index": 2, "family": "(2,0)", "predicted_hz": 200.0},
        {"peak": 2, "measured_hz": 300.0, "mode_index": None, "family": None, "predicted_hz": None},
    ]))
    assert rows[0].split()[-2:] == ["+1.00", "%"]          # (101 - 100) / 100
    assert "(1,1) torsion" in rows[0]
    assert rows[1].endswith("predicted mode without a peak")
    assert rows[2].endswith("peak without a mode")


def test_modes_table_columns():
    head, rows = _rows(summary.modes_table([100.0, 250.5], ["(1,1) torsion", "(2,0)"], [0.1, None]))
    assert head.split() == ["mode", "frequency", "(Hz)", "σ", "(Hz)", "family", "(m,n)"]
    assert rows[0].split() == ["1", "100.000", "0.1", "(1,1)", "torsion"]
    assert rows[1].split() == ["2", "250.500", "—", "(2,0)"]


# ---------------------------------------------------------------- the commands' printed summaries
from labid.cli.main import main  # noqa: E402


def _table_rows(text: str, first_col: str) -> dict[str, list[str]]:
    """{first cell: cells} of the rows of the text table whose head starts with ``first_col``."""
    import re
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(first_col))
    rows = {}
    for ln in lines[i + 2:]:
        cells = re.split(r"\s{2,}", ln.strip())    # columns are 2+ spaces apart
        if len(cells) < 2:
            break
        rows[cells[0]] = cells[1:]
    return rows


def test_dispersion_prints_a_table_of_modes(capsys):
    """Aluminium 3.175 mm (E 71.04 GPa, G 25.32 GPa, 2700 kg/m3, the specimen file): SH0 is
    non-dispersive at c_T = sqrt(G/rho) = 3062 m/s, and A1/SH1 start at the thickness-shear
    cut-off c_T / (2h) = 482 kHz (Rose, Ultrasonic Guided Waves in Solid Media, ch. 6)."""
    assert main(["dispersion", "aluminium", "--fmax", "1e6", "--n", "10"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("Aluminium")
    rows = _table_rows(out, "mode")
    assert list(rows)[:3] == ["A0", "S0", "SH0"]
    c_t = math.sqrt(25.32e9 / 2700.0)
    sh0 = rows["SH0"]
    assert sh0[2] == "10"                                       # every grid frequency
    assert [float(x) for x in sh0[3].split("/")] == pytest.approx([c_t, c_t], abs=1)
    cut = c_t / (2 * 3.175e-3)
    for m in ("A1", "SH1"):
        val, unit = rows[m][0].split()
        assert unit == "kHz" and float(val) * 1e3 == pytest.approx(cut, rel=0.01)
    assert out.rstrip().endswith("add --json FILE (numbers) or --plot FILE.png (figure)")


def test_dispersion_with_json_to_stdout_prints_only_json(capsys):
    import json
    assert main(["dispersion", "aluminium", "--fmax", "1e6", "--n", "4", "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["n"] == 4


def test_modes_prints_frequencies_with_family_labels(capsys):
    """The lowest mode of a free square plate is the twisting (1,1) mode, then the
    (0,2)/(2,0) bending pair (Leissa, NASA SP-160, table 4.79); --shapes says where the
    shapes are."""
    assert main(["modes", "cfrp", "--n", "4", "--shapes"]) == 0
    out = capsys.readouterr().out
    rows = _table_rows(out, "mode")
    assert list(rows) == ["1", "2", "3", "4"]
    assert rows["1"][1] == "(1,1) torsion"
    assert {rows["2"][1], rows["3"][1]} == {"(0,2)", "(2,0)"}
    f = [float(r[0]) for r in rows.values()]
    assert f == sorted(f)
    assert "shapes: w0 on a 11 x 11 grid" in out


def test_modes_json_carries_the_families(capsys, tmp_path):
    import json
    p = tmp_path / "m.json"
    assert main(["modes", "cfrp", "--n", "3", "--json", str(p)]) == 0
    doc = json.loads(p.read_text())
    assert doc["families"][0] == "(1,1) torsion" and len(doc["families"]) == 3


def test_next_step_follows_the_workflow():
    assert summary.next_step({}, [])[1].startswith("acquire")
    assert summary.next_step({"hammer": 1}, []) == (
        "acquired: 1 hammer hit, 0 wave shots", "analyse (Modes tab: Analyze run, or labid analyze)")
    assert summary.next_step({"hammer": 2}, ["analysis"])[1].startswith("identify")
    assert summary.next_step({"hammer": 2}, ["analysis", "identification_modal"])[1].startswith("diagnose")
    assert summary.next_step({"wave": 2}, ["analysis", "identification", "diagnosis"])[1].startswith("write")
