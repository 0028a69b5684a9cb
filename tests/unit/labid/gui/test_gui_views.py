"""The lab panel driven through its widgets (pytest-qt, offscreen).

Screenshots of every view go to tests/artifacts/ (gitignored) at 1366x768.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt, QTimer  # noqa: E402

from labid.gui.main_window import MainWindow  # noqa: E402
from labid.inputs.rig import read_rig_text  # noqa: E402
from labid.store import RunStore  # noqa: E402

ART = Path(__file__).resolve().parents[3] / "artifacts"
SIZE = (1366, 768)
#: a guard against a hung job, not a speed requirement: every wait ends on a signal or a
#: state change, however long a busy machine takes to get there
BUDGET = 900_000


def wait_job(qtbot, job) -> None:
    """Wait for ``job`` (a ``labid.gui.worker.Job``) to end: its ``ended`` signal
    (None: it has ended and been cleared already)."""
    if job is None:
        return
    if job.has_ended:               # a plain Python attribute: readable after deletion too
        return
    with qtbot.waitSignal(job.ended, timeout=BUDGET):
        pass


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


def dispose(w: MainWindow) -> None:
    """Close and delete a window now (PySide6/pyqtgraph objects left to the garbage
    collector at interpreter exit can crash it)."""
    import gc

    from PySide6.QtCore import QEvent
    from PySide6.QtWidgets import QApplication
    w.close()
    w.deleteLater()
    QApplication.sendPostedEvents(None, QEvent.DeferredDelete)
    QApplication.processEvents()
    gc.collect()


@pytest.fixture(scope="module", autouse=True)
def _collect_qt_objects():
    """Collect the Qt wrappers of this module while the QApplication still lives."""
    yield
    import gc

    from PySide6.QtCore import QEvent
    from PySide6.QtWidgets import QApplication
    if QApplication.instance() is not None:
        QApplication.sendPostedEvents(None, QEvent.DeferredDelete)
        QApplication.processEvents()
    gc.collect()


@pytest.fixture
def win(qtbot):
    w = MainWindow()
    w.resize(*SIZE)
    w.show()
    yield w
    dispose(w)


def set_rig(win: MainWindow, text: str) -> None:
    win.setup.rig_box.editor.setPlainText(text)
    assert win.setup.rig_box.validate() is not None


def acquire(qtbot, win: MainWindow, run: Path, hits: int, waves: int) -> None:
    acq = win.acquisition
    acq.run_edit.setText(str(run))
    acq.hits_spin.setValue(hits)
    acq.waves_spin.setValue(waves)
    if win.job is not None:
        wait_job(qtbot, win.job)
    qtbot.mouseClick(acq.start_btn, Qt.LeftButton)
    assert win.job is not None
    wait_job(qtbot, win.job)


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
    win.setup.set_backend("nidaqmx")            # checked at once, next to the choice
    qtbot.waitUntil(lambda: "NI-DAQmx driver" in win.setup.backend_status.text(), timeout=BUDGET)
    win.tabs.setCurrentIndex(0)
    shot(win, "setup_ni_missing")
    run = tmp_path / "ni.h5"
    acquire(qtbot, win, run, 1, 0)
    text, error = win.messages[-1]
    assert error and "NI-DAQmx" in text and "Traceback" not in text
    assert "error:" in win.acquisition.log.item(win.acquisition.log.count() - 1).text()
    assert win.acquisition.start_btn.isEnabled()
    win.tabs.setCurrentIndex(1)
    shot(win, "acquisition_ni_missing")


def test_serial_probe_temperature_then_unplugged(win, qtbot):
    from mock_hw.serial_sim import PtyServer, SimEnvProbe, SimHammer
    probe = SimEnvProbe(temperature_c=21.37, humidity_pct=40.0)
    server = PtyServer(probe)
    hammer = PtyServer(SimHammer(level_pct=60))
    try:
        win.setup.env_port.setText(server.port)
        win.setup.hammer_port.setText(hammer.port)
        qtbot.mouseClick(win.setup.connect_btn, Qt.LeftButton)
        qtbot.waitUntil(lambda: win.setup.temperature_c is not None, timeout=BUDGET)
        assert win.setup.temperature_c == pytest.approx(21.37)
        assert "21.37" in win.setup.temperature_label.text()
        assert "HAMMER" in win.setup.hammer_status.text() and "level 60 %" in win.setup.hammer_status.text()
        win.tabs.setCurrentIndex(0)
        shot(win, "setup_serial")
    finally:
        server.close()          # unplugged
        hammer.close()
    n = len(win.messages)
    win.setup.refresh_instruments()
    qtbot.waitUntil(lambda: len(win.messages) > n, timeout=BUDGET)
    text, error = win.messages[-1]
    assert error and server.port in text and "environment probe" in text
    assert server.port in win.setup.env_status.text()
    assert win.setup.temperature_label.text().startswith("—")
    shot(win, "setup_serial_unplugged")
    win.setup.poll.stop()


# ---------------------------------------------------------------- identification off the GUI thread
@pytest.fixture
def features_file(tmp_path):
    ident = pytest.importorskip("labid.workflows.identification")
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
    wait_job(qtbot, view.job)
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
                    or "multi-start" in view.progress_label.text(), timeout=BUDGET)
    qtbot.mouseClick(view.cancel_btn, Qt.LeftButton)
    wait_job(qtbot, view.job)
    assert view.result is None
    assert win.messages[-1][0].endswith("cancelled")


# ---------------------------------------------------------------- a whole session on the simulated rig
def click_frequency(qtbot, view, f_hz: float) -> None:
    """A real mouse click on the Modes plot at frequency f_hz (mid-height)."""
    from PySide6.QtCore import QPointF
    pw = view.plot
    vb = pw.getPlotItem().vb
    (y0, y1) = vb.viewRange()[1]
    scene = vb.mapViewToScene(QPointF(f_hz, 0.5 * (y0 + y1)))
    pos = pw.mapFromScene(scene)
    qtbot.mouseClick(pw.viewport(), Qt.LeftButton, pos=pos)


@pytest.mark.slow
def test_whole_session_on_the_simulated_rig(qtbot, tmp_path):
    pytest.importorskip("labid.workflows.analysis")
    pytest.importorskip("labid.workflows.identification")
    pytest.importorskip("labid.workflows.diagnosis")
    win = MainWindow()
    win.resize(*SIZE)
    win.show()
    run = tmp_path / "session.h5"
    # -- set up: a small rig, 5 g unmodelled mass at every accelerometer, trigger level via the panel
    set_rig(win, fast_rig_text())
    win.setup.effects_edit.setText("sensor_mass=0.005")
    win.tabs.setCurrentIndex(0)
    shot(win, "view_setup")
    acq = win.acquisition
    acq.device_combo.setCurrentIndex(0)
    acq.level_spin.setValue(0.03)
    acq.pre_spin.setValue(150)
    qtbot.mouseClick(acq.apply_btn, Qt.LeftButton)
    acq.device_combo.setCurrentIndex(1)            # the guided-wave device
    acq.level_spin.setValue(-0.015)
    qtbot.mouseClick(acq.apply_btn, Qt.LeftButton)
    rig_text = win.setup.rig_box.text()
    assert "level_v = 0.03" in rig_text and "pretrigger = 150" in rig_text and "level_v = -0.015" in rig_text
    # -- acquire
    win.tabs.setCurrentIndex(1)
    acquire(qtbot, win, run, 3, 0)
    assert acq.counter.text() == "hits 3/3 · waves 0/0", acq.log.item(acq.log.count() - 1).text()
    assert all(lab.state is False for n, lab in acq.lights.items() if n in ("force", "acc1", "acc2", "acc3"))
    shot(win, "view_acquisition")
    with RunStore(run, "r") as st:           # each accepted shot is in the file already
        assert st.n_shots("hammer") == 3 and st.n_shots("wave") == 0
    # -- analyse and pick
    win.tabs.setCurrentIndex(2)
    modes = win.modes
    qtbot.mouseClick(modes.analyze_btn, Qt.LeftButton)
    wait_job(qtbot, win.job)
    auto = [p.frequency_hz for p in modes.peaks]
    assert len(auto) >= 4, win.messages[-1]
    target = auto[1]
    click_frequency(qtbot, modes, target)          # click on a pick: removed
    assert len(modes.peaks) == len(auto) - 1
    click_frequency(qtbot, modes, target)          # click there again: fitted back, manual
    assert len(modes.peaks) == len(auto)
    back = min(modes.peaks, key=lambda p: abs(p.frequency_hz - target))
    # the same resonance again (neighbours lie > 10 % away), now marked manual
    assert back.manual and back.frequency_hz == pytest.approx(target, rel=5e-3)
    qtbot.mouseClick(modes.save_btn, Qt.LeftButton)
    # -- identify (modal data: E1, E2, G12)
    ident = win.identification
    ident.reload()
    win.tabs.setCurrentIndex(4)
    for n, cb in ident.param_checks.items():
        cb.setChecked(n in ("E1", "E2", "G12"))
    ident.data_radios["modal"].setChecked(True)
    qtbot.mouseClick(ident.run_btn, Qt.LeftButton)
    wait_job(qtbot, ident.job)
    assert ident.result is not None, win.messages[-1]
    win.tabs.setCurrentIndex(2)
    modes.reload()
    shot(win, "view_modes")
    win.tabs.setCurrentIndex(4)
    shot(win, "view_identification")
    # -- diagnose
    win.gap.reload()
    win.tabs.setCurrentIndex(5)
    qtbot.mouseClick(win.gap.run_btn, Qt.LeftButton)
    wait_job(qtbot, win.gap.job)
    assert win.gap.result is not None, win.messages[-1]
    shot(win, "view_gap")
    # -- save the session
    win.tabs.setCurrentIndex(4)
    assert win.save_session()

    # -- the run file holds everything
    with RunStore(run, "r") as st:
        assert st.n_shots("hammer") == 3 and st.n_shots("wave") == 0
        assert "level_v = 0.03" in st.rig_toml()
        assert 'name = "CFRP' in st.specimen_toml()
        feats = json.loads(st.read_group("analysis")["features"]["json"])
        pk = st.read_group("analysis")["peaks"]
        idr = json.loads(st.read_group("identification")["json"])
        dg = json.loads(st.read_group("diagnosis")["json"])
        gui = json.loads(st.read_group("gui")["state_json"])
    f = np.array(feats["modal"]["frequencies_hz"])
    assert len(f) == len(auto) and np.isclose(f, back.frequency_hz).any()
    assert pk["manual"].sum() == 1
    assert set(idr["parameters"]) == {"E1", "E2", "G12"} and idr["data"] == ["modal"] and idr["data_set"] == "modal"
    assert all(p["std"] > 0 for p in idr["parameters"].values())
    assert {"gap", "where", "effects", "verdict"} <= set(dg)
    assert dg["verdict"] == "sensor_mass", dg["verdict"]      # the effect injected into the rig
    assert gui["tab"] == 4 and gui["setup"]["effects"] == "sensor_mass=0.005"
    assert gui["identification"]["params"] == ["E1", "E2", "G12"]
    rig_text = win.setup.rig_box.text()
    dispose(win)

    # -- reopening the run restores the views
    win2 = MainWindow(str(run))
    win2.resize(*SIZE)
    win2.show()
    assert win2.tabs.currentIndex() == 4
    assert win2.setup.rig_box.text() == rig_text
    assert win2.setup.effects_edit.text() == "sensor_mass=0.005"
    assert win2.identification.table.rowCount() == 3
    assert win2.identification.chosen_params() == ("E1", "E2", "G12")
    assert len(win2.modes.peaks) == len(auto)
    assert sum(p.manual for p in win2.modes.peaks) == 1
    assert win2.gap.result["verdict"] == "sensor_mass"
    # picks stay editable after reopening (the spectra are recomputed from the shots)
    assert win2.modes.toggle_peak(auto[-1]) == "removed" and len(win2.modes.peaks) == len(auto) - 1
    shot(win2, "view_reopened")
    # the report of this run
    from labid.report.certificate import write_report
    html = Path(write_report(run, tmp_path / "r.html")).read_text()
    assert html.count("data:image/png;base64,") >= 2 and "sensor_mass" in html
    job = win2.write_report(str(tmp_path / "panel.html"))      # File > Write report
    assert job is not None
    wait_job(qtbot, win2.job)
    assert (tmp_path / "panel.html").read_text().count("data:image/png;base64,") >= 2
    dispose(win2)


def test_wave_shot_scalogram_and_group_velocity(win, qtbot, tmp_path):
    """One guided-wave shot, analysed: the Waves view shows the scalogram of each sensor
    with the arrival ridge, and the A0 group velocity (error bars) over the SAFE curve."""
    pytest.importorskip("labid.workflows.analysis")
    set_rig(win, fast_rig_text())
    acq = win.acquisition
    run = tmp_path / "waves.h5"
    acquire(qtbot, win, run, 0, 1)
    assert acq.counter.text() == "hits 0/0 · waves 1/1", acq.log.item(acq.log.count() - 1).text()
    assert {acq.lights[n].state for n in ("mfc1", "mfc2")} == {False}
    win.tabs.setCurrentIndex(1)
    shot(win, "view_acquisition_wave")
    win.setup.temperature_c = 24.5          # as read from the environment probe
    qtbot.mouseClick(win.modes.analyze_btn, Qt.LeftButton)
    wait_job(qtbot, win.job)
    assert win.features()["rig"]["temperature_c"] == 24.5     # goes into the features
    win.tabs.setCurrentIndex(3)
    view = win.waves
    assert view.shot_combo.count() == 2
    assert view.image.image is not None and view.image.image.shape[1] == 100
    t, f = view.ridge.getData()
    assert t is not None and len(t) >= 5
    qtbot.waitUntil(lambda: ("A0", "nominal") in view.safe_curves, timeout=BUDGET)
    import pyqtgraph as pg
    bars = [it for it in view.velocity.getPlotItem().items if isinstance(it, pg.ErrorBarItem)]
    assert len(bars) == 1
    # the simulated rig synthesises its waves with the nominal constants: the measured A0
    # velocities lie on the nominal SAFE curve (within 5 %)
    cur = view._res["waves"]["A0_0"]
    ok = np.asarray(cur["valid"], bool)
    fs, vs = view.safe_curves[("A0", "nominal")]
    model = np.interp(np.asarray(cur["frequency_hz"])[ok], fs, vs)
    assert np.allclose(np.asarray(cur["group_velocity_m_s"])[ok], model, rtol=0.05)
    shot(win, "view_waves")


def test_abort_keeps_every_recorded_hit(win, qtbot, tmp_path):
    set_rig(win, fast_rig_text())
    acq = win.acquisition
    run = tmp_path / "abort.h5"
    acq.run_edit.setText(str(run))
    acq.hits_spin.setValue(100_000)
    acq.waves_spin.setValue(0)
    qtbot.mouseClick(acq.start_btn, Qt.LeftButton)
    qtbot.waitUntil(lambda: acq.done["hammer"] >= 2, timeout=BUDGET)
    with RunStore(run, "r") as st:      # accepted hits are in the file while the session runs
        assert st.n_shots("hammer") >= 2
    assert win.job is not None
    qtbot.mouseClick(acq.abort_btn, Qt.LeftButton)
    wait_job(qtbot, win.job)
    summary = acq.last_summary
    assert summary["interrupted"] and 2 <= summary["recorded"]["hammer"] < 100_000, (
        {k: summary[k] for k in ("interrupted", "recorded", "problems", "complete")})
    with RunStore(run, "r") as st:
        assert st.n_shots("hammer") == summary["recorded"]["hammer"] == acq.done["hammer"]
    assert "interrupted" in win.messages[-1][0]


def test_overload_light_turns_red(win, qtbot, tmp_path):
    """acc1 given a 1 mV range: every hit clips it; the light shows it and the shot is redone."""
    text = fast_rig_text()
    head = text.index('name = "acc1"')
    cut = text.index("range_v = 5.0", head)
    text = text[:cut] + "range_v = 0.001" + text[cut + len("range_v = 5.0"):]
    set_rig(win, text)
    acquire(qtbot, win, tmp_path / "over.h5", 1, 0)
    acq = win.acquisition
    assert acq.lights["acc1"].state is True and acq.lights["acc2"].state is False
    assert any("overload on acc1" in acq.log.item(i).text() for i in range(acq.log.count()))
    text, error = win.messages[-1]
    assert error and "gave up" in text
    win.tabs.setCurrentIndex(1)
    shot(win, "acquisition_overload")


def test_malformed_specimen_file_is_marked_where_it_breaks(win, tmp_path):
    bad = tmp_path / "plate.toml"
    bad.write_text('name = "plate"\n[plate]\nlength = 0.3\nwidth = = 0.2\n')
    box = win.setup.specimen_box
    assert box.load_file(str(bad))
    assert box.validate() is None
    assert box.editor.error_line == 3 and box.editor.error_label.isVisible()
    assert str(bad) in box.status.text() and "malformed TOML" in box.status.text()
    # a file that is not there: one line in the panel, the editor keeps its text
    before = box.text()
    assert not box.load_file(str(tmp_path / "missing.toml"))
    assert "missing.toml" in box.status.text() and box.text() == before


def test_cli_gui_command_takes_an_optional_run():
    from labid.cli.main import build_parser
    p = build_parser()
    assert p.parse_args(["gui"]).run is None
    assert p.parse_args(["gui", "RUN.h5"]).run == "RUN.h5"


def test_specimen_edit_save_and_reload(win, tmp_path):
    box = win.setup.specimen_box
    text = box.text().replace("E2 = 9.0e9", "E2 = 9.5e9")
    box.editor.setPlainText(text)
    target = tmp_path / "edited.toml"
    assert box.save(str(target))
    assert target.read_text() == text and not box.modified()
    box.load_builtin("aluminium")
    assert box.load_file(str(target)) and box.text() == text
    spec = box.validate()
    assert spec is not None and spec.laminate.plies[0].material.E2 == 9.5e9


def test_a_cancelled_job_that_cannot_stop_early_is_discarded(win, qtbot, tmp_path):
    """The Gap tab's diagnosis runs to its end once started; cancelling discards it and
    the tab is usable again."""
    pytest.importorskip("labid.workflows.diagnosis")
    ident = pytest.importorskip("labid.workflows.identification")
    doc = ident.synthetic_features("cfrp", n_modes=4, waves=())
    p = tmp_path / "f.json"
    p.write_text(json.dumps(doc))
    assert win.identification.load_features_file(str(p))
    win.gap.reload()
    qtbot.mouseClick(win.gap.run_btn, Qt.LeftButton)
    assert win.gap.job is not None and win.cancel_btn.isVisible()
    qtbot.mouseClick(win.cancel_btn, Qt.LeftButton)
    wait_job(qtbot, win.job)
    assert win.gap.job is None and win.gap.run_btn.isEnabled() and win.gap.result is None
    assert not win.cancel_btn.isVisible()
    assert win.messages[-1][0] == "diagnosis: cancelled (result discarded)", win.messages[-1]
