"""Test-wide settings: headless Qt and matplotlib, labid's own BLAS threading
(one thread per process unless LABID_THREADS or OMP_NUM_THREADS say otherwise)."""
import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("MPLBACKEND", "Agg")

from labid.base import threads  # noqa: E402

threads.configure()

import signal  # noqa: E402

# A test suite started as a background job (`make test &`, nohup, some CI runners) inherits
# SIGINT ignored; its children would inherit that too and never see the Ctrl-C the signal
# tests send (a child waited 40 min in signal.pause()). Ctrl-C is restored as a terminal gives it.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


import pytest  # noqa: E402


@pytest.fixture
def main_window(qtbot):
    """The panel's main window, shown at 1366 x 768; closed and deleted (its jobs
    cancelled and disconnected) after the test."""
    import gc

    from PySide6.QtCore import QEvent
    from PySide6.QtWidgets import QApplication

    from labid.gui.main_window import MainWindow
    w = MainWindow()
    w.resize(1366, 768)
    w.show()
    yield w
    w.close()
    w.deleteLater()
    QApplication.sendPostedEvents(None, QEvent.DeferredDelete)
    QApplication.processEvents()
    gc.collect()


@pytest.fixture(scope="session")
def demo_output(tmp_path_factory):
    """``labid demo --json`` run once per test session, shared (issue 29: it ran twice, 112 s
    of the suite's CPU): (output folder, its JSON result). Under pytest-xdist the workers share
    one run through a lock in the session's base folder; the first to come runs it. Tests that
    write into its files copy them first."""
    import fcntl
    import json

    from labid.cli.main import main

    worker = os.environ.get("PYTEST_XDIST_WORKER")
    root = tmp_path_factory.getbasetemp()
    if worker:                         # the session folder all workers share
        root = root.parent
    out, res = root / "shared_demo", root / "shared_demo.json"
    with open(root / "shared_demo.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)          # the others wait here for the first run
        if not res.exists():
            code = main(["demo", "--quiet", "--out", str(out), "--json", str(res) + ".part"])
            assert code == 0, f"labid demo exited with {code}"
            os.replace(str(res) + ".part", res)
    return out, json.loads(res.read_text())
