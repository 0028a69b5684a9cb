"""``labid gui RUN.h5`` closes cleanly on SIGTERM and on Ctrl-C (SIGINT), issue 26: the
window closes (its session saved in the run), the command exits 143 / 130. The test waits
on the panel's own line on stderr (the run opened), then on the process's exit: events, no
sleeps (the waits have a 15-minute hang guard, not a speed budget)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from labid.inputs.rig import read_rig_text
from labid.inputs.specimen import BUILTIN
from labid.store import RunStore

ROOT = Path(__file__).resolve().parents[4]
HANG_GUARD_S = 900


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    # the hammer record of tests/integration/test_report.py; that folder is on sys.path only
    # when pytest collected it first (a run of this file alone did not find the module)
    sys.path.insert(0, str(ROOT / "tests" / "integration"))
    from test_report import hammer_record
    p = tmp_path_factory.mktemp("sig") / "run.h5"
    spec = resources.files("labid.data").joinpath(BUILTIN["cfrp"]).read_text()
    with RunStore(p, "a") as st:
        st.write_config(spec, read_rig_text("default")[0])
        st.append_shot(hammer_record(), "hammer")
    return p


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_panel_closes_cleanly_on_a_signal(run_file, sig, code):
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", MPLBACKEND="Agg", PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "labid.cli.main", "gui", str(run_file)], cwd=ROOT, env=env,
                         stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        lines = []
        for line in p.stderr:                          # an event: the panel says the run is open
            lines.append(line)
            if line.startswith("labid gui: opened"):
                break
        assert lines and lines[-1].startswith("labid gui: opened"), lines
        p.send_signal(sig)
        rest = p.stderr.read()
        assert p.wait(timeout=HANG_GUARD_S) == code, rest
    finally:
        if p.poll() is None:
            p.kill()
    assert f"closed on {signal.Signals(sig).name}" in rest and "Traceback" not in rest
    with RunStore(run_file, "r") as st:                # the window closed: its session was saved
        state = json.loads(st.read_result("gui")["state_json"])
    assert "tab" in state
