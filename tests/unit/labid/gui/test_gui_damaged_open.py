"""Issue 15: a damaged run file opened from the panel's File > Open run… menu gives one
line naming the file and what is wrong; the run opened before stays open and the panel
stays usable (pytest-qt, offscreen)."""
from __future__ import annotations

import sys

import pytest

pytest.importorskip("pytestqt")

from PySide6.QtWidgets import QApplication  # noqa: E402

import labid.gui.main_window as mw  # noqa: E402

from fuzzcases import damaged_copy  # noqa: E402
from tests.integration.test_reliability import small_run  # noqa: E402

#: damage -> a word the one line must hold (what is wrong)
DAMAGES = {"labid_schema=one": "labid_schema", "channels={bad": "channels", "rate_hz=0": "rate_hz",
           "not_hdf5": "HDF5", "half": "", "samples=99999999999": "samples"}


def damaged(base, dst, how):
    if how == "not_hdf5":
        dst.write_text("name = 'a specimen, not a run'\n")
        return dst
    if how == "half":
        data = base.read_bytes()
        dst.write_bytes(data[: len(data) // 2])
        return dst
    return damaged_copy(base, dst, how, 3)


@pytest.fixture
def win(main_window):
    return main_window


def open_from_menu(win, qtbot, monkeypatch, path) -> None:
    """File > Open run…, the dialog answering ``path``."""
    monkeypatch.setattr(mw.QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(path), "")))
    menu = next(a.menu() for a in win.menuBar().actions() if a.text() == "&File")
    action = next(a for a in menu.actions() if a.text() == "&Open run…")
    action.trigger()                 # the run is read in a worker thread (issue 26): wait for it
    if win.opening is not None:
        qtbot.waitSignal(win.opening.ended, timeout=900_000).wait()
    QApplication.processEvents()


@pytest.mark.parametrize("how", list(DAMAGES))
def test_damaged_run_from_the_file_menu(win, qtbot, monkeypatch, tmp_path, how):
    hooked = []
    monkeypatch.setattr(sys, "excepthook", lambda *a: hooked.append(a))
    good = small_run(tmp_path / "good.h5", shots=2)
    bad = damaged(good, tmp_path / "bad.h5", how)
    open_from_menu(win, qtbot, monkeypatch, good)
    assert win.messages[-1] == (f"opened {good}", False) and win.run_path == str(good)
    n = len(win.messages)
    open_from_menu(win, qtbot, monkeypatch, bad)
    new = win.messages[n:]
    assert len(new) == 1, new
    text, error = new[0]
    assert error and "\n" not in text and str(bad) in text and DAMAGES[how] in text, text
    assert "Traceback" not in text
    assert win.status_label.text() == text
    # the panel is usable: the good run is still the one open, its views reload, it opens again
    assert win.run_path == str(good) and win.run_label.text() != ""
    assert win.acquisition.isEnabled() and win.identification.run_btn is not None
    win.tabs.setCurrentWidget(win.modes)
    win.modes.reload()
    open_from_menu(win, qtbot, monkeypatch, good)
    assert win.messages[-1] == (f"opened {good}", False)
    assert hooked == []
