"""SIGINT (Ctrl-C) and SIGTERM close the panel cleanly (issue 26).

Qt's event loop runs in C++: a Python signal handler only runs when the interpreter gets
control, so a timer wakes it every :data:`WAKE_MS`. The handler closes the window (its
jobs cancelled, an acquisition finishing its shot, the session saved: ``closeEvent``) and
quits the event loop; ``received()`` then tells which signal ended the panel, so that the
command exits 130 (SIGINT) or 143 (SIGTERM) like every other labid command.
"""
from __future__ import annotations

import signal

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QWidget

#: how often the interpreter gets control to run a pending signal handler, ms
WAKE_MS = 200


class CloseOnSignals:
    """Install the handlers for ``window`` in ``app`` (main thread); ``restore()`` puts the
    previous handlers back."""

    def __init__(self, app: QApplication, window: QWidget):
        self.app, self.window, self.signum = app, window, None
        self._previous = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        self._timer = QTimer()
        self._timer.timeout.connect(lambda: None)       # Python runs pending handlers between calls
        self._timer.start(WAKE_MS)

    def _handle(self, signum, frame) -> None:  # noqa: ARG002 - signal handler signature
        if self.signum is None:
            self.signum = signum
            QTimer.singleShot(0, self._close)

    def _close(self) -> None:
        self.window.close()
        self.app.quit()

    def received(self) -> int | None:
        """The signal that closed the panel, or None."""
        return self.signum

    def restore(self) -> None:
        self._timer.stop()
        for s, h in self._previous.items():
            signal.signal(s, h)
