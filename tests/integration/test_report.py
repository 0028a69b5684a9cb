"""labid report: a self-contained HTML file from a run file."""
from __future__ import annotations

import base64
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drivers.protocol import ChannelConfig, Record, Timing, Trigger
from labid.report.certificate import build_report, write_report
from labid.inputs.rig import read_rig_text
from labid.store import RunStore
from labid.inputs.specimen import BUILTIN

ROOT = Path(__file__).resolve().parents[2]


def _spec_text() -> str:
    """The built-in CFRP specimen without its (demo) ``[report]`` table."""
    from importlib import resources
    return resources.files("labid.data").joinpath(BUILTIN["cfrp"]).read_text().split("\n[report]")[0]


def hammer_record(f0: float = 120.0, fs: float = 2000.0, n: int = 2048, pre: int = 50) -> Record:
    """A force pulse and one accelerometer ringing at f0 (Hz), zeta = 1 %."""
    chans = (ChannelConfig("force", "force", sensitivity=2.25e-3),
             ChannelConfig("acc1", "accelerometer", sensitivity=1.02e-3, x=0.02, y=0.02))
    t = (np.arange(n) - pre) / fs
    w = 2 * np.pi * f0
    acc = np.where(t >= 0, np.exp(-0.01 * w * t) * np.sin(w * t), 0.0)
    force = np.where((t >= 0) & (t < 2e-3), np.sin(np.pi * t / 2e-3), 0.0) * 10.0
    return Record({"force": force * 2.25e-3, "acc1": acc * 1.02e-3}, chans, Timing(fs, n, pre),
                  Trigger("force", 0.01), {"force": False, "acc1": False}, backend="test")


@pytest.fixture
def run_file(tmp_path):
    p = tmp_path / "run.h5"
    rig_text, _ = read_rig_text("default")
    with RunStore(p, "a") as st:
        st.write_config(_spec_text(), rig_text)
        for _ in range(2):
            st.append_shot(hammer_record(), "hammer")
    return p


def _images(html: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)]


def test_report_is_self_contained_and_notes_missing_sections(run_file):
    html = build_report(run_file)
    imgs = _images(html)
    assert imgs and all(b.startswith(b"\x89PNG\r\n\x1a\n") for b in imgs)
    # nothing fetched from elsewhere
    assert not re.search(r'(src|href)="(?!data:)', html)
    assert "CFRP [0/+45/-45]2s" in html and "12 [0, 45, -45" in html
    assert "2 hammer hits, 0 wave shots" in html
    for note in ("no wave shots in this run", "no group velocities in this run",
                 "no identification in this run", "no gap diagnosis in this run",
                 "no resonance picks stored"):
        assert note in html


def test_report_shows_stored_results(run_file):
    with RunStore(run_file, "a") as st:
        feats = {"modal": {"frequencies_hz": [120.0], "sigma_hz": [0.01]},
                 "waves": [{"mode": "A0", "direction_deg": 0.0, "frequency_hz": [5e3, 1e4],
                            "group_velocity_m_s": [800.0, 1100.0], "sigma_m_s": [10.0, 12.0]}]}
        st.write_group("analysis", {"features": {"json": json.dumps(feats)}})
        ident = {"parameters": {"E1": {"value": 1.30e11, "std": 2.6e9}}, "converged": True,
                 "residual": {"modal_rms_rel": 1e-3, "waves_rms_rel": None},
                 "blocks": {"modal": {"kind": "modal", "predicted": [119.5]}},
                 # labid identify's GUM budget (engine.fit.budget.Budget.to_dict): u_c^2 = sum of squares
                 "uncertainty_budget": {"coverage_factor": 2.0, "constants": {"E1": {
                     "value": 1.30e11, "u_combined": 3.4e9, "U": 6.8e9, "contributions": {
                         "type A (fit)": {"u": 2.6e9}, "thickness": {"u": 2.191e9}}}}}}
        st.write_group("identification", {"json": json.dumps(ident)})
        gap = {"gap": {"before": 12.0, "after": 1.1}, "where": ["modal:band:low"], "verdict": "sensor_mass",
               "effects": [{"name": "sensor_mass", "magnitude": 0.004, "unit": "kg", "gap_after": 1.1,
                            "score": 0.9}]}
        st.write_group("diagnosis", {"json": json.dumps(gap)})
    html = build_report(run_file)
    # E1 130 GPa: U (k = 2) is the budget's 6.8 GPa = 5.2 %, beside u_A = 2.6 GPa and
    # u_B = sqrt(3.4^2 - 2.6^2) = 2.19 GPa; k u_A = 5.2 GPa (a second U) appears nowhere
    assert "130.0 GPa" in html and "<b>6.8 GPa</b>" in html and "5.2 %" in html and "5.2 GPa" not in html
    assert "<td>2.6 GPa</td><td>2.2 GPa</td>" in html
    assert "136.7 GPa" in html
    assert "Uncertainty budget" in html and "thickness" in html and "2.2 GPa" in html and "6.8 GPa" in html
    assert "Verdict: sensor_mass" in html and "modal:band:low" in html
    assert "120.000" in html           # the pick table
    assert "no group velocities" not in html and "no identification" not in html
    assert len(_images(html)) >= 3     # spectrum, dispersion, gap


def test_cli_report(run_file, tmp_path):
    out = tmp_path / "r.html"
    p = subprocess.run([sys.executable, "-m", "labid.cli.main", "report", str(run_file), "--out", str(out),
                        "--json", "-"], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["out"] == str(out) and out.read_text().startswith("<!DOCTYPE html>")
    bad = tmp_path / "missing.h5"
    p = subprocess.run([sys.executable, "-m", "labid.cli.main", "report", str(bad)], capture_output=True,
                       text=True, cwd=ROOT)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert str(bad) in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_default_output_next_to_the_run(run_file):
    assert write_report(run_file) == str(run_file.with_suffix(".html"))


def test_constants_of_each_data_set_side_by_side(run_file):
    with RunStore(run_file, "a") as st:
        for name, e1 in (("identification", 1.30e11), ("identification_modal", 1.31e11),
                         ("identification_waves", 1.25e11)):
            st.write_group(name, {"json": json.dumps({"parameters": {"E1": {"value": e1, "std": 1e9}},
                                                      "converged": True})})
    html = build_report(run_file)
    assert "By data set (value ± u, type A only):" in html and "Appendix A. Constants by data set" in html
    for text in ("130.0 GPa ± 1.0 GPa", "131.0 GPa ± 1.0 GPa", "125.0 GPa ± 1.0 GPa", "modal data", "waves data"):
        assert text in html


# ---------------------------------------------------------------- the report as a test certificate
def _run_with_report_table(path, table: str):
    """A run whose specimen text carries a [report] table."""
    with RunStore(path, "a") as st:
        st.write_config(_spec_text() + "\n" + table, read_rig_text("default")[0])
        st.append_shot(hammer_record(), "hammer")
    return path


def test_certificate_fields_from_the_report_table(tmp_path):
    run_file = _run_with_report_table(tmp_path / "cert.h5", '[report]\nlab = "Composites Lab A"\nclient = "ACME Aero"\n'
                                 'operator = "J. Smith"\nspecimen_id = "P-0042"\ntemperature_c = 21.5\n'
                                 'suspension = "foam blocks"\nrevision = "B"\n')
    html = build_report(run_file)
    for text in ("Composites Lab A", "ACME Aero", "J. Smith", "P-0042", "21.5 °C ([report] table)",
                 "foam blocks", "<th>Revision</th><td>B</td>", "Bartoli", "Tested by", "Approved by"):
        assert text in html, text
    assert "no [report] table" not in html


def test_missing_report_table_is_said_not_fatal(run_file):
    html = build_report(run_file)
    assert "no [report] table in the specimen or rig file" in html
    assert "Authorisation" in html and "temperature" in html


def test_uncertainty_statement_and_long_tables_in_an_appendix(run_file):
    f = list(np.linspace(50.0, 1500.0, 39))           # 39 picks, as the demo's
    with RunStore(run_file, "a") as st:
        st.write_group("analysis", {"features": {"json": json.dumps(
            {"modal": {"frequencies_hz": f, "sigma_hz": [1e-5 * x for x in f]}})}})
        ident = {"parameters": {"E1": {"value": 1.367e11, "std": 4.2e7}, "nu12": {"value": 0.3, "std": 0.004}},
                 "converged": True, "held": {"density": 1550.0},
                 "fit": {"chi2": 30.1, "dof": 33, "p_value": 0.61, "consistent": True},
                 "flags": ["G13 weakly constrained"],
                 "pairing": [{"peak": 1, "measured_hz": 50.0, "mode_index": 1, "family": "(1,1) torsion",
                              "predicted_hz": 50.5},
                             {"peak": None, "measured_hz": None, "mode_index": 2, "family": "(0,2)",
                              "predicted_hz": 60.0}]}
        st.write_group("identification", {"json": json.dumps(ident)})
    html = build_report(run_file)
    # k = 2: U(E1) = 84 MPa = 0.084 GPa, printed in the value's prefix
    assert "136.7 GPa" in html and "0.042 GPa" in html and "0.084 GPa" in html
    assert "coverage factor k = 2" in html and "does not cover model-form errors" in html
    # chi^2/nu = 30.1/33 = 0.912, p = 0.61: neither tail; the reading names both ways
    assert "χ² = 30.1 for ν = 33 degrees of freedom, χ²/ν = 0.912 (probability of a larger χ²: p = 0.61)" in html
    assert "χ²/ν ≈ 1" in html and "sigmas are too large" in html and "too small or the model" in html
    assert "held" in html and "1550 kg/m³" in html and "G13 weakly constrained" in html
    assert "(1,1) torsion" in html and "+1.00 %" in html and "predicted mode without a peak" in html
    # the 39-row sigma table is in an appendix, after the signatures
    body, appendix = html.split("8. Authorisation", 1)
    assert "Appendix A. Resonance picks and their σ" in appendix and "1500.000" not in body
    assert "39 resonances picked, 50.0 Hz to 1.500 kHz" in body
    assert appendix.count("<tr>") >= 40
    assert "15.0 mHz" in appendix                        # sigma of the 1500 Hz pick: 1e-5 x 1500 Hz


def test_no_constant_in_plain_e_notation(run_file):
    with RunStore(run_file, "a") as st:
        st.write_group("identification", {"json": json.dumps(
            {"parameters": {"E1": {"value": 1.367e11, "std": 4.2e7}}, "converged": True})})
    html = build_report(run_file)
    text = re.sub(r"<[^>]+>|data:image/png;base64,[A-Za-z0-9+/=]+", " ", html)
    assert not re.search(r"\d\.\d+e[+-]\d\d", text), re.findall(r".{30}\d\.\d+e[+-]\d\d.{10}", text)


def test_statement_of_conformity_follows_the_decision_rule(tmp_path):
    """value ± U (k = 2) against [report.limits]: inside -> conforms, wholly outside -> does not
    conform, straddling a limit -> no statement (ILAC-G8 guarded acceptance)."""
    run = _run_with_report_table(tmp_path / "c.h5", "[report]\nlab = 'L'\n[report.limits]\n"
                                 "E1 = [120e9, 140e9]\nG12 = [5.5e9, nan]\nE2 = [8.5e9, 12e9]\n")
    with RunStore(run, "a") as st:
        st.write_group("identification", {"json": json.dumps({"converged": True, "parameters": {
            "E1": {"value": 130e9, "std": 3e9, "identified": True}, "G12": {"value": 5e9, "std": 0.1e9, "identified": True},
            "E2": {"value": 9e9, "std": 0.5e9, "identified": True}}})})
    html = build_report(run)
    rows = dict(re.findall(r"<tr><td>(E1|G12|E2)</td><td>[^<]*</td><td>[^<]*</td><td><b>([^<]*)</b></td></tr>",
                           html))
    # E1: 124..136 GPa within 120..140; G12: 4.8..5.2 below 5.5; E2: 8..10 straddles 8.5
    assert rows == {"E1": "conforms", "G12": "does not conform", "E2": "no statement: value ± U straddles a limit"}


def test_one_mode_label_per_peak_in_every_table(run_file):
    """The picks, the pairing and the damping appendices give the identified model's label for
    a peak, even where the analysis (nominal model) labelled it otherwise."""
    f = [50.0 + 30.0 * i for i in range(14)]
    nominal_labels = ["(2,1)/(0,3)"] + [f"({i},1)" for i in range(1, 14)]
    with RunStore(run_file, "a") as st:
        st.write_group("analysis", {"features": {"json": json.dumps({
            "modal": {"frequencies_hz": f, "sigma_hz": [0.01] * 14},
            "damping": {"modes": [{"frequency_hz": x, "label": lab, "loss_factor": 0.01}
                                  for x, lab in zip(f, nominal_labels)],
                        "families": {}, "all": {}}})}})
        st.write_group("identification", {"json": json.dumps({
            "parameters": {"E1": {"value": 1.3e11, "std": 1e9}}, "converged": True,
            "pairing": [{"peak": i, "measured_hz": x, "mode_index": i, "family": "(2,1)" if i == 0 else f"({i},1)",
                         "predicted_hz": x} for i, x in enumerate(f)]})})
    html = build_report(run_file)
    assert "(2,1)/(0,3)" not in html
    # peak 1 at 50 Hz is (2,1) in the picks, the pairing and the loss-factor appendices
    assert html.count("<td>1</td><td>50.000</td><td>10.0 mHz</td><td>(2,1)</td>") == 1
    assert "<td>1</td><td>50.000</td><td>1</td><td>(2,1)</td>" in html
    assert "<td>50.000</td><td>(2,1)</td><td>0.01</td>" in html


def test_report_limits_mistakes_are_one_line():
    import tomllib
    from labid.base.errors import UserError
    from labid.inputs.specimen import specimen_from_dict
    doc = tomllib.loads(_spec_text() + "\n[report.limits]\nE1 = [145e9, 130e9]\n")
    with pytest.raises(UserError, match=r"s\.toml: report\.limits\.E1: value \[145000000000\.0, 130000000000\.0\]: "
                                        r"expected \[low, high\] in SI units, low <= high"):
        specimen_from_dict(doc, "s.toml")
    doc = tomllib.loads(_spec_text() + "\n[report]\nlimits = 3\n")
    with pytest.raises(UserError, match=r"report\.limits: value 3: expected a table NAME = \[low, high\]"):
        specimen_from_dict(doc, "s.toml")
