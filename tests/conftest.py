"""Test-wide settings: headless Qt and matplotlib, labid's own BLAS threading
(one thread per process unless LABID_THREADS or OMP_NUM_THREADS say otherwise)."""
import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("MPLBACKEND", "Agg")

from labid.base import threads  # noqa: E402

threads.configure()


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
