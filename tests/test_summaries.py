"""Console summaries (labid.summary) and the commands' printed tables.

Numbers asserted come from outside the code: SI prefixes by definition, the
expanded uncertainty U = k x std (GUM, k = 2), the demo's true constants.
"""
from __future__ import annotations

import math

import pytest

from labid import summary


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


def test_expanded_uncertainty_is_k_times_std_in_the_value_prefix():
    assert summary.constant_with_u("E1", 136.7e9, 0.8e9) == "136.7 GPa ± 1.6 GPa (k=2)"
    assert summary.constant_with_u("nu12", 0.3, 0.004, k=3) == "0.3 ± 0.012 (k=3)"


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
