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
from labid.report import build_report, write_report
from labid.rig import read_rig_text
from labid.store import RunStore
from labid.specimen import BUILTIN

ROOT = Path(__file__).resolve().parents[1]


def _spec_text() -> str:
    from importlib import resources
    return resources.files("labid.data").joinpath(BUILTIN["cfrp"]).read_text()


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
    assert "Shots: 2 hammer, 0 wave" in html
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
                 "blocks": {"modal": {"kind": "modal", "predicted": [119.5]}}}
        st.write_group("identification", {"json": json.dumps(ident)})
        gap = {"gap": {"before": 12.0, "after": 1.1}, "where": ["modal:band:low"], "verdict": "sensor_mass",
               "effects": [{"name": "sensor_mass", "magnitude": 0.004, "unit": "kg", "gap_after": 1.1,
                            "score": 0.9}]}
        st.write_group("diagnosis", {"json": json.dumps(gap)})
    html = build_report(run_file)
    # E1 130 GPa +- 2.6 GPa = 2 %, against the specimen file's 136.7 GPa
    assert "130 GPa" in html and "2.6 GPa" in html and "2 %" in html and "136.7 GPa" in html
    assert "Verdict: sensor_mass" in html and "modal:band:low" in html
    assert "120.000" in html           # the pick table
    assert "no group velocities" not in html and "no identification" not in html
    assert len(_images(html)) >= 3     # spectrum, dispersion, gap


def test_cli_report(run_file, tmp_path):
    out = tmp_path / "r.html"
    p = subprocess.run([sys.executable, "-m", "labid.cli", "report", str(run_file), "--out", str(out),
                        "--json", "-"], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["out"] == str(out) and out.read_text().startswith("<!DOCTYPE html>")
    bad = tmp_path / "missing.h5"
    p = subprocess.run([sys.executable, "-m", "labid.cli", "report", str(bad)], capture_output=True,
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
    assert "By data set:" in html
    for text in ("130 GPa ± 1 GPa", "131 GPa ± 1 GPa", "125 GPa ± 1 GPa", "modal data", "waves data"):
        assert text in html
