"""The lab panel driven through its widgets (pytest-qt, offscreen).

Screenshots of every view go to tests/artifacts/ (gitignored) at 1366x768.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt, QTimer  # noqa: E402

from labid.gui.main_window import MainWindow  # noqa: E402
from labid.rig import read_rig_text  # noqa: E402
from labid.runstore import RunStore  # noqa: E402

ART = Path(__file__).parent / "artifacts"
SIZE = (1366, 768)


def fast_rig_text() -> str:
    """The built-in simulated rig, made small: few modes, short records."""
    text, _ = read_rig_text("default")
    return (text.replace("n_modes = 40", "n_modes = 8")
            .replace("samples = 20000", "samples = 4096")
            .replace("samples = 4096           # 2.05 ms", "samples = 1024")
            .replace("hits = 5", "hits = 3").replace("waves = 3", "waves = 1"))


def shot(win: MainWindow, name: str) -> Path:
    ART.mkdir(exist_ok=True)
    p = ART / f"{name}.png"
    assert win.grab().save(str(p))
    return p


@pytest.fixture
def win(qtbot):
    w = MainWindow()
    qtbot.addWidget(w)
    w.resize(*SIZE)
    w.show()
    yield w
    w.close()


def set_rig(win: MainWindow, text: str) -> None:
    win.setup.rig_box.editor.setPlainText(text)
    assert win.setup.rig_box.validate() is not None


def acquire(qtbot, win: MainWindow, run: Path, hits: int, waves: int, timeout=60_000) -> None:
    acq = win.acquisition
    acq.run_edit.setText(str(run))
    acq.hits_spin.setValue(hits)
    acq.waves_spin.setValue(waves)
    with qtbot.waitSignal(win.job.ended if win.job else acq.start_btn.clicked, timeout=2000, raising=False):
        pass
    qtbot.mouseClick(acq.start_btn, Qt.LeftButton)
    assert win.job is not None
    qtbot.waitUntil(lambda: win.job is None, timeout=timeout)


# ---------------------------------------------------------------- setup validation
def test_specimen_error_is_shown_next_to_the_field_at_fault(win, qtbot):
    box = win.setup.specimen_box
    text = box.text().replace("E2 = 9.0e9", "E2 = -9.0e9")
    box.editor.setPlainText(text)
    qtbot.mouseClick(box.check_btn, Qt.LeftButton)
    lines = text.splitlines()
    assert lines[box.editor.error_line].startswith("E2 = -9.0e9")
    lab = box.editor.error_label
    assert lab.isVisible() and "positive" in lab.text()
    assert "materials.T300.E2" in box.status.text()
    # the message sits on the marked line, right of its text
    block = box.editor.document().findBlockByNumber(box.editor.error_line)
    geo = box.editor.blockBoundingGeometry(block).translated(box.editor.contentOffset())
    assert abs(lab.y() - geo.top()) < geo.height()
    assert lab.x() > box.editor.fontMetrics().horizontalAdvance(block.text())
    win.tabs.setCurrentIndex(0)
    shot(win, "setup_error")
    # fixing it clears the mark
    box.editor.setPlainText(text.replace("E2 = -9.0e9", "E2 = 9.0e9"))
    assert box.validate() is not None and not lab.isVisible()


def test_malformed_toml_marks_the_line(win, qtbot):
    box = win.setup.rig_box
    text = box.text().splitlines()
    text[12] = "max_retries = = 5"
    box.editor.setPlainText("\n".join(text))
    assert box.validate() is None
    assert box.editor.error_line == 12
    assert "malformed TOML" in box.status.text()


# ---------------------------------------------------------------- the three clear errors
def test_malformed_run_file_shows_a_message(win, tmp_path):
    bad = tmp_path / "notarun.h5"
    bad.write_text("this is not HDF5\n")
    assert win.open_run(str(bad)) is False
    text, error = win.messages[-1]
    assert error and str(bad) in text and "HDF5" in text
    assert win.status_label.text() == text and win.isVisible()


def test_missing_ni_driver_shows_a_message(win, qtbot, tmp_path):
    set_rig(win, fast_rig_text())
    win.setup.set_backend("nidaqmx")
    run = tmp_path / "ni.h5"
    acquire(qtbot, win, run, 1, 0, timeout=20_000)
    text, error = win.messages[-1]
    assert error and "NI-DAQmx" in text and "Traceback" not in text
    assert "error:" in win.acquisition.log.item(win.acquisition.log.count() - 1).text()
    assert win.acquisition.start_btn.isEnabled()
    win.tabs.setCurrentIndex(1)
    shot(win, "acquisition_ni_missing")


def test_serial_probe_temperature_then_unplugged(win, qtbot):
    from mock_hw.serial_sim import PtyServer, SimEnvProbe
    probe = SimEnvProbe(temperature_c=21.37, humidity_pct=40.0)
    server = PtyServer(probe)
    try:
        win.setup.env_port.setText(server.port)
        qtbot.mouseClick(win.setup.connect_btn, Qt.LeftButton)
        qtbot.waitUntil(lambda: win.setup.temperature_c is not None, timeout=10_000)
        assert win.setup.temperature_c == pytest.approx(21.37)
        assert "21.37" in win.setup.temperature_label.text()
        win.tabs.setCurrentIndex(0)
        shot(win, "setup_serial")
    finally:
        server.close()          # unplugged
    n = len(win.messages)
    win.setup.refresh_instruments()
    qtbot.waitUntil(lambda: len(win.messages) > n, timeout=10_000)
    text, error = win.messages[-1]
    assert error and server.port in text and "environment probe" in text
    assert server.port in win.setup.env_status.text()
    assert win.setup.temperature_label.text().startswith("—")
    shot(win, "setup_serial_unplugged")
    win.setup.poll.stop()


# ---------------------------------------------------------------- identification off the GUI thread
@pytest.fixture
def features_file(tmp_path):
    ident = pytest.importorskip("labid.identification")
    doc = ident.synthetic_features("cfrp", n_modes=6, waves=(("A0", 0.0, 100e3, 8),))
    p = tmp_path / "features.json"
    p.write_text(json.dumps(doc))
    return p, doc


def test_event_loop_turns_while_identification_runs(win, qtbot, features_file, tmp_path):
    path, doc = features_file
    view = win.identification
    assert view.load_features_file(str(path))
    win.tabs.setCurrentIndex(4)
    for n, cb in view.param_checks.items():
        cb.setChecked(n in ("E1", "E2", "G12", "G13"))
    view.starts_spin.setValue(4)
    view.start_edit.setText("E1=110e9,E2=7e9,G12=6e9,G13=4e9")
    ticks = []
    timer = QTimer()
    timer.setInterval(10)
    timer.timeout.connect(lambda: ticks.append(view.job is not None))
    timer.start()
    qtbot.mouseClick(view.run_btn, Qt.LeftButton)
    assert view.job is not None
    qtbot.waitUntil(lambda: view.job is None, timeout=60_000)
    timer.stop()
    # the timer fired many times while the job was running: the GUI thread was free
    assert sum(ticks) >= 5
    res = view.result
    assert res is not None and res["converged"]
    # noise-free synthetic data: the nominal constants come back (outside truth: the specimen file)
    for n in ("E1", "E2", "G12"):
        truth = {"E1": 136.7e9, "E2": 9.0e9, "G12": 5.0e9}[n]
        assert res["parameters"][n]["value"] == pytest.approx(truth, rel=1e-3)
    assert len(res["multi_start"]) == 4 and res["iterations"] >= 2
    assert view.table.rowCount() == 4
    shot(win, "identification")


def test_identification_can_be_cancelled(win, qtbot, features_file):
    path, _ = features_file
    view = win.identification
    assert view.load_features_file(str(path))
    view.starts_spin.setValue(50)
    qtbot.mouseClick(view.run_btn, Qt.LeftButton)
    qtbot.waitUntil(lambda: "model evaluations" in view.progress_label.text()
                    or "multi-start" in view.progress_label.text(), timeout=30_000)
    qtbot.mouseClick(view.cancel_btn, Qt.LeftButton)
    qtbot.waitUntil(lambda: view.job is None, timeout=30_000)
    assert view.result is None
    assert win.messages[-1][0].endswith("cancelled")


@pytest.mark.slow
def test_gap_view_diagnoses_an_injected_sensor_mass(win, qtbot, tmp_path):
    """Features synthesised with 5 g extra at each accelerometer (not in the nominal model):
    the diagnosis must name sensor_mass (outside truth: what was injected)."""
    ident = pytest.importorskip("labid.identification")
    pytest.importorskip("labid.diagnosis")
    from engine.plate_fe import PlateModel
    from labid.specimen import load_specimen
    spec = load_specimen("cfrp")
    acc = [(0.02, 0.02), (0.31, 0.02), (0.23, 0.29)]
    model = PlateModel.build(spec.laminate, spec.length, spec.width).with_point_masses(
        [(x, y, 0.005) for x, y in acc])
    doc = ident.synthetic_features("cfrp", n_modes=8, waves=(), modal_model=model)
    doc["rig"] = {"temperature_c": 23.0,
                  "accelerometers": [{"x": x, "y": y, "mass_kg": 0.0} for x, y in acc],
                  "supports": [{"x": 0.03, "y": 0.33}, {"x": 0.30, "y": 0.33}]}
    p = tmp_path / "features.json"
    p.write_text(json.dumps(doc))
    run = tmp_path / "gap.h5"
    RunStore(run, "a").close()
    win.set_run_path(str(run))
    assert win.identification.load_features_file(str(p))
    win.gap.reload()
    win.tabs.setCurrentIndex(5)
    qtbot.mouseClick(win.gap.run_btn, Qt.LeftButton)
    qtbot.waitUntil(lambda: win.gap.job is None, timeout=60_000)
    res = win.gap.result
    assert res is not None, win.messages[-1]
    assert res["verdict"] == "sensor_mass"
    assert res["effects"][0]["magnitude"] == pytest.approx(0.005, rel=0.2)
    assert win.gap.table.item(0, 1).text() == "sensor_mass"
    shot(win, "gap")
    with RunStore(run, "r") as st:
        stored = json.loads(st.read_group("diagnosis")["json"])
    assert stored["verdict"] == "sensor_mass"
