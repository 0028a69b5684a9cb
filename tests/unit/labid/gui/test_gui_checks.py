"""The Hammer checks tab (issue 26): per hit the force in N with its double-hit and overload
flags, per channel |H1| in dB re 1 (unit)/N and the coherence over the hits.

Outside numbers: a response that is exactly twice the force has |H1| = 2, i.e. 20 log10 2 =
6.02 dB re 1 (m/s²)/N, and coherence 1, at every frequency the force excites; a force with
two pulses 2 ms apart is a double hit."""
from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

from drivers.protocol import ChannelConfig, Record, Timing, Trigger
from labid import services
from labid.inputs.rig import read_rig_text
from labid.inputs.specimen import BUILTIN
from labid.store import RunStore

pytest.importorskip("pytestqt")

FS, N, PRE = 10_000.0, 4096, 100


def hit(double: bool = False, overload: bool = False, amp: float = 10.0) -> Record:
    chans = (ChannelConfig("force", "force", sensitivity=1.0), ChannelConfig("acc1", "accelerometer", sensitivity=1.0))
    t = (np.arange(N) - PRE) / FS
    pulse = lambda t0: np.where((t >= t0) & (t < t0 + 1e-3), np.sin(np.pi * (t - t0) / 1e-3), 0.0)  # noqa: E731
    f = amp * (pulse(0.0) + (0.6 * pulse(3e-3) if double else 0.0))
    return Record({"force": f, "acc1": 2.0 * f}, chans, Timing(FS, N, PRE), Trigger("force", 0.5),
                  {"force": False, "acc1": overload}, backend="test")


@pytest.fixture
def run_file(tmp_path):
    p = tmp_path / "checks.h5"
    spec = resources.files("labid.data").joinpath(BUILTIN["cfrp"]).read_text()
    with RunStore(p, "a") as st:
        st.write_config(spec, read_rig_text("default")[0])
        st.append_shot(hit(), "hammer")
        st.append_shot(hit(double=True, overload=True, amp=8.0), "hammer")
    return p


def test_checks_of_the_hits(run_file):
    c = services.hammer_checks(services.shots(run_file, "hammer"))
    assert c.double_hit == (False, True) and c.overload == ((), ("acc1",))
    assert c.peak_n == pytest.approx((10.0, 8.0), rel=1e-3)
    band = c.frequencies_hz < 1000.0          # the 1 ms half-sine excites up to ~1.5 kHz
    assert c.frf_db["acc1"][band][1:] == pytest.approx(20 * np.log10(2.0), abs=1e-6)
    assert c.coherence["acc1"][band][1:] == pytest.approx(1.0, abs=1e-9)


def test_hammer_checks_tab(main_window, qtbot, run_file):
    win = main_window
    assert win.open_run(str(run_file))
    if win.checks.job is not None:            # computed in a worker thread: wait for it
        qtbot.waitSignal(win.checks.job.ended, timeout=900_000).wait()
    view = win.checks
    assert "1 of 2 hits flagged" in view.banner.text()
    rows = [[view.table.item(i, j).text() for j in range(4)] for i in range(view.table.rowCount())]
    assert rows == [["hammer_0001", "10", "no", "none"], ["hammer_0002", "8", "YES", "acc1"]]
    assert view.frf_plot.getAxis("left").labelUnits == "dB re 1 (m/s²)/N"
    win.tabs.setCurrentWidget(view)
    from pathlib import Path
    art = Path(__file__).resolve().parents[3] / "artifacts"
    art.mkdir(exist_ok=True)
    win.grab().save(str(art / "hammer-checks.png"))
