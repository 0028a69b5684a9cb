"""Abort under load (CI failure, session 22): the panel told a sound run file was damaged.

After an acquisition job, ``run_changed`` starts the Hammer checks job, which reads the
run's hits in a worker thread (``services.shots``: a read-only HDF5 open), and the job's
``ended`` slot saves the session (``services.save_session``: an ``"a"`` open) in the GUI
thread. h5py refuses to open a file for writing that is open read-only elsewhere in the
same process ("file is already open for read-only"), and the store called that refusal
"damaged or not a labid run file". On a loaded machine the checks job's read was still
open when the autosave came.

The interleaving is forced with events, never sleeps: the autosave starts only once the
checks job's read has the file open, and that read stays open until the autosave's writer
has met it (failed, before the fix; waits for the read to close, after it)."""
from __future__ import annotations

import threading

import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402

from labid import services  # noqa: E402
from labid.store import RunStore, runstore  # noqa: E402

from tests.unit.labid.gui.test_gui_views import BUDGET, fast_rig_text, set_rig, shot, wait_job  # noqa: E402

GUARD_S = BUDGET / 1000      # against a hung test only: every wait below ends on an event


@pytest.fixture
def win(main_window):
    return main_window


class Interleave:
    """Events of the forced interleaving (see the module docstring)."""

    def __init__(self, monkeypatch):
        self.reader_open = threading.Event()        # the checks job's read has the file open
        self.writer_met_reader = threading.Event()  # the autosave's writer failed, or waits for the read
        ev = self
        real_shots, real_save, real_changing = services.shots, services.save_session, getattr(
            runstore, "changing", None)

        def held_shots(run, kind, limit=None):
            if threading.current_thread() is threading.main_thread():
                return real_shots(run, kind, limit)
            with RunStore(run, "r") as st:        # the checks job: hold the read open
                ev.reader_open.set()
                assert ev.writer_met_reader.wait(GUARD_S)
                return st.shots(kind, limit=limit)

        def save_after_read(run, state):
            assert ev.reader_open.wait(GUARD_S)
            try:
                return real_save(run, state)
            finally:
                ev.writer_met_reader.set()

        def changing(path):                        # the writer waits for the readers (store.inprocess)
            if threading.current_thread() is threading.main_thread():
                ev.writer_met_reader.set()
            return real_changing(path)

        monkeypatch.setattr(services, "shots", held_shots)
        monkeypatch.setattr(services, "save_session", save_after_read)
        if real_changing is not None:
            monkeypatch.setattr(runstore, "changing", changing)


def test_abort_while_the_checks_read_the_run_says_interrupted(win, qtbot, tmp_path, monkeypatch):
    set_rig(win, fast_rig_text())
    acq = win.acquisition
    run = tmp_path / "abort.h5"
    acq.run_edit.setText(str(run))
    acq.hits_spin.setValue(100_000)
    acq.waves_spin.setValue(0)
    ev = Interleave(monkeypatch)
    qtbot.mouseClick(acq.start_btn, Qt.LeftButton)
    qtbot.waitUntil(lambda: acq.done["hammer"] >= 2, timeout=BUDGET)
    job = win.job
    qtbot.mouseClick(acq.abort_btn, Qt.LeftButton)
    wait_job(qtbot, job)
    checks = win.checks.job
    if checks is not None:
        wait_job(qtbot, checks)
    assert ev.reader_open.is_set() and ev.writer_met_reader.is_set()
    texts = [t for t, _ in win.messages]
    assert not [t for t in texts if "damaged" in t], texts
    assert "interrupted" in texts[-1], texts
    n = acq.last_summary["recorded"]["hammer"]
    with RunStore(run, "r") as st:           # every hit kept, and the session saved
        assert st.n_shots("hammer") == n >= 2
        assert "gui" in st.result_names()
    assert win.checks.checks is not None and len(win.checks.checks.hits) == n
    win.tabs.setCurrentWidget(acq)
    shot(win, "acquisition-after-abort")
