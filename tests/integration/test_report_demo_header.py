"""The demo's certificate header is filled from the demo specimen's ``[report]`` table:
the run the demo writes (built-in CFRP specimen, simulated rig) gives a report whose
header names the lab, client, operator and specimen ID, with no 'not stated' note."""
from __future__ import annotations

import re

from labid.inputs.specimen import specimen_text
from labid.report.certificate import build_report
from labid.inputs.rig import read_rig_text
from labid.inputs.specimen import load_specimen
from labid.store import RunStore

from tests.integration.test_report import hammer_record


def _header(html: str) -> dict[str, str]:
    block = re.search(r"<table class='cert'>(.*?)</table>", html, re.S).group(1)
    return dict(re.findall(r"<tr><th>(.*?)</th><td>(.*?)</td></tr>", block))


def test_demo_report_header(tmp_path):
    run = tmp_path / "demo_run.h5"
    spec = load_specimen("cfrp")                     # what labid.cli.demo acquires
    with RunStore(run, "a") as st:                   # what the acquisition session stores
        st.write_config(specimen_text(spec), read_rig_text("default")[0])
        st.append_shot(hammer_record(), "hammer")
    html = build_report(run)
    head = _header(html)
    assert head["Laboratory"] == "labid demo (simulated rig)"
    assert head["Customer"] == "none: a demonstration on simulated data"
    assert head["Operator"] == "labid demo (automated run, no operator)"
    assert head["Specimen ID"] == "DEMO-CFRP-12PLY"
    assert head["Specimen"] == "CFRP [0/+45/-45]2s, 1.6 mm"
    assert head["Revision"] == "0"
    assert "no [report] table" not in html and "not stated" not in html
