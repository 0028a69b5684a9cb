"""The panel opens every run file labid writes: the demo's, and every partial run
(configuration only, shots only, analysed, identified by the command line with
missing numbers, diagnosed). What it shows is checked against what the file holds;
closing a window with a job running cancels and disconnects the job.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import QEvent  # noqa: E402
from PySide6.QtWidgets import QApplication  # noqa: E402

from labid import services  # noqa: E402
from labid.gui.main_window import MainWindow  # noqa: E402
from labid.inputs.rig import read_rig_text  # noqa: E402

# a run missing some numbers opens without a console warning (pyqtgraph's All-NaN bounds, seen
# on identified runs without a rel_std before session 26)
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

#: a guard against a hang, not a speed requirement (waits end on signals)
BUDGET = 900_000


def fast_rig_text() -> str:
    """The built-in simulated rig, made small (as in test_gui)."""
    text, _ = read_rig_text("default")
    return (text.replace("n_modes = 40", "n_modes = 8")
            .replace("samples = 20000", "samples = 4096")
            .replace("samples = 4096           # 2.05 ms", "samples = 1024"))


def dispose(w: MainWindow) -> None:
    import gc
    w.close()
    w.deleteLater()
    QApplication.sendPostedEvents(None, QEvent.DeferredDelete)
    QApplication.processEvents()
    gc.collect()


def open_window(path) -> MainWindow:
    w = MainWindow(str(path))
    w.resize(1366, 768)
    w.show()
    QApplication.processEvents()
    return w


def errors(w: MainWindow) -> list[str]:
    return [t for t, bad in w.messages if bad]


def notes(plot) -> list[str]:
    """The texts of the 'no data yet' notes on a pyqtgraph plot."""
    import pyqtgraph as pg
    return [it.toPlainText() for it in plot.getPlotItem().vb.addedItems if isinstance(it, pg.TextItem)]


@pytest.fixture(scope="module")
def partial_runs(tmp_path_factory):
    """Run files at every stage of the job, written by labid's own workflows."""
    d = tmp_path_factory.mktemp("partial")
    rig_path = d / "rig.toml"
    rig_path.write_text(fast_rig_text())
    runs = {}
    # 1. configuration only: an acquisition that recorded nothing
    runs["empty"] = d / "empty.h5"
    services.acquire(runs["empty"], str(rig_path), "cfrp", hits=0, waves=0)
    # 2. shots only (3 hits, 1 wave shot), never analysed
    runs["shots"] = d / "shots.h5"
    services.acquire(runs["shots"], str(rig_path), "cfrp", hits=3, waves=1)
    # 3. analysed (features stored), not identified
    runs["analysed"] = d / "analysed.h5"
    services.acquire(runs["analysed"], str(rig_path), "cfrp", hits=3, waves=0)
    services.run_analysis(runs["analysed"])
    # 4. identified by the command line: a result with numbers missing (a std of None, no
    #    identifiability rel_std, no history), as a CLI result of another version may be
    runs["identified"] = d / "identified.h5"
    runs["identified"].write_bytes(runs["analysed"].read_bytes())
    services.store_result(runs["identified"], "identification", {
        "parameters": {"E1": {"value": 130e9, "std": None}, "E2": {"value": 9e9, "std": 0.1e9}},
        "converged": True, "method": "lm",
        "identifiability": {"blocks": {"modal": {"rel_std": {"E1": None, "E2": 0.01}}},
                            "parameters": {"E1": {"rel_std": None}}},
        "blocks": {"modal": {"kind": "modal", "predicted": None}}})
    # 5. diagnosed too
    runs["diagnosed"] = d / "diagnosed.h5"
    runs["diagnosed"].write_bytes(runs["identified"].read_bytes())
    services.store_result(runs["diagnosed"], "diagnosis", {"verdict": "none", "gap": {"before": 0.1}})
    return runs


@pytest.mark.parametrize("stage, current, nxt", [
    ("empty", "no shots yet", "acquire"),
    ("shots", "acquired: 3 hammer hits, 1 wave shot", "analyse"),
    ("analysed", "analysed: 3 hammer hits, 0 wave shots", "identify"),
    ("identified", "identified", "diagnose"),
    ("diagnosed", "identified and diagnosed", "write the report"),
])
def test_every_partial_run_opens_and_says_the_next_step(qtbot, partial_runs, stage, current, nxt):
    path = partial_runs[stage]
    w = open_window(path)
    try:
        assert w.run_path == str(path)
        assert not errors(w), errors(w)
        assert w.messages[-1][0] == f"opened {path}"
        assert w.step_label.text() == f"now: {current}  →  next: " + w.step_label.text().split("next: ")[1]
        assert w.step_label.text().split("next: ")[1].startswith(nxt)
        counts = services.open_run(path).counts
        assert w.acquisition.counter.text() == (f"in the run file: {counts['hammer']} hits · "
                                                f"{counts['wave']} wave shots")
        if stage == "empty":
            assert any(t.startswith("no data yet") for t in notes(w.acquisition.trace_plot))
            assert any(t.startswith("no data yet") for t in notes(w.modes.plot))
            assert w.waves._scalo_note.isVisible()
        else:       # the last stored record is drawn
            assert w.acquisition.trace_plot.getPlotItem().listDataItems()
        if stage != "diagnosed":
            assert any(t.startswith("no data yet") for t in notes(w.gap.resid_plot))
        else:
            assert w.gap.result["verdict"] == "none" and not notes(w.gap.resid_plot)
        if stage in ("empty", "shots", "analysed"):
            assert any(t.startswith("no data yet") for t in notes(w.identification.history_plot))
        if stage in ("identified", "diagnosed"):
            t = w.identification.table
            assert t.rowCount() == 2
            assert t.item(0, 1).text().startswith("130 ± nan GPa")    # missing std: said, not a crash
    finally:
        dispose(w)


def test_modes_table_shows_the_features_sigma(qtbot, partial_runs):
    """One source of truth: the sigma in the Modes table is the features file's, which
    identification uses (not the peak fit's own)."""
    path = partial_runs["analysed"]
    feats = json.loads(Path(services.features_path(path)).read_text())["modal"]
    w = open_window(path)
    try:
        t = w.modes.table
        assert t.rowCount() == len(feats["frequencies_hz"])
        for i, (f, s) in enumerate(zip(feats["frequencies_hz"], feats["sigma_hz"])):
            assert float(t.item(i, 0).text()) == pytest.approx(f, abs=1e-3)
            assert float(t.item(i, 1).text()) == pytest.approx(s, rel=1e-2)
    finally:
        dispose(w)


def test_default_parameters_are_the_command_lines(qtbot, partial_runs):
    """Modal data of an orthotropic plate: the CLI fits E1 E2 nu12 G12 G13 G23 (estimation.default_params)."""
    w = open_window(partial_runs["analysed"])
    try:
        assert w.identification.chosen_params() == ("E1", "E2", "nu12", "G12", "G13", "G23")
    finally:
        dispose(w)


def test_closing_the_window_cancels_and_disconnects_its_job(qtbot, partial_runs):
    """A job still running when its window closes is cancelled and can no longer reach
    the deleted widgets (issue 17: 'QLabel already deleted' in the teardown)."""
    import threading
    w = open_window(partial_runs["analysed"])
    release = threading.Event()
    seen = []

    def work(progress, should_stop):
        release.wait(60)
        progress(("eval", 1))
        return "late result"

    job = w.start_job("probe", work, seen.append, on_progress=seen.append, exclusive=False)
    assert job is not None and job.is_running()
    w.shutdown_jobs(wait_ms=0)
    assert job.cancelled and w.job is None and not w._side_jobs
    dispose(w)
    release.set()
    job.wait(60_000)
    QApplication.processEvents()
    assert seen == []          # nothing delivered after the window closed


@pytest.mark.slow
def test_the_demo_run_file_opens(qtbot, tmp_path, demo_output):
    """The run file `labid demo` writes opens with every view filled (issue 17, item 1)."""
    out = tmp_path / "demo"
    shutil.copytree(demo_output[0], out)      # the session's shared demo run, not written into
    for name in ("demo_run.h5", "demo_waves.h5"):
        path = out / name
        rd = services.open_run(path)
        w = open_window(path)
        try:
            assert not errors(w), errors(w)
            ident = rd.results["identification"]
            t = w.identification.table
            assert t.rowCount() == len(ident["parameters"])
            assert [t.item(i, 0).text() for i in range(t.rowCount())] == list(ident["parameters"])
            assert w.acquisition.counter.text() == (f"in the run file: {rd.counts['hammer']} hits · "
                                                    f"{rd.counts['wave']} wave shots")
            if rd.counts["hammer"]:
                modal = services.features_of(rd)["modal"]
                assert w.modes.table.rowCount() == len(modal["frequencies_hz"])
            if "diagnosis" in rd.results:
                assert w.gap.result is not None
                assert w.gap.result["verdict"] == rd.results["diagnosis"]["verdict"]
        finally:
            dispose(w)


def test_pairing_of_a_result_is_shown(qtbot, partial_runs, tmp_path):
    """A result with a pairing (s1/s5's identify) shows it, family labels included;
    without one the table stays hidden."""
    path = tmp_path / "paired.h5"
    path.write_bytes(partial_runs["analysed"].read_bytes())
    services.store_result(path, "identification", {
        "parameters": {"E1": {"value": 136.7e9, "std": 0.4e9}}, "converged": True,
        "pairing": [{"peak": 1, "measured_hz": 100.0, "mode_index": 1, "family": "(1,1) torsion",
                     "predicted_hz": 101.0},
                    {"peak": None, "measured_hz": None, "mode_index": 2, "family": "(0,2)", "predicted_hz": 120.0}]})
    w = open_window(path)
    try:
        t = w.identification.pairing_table
        assert not t.isHidden() and t.rowCount() == 2
        assert [t.item(0, j).text() for j in range(6)] == ["1", "100.000", "1", "(1,1) torsion", "101.000",
                                                          "+1.00 %"]
        assert t.item(1, 5).text() == "predicted mode without a peak"
    finally:
        dispose(w)
    w = open_window(partial_runs["analysed"])
    try:
        assert w.identification.pairing_table.isHidden()
    finally:
        dispose(w)
