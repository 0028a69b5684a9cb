"""Long work off the GUI thread: a ``Job`` runs ``fn(progress, should_stop)`` in a QThread.

The function reports through ``progress(obj)`` (delivered to the GUI thread as the
``progress`` signal) and polls ``should_stop()`` to end early after ``cancel()``.
Errors a user can cause (``UserError``, ``AcquisitionError``, back-end
``ValueError`` subclasses) arrive as ``failed(one line)``; anything else as
``failed('internal error: ...')`` with the traceback printed to stderr only.
"""
from __future__ import annotations

import sys
import threading
import traceback
from typing import Any, Callable

from PySide6.QtCore import QObject, QThread, Signal

from drivers.protocol import AcquisitionError

from ..errors import UserError


class Cancelled(Exception):
    """Raised by job functions that stop early on request."""


def one_line(exc: BaseException) -> str:
    """The message a user sees for an exception: one line, no traceback."""
    text = str(exc).strip().splitlines()
    msg = text[0] if text else type(exc).__name__
    if isinstance(exc, (UserError, AcquisitionError)):
        return msg
    if isinstance(exc, ValueError):
        return msg
    return f"internal error ({type(exc).__name__}: {msg})"


class _Thread(QThread):
    def __init__(self, job: "Job"):
        super().__init__()
        self.job = job

    def run(self) -> None:  # noqa: D102 - executed in the worker thread
        job = self.job
        try:
            result = job.fn(job._emit_progress, job.should_stop)
        except Cancelled:
            job.failed.emit("cancelled")
            return
        except BaseException as e:  # noqa: BLE001 - nothing may escape into Qt
            if not isinstance(e, (UserError, AcquisitionError, ValueError)):
                traceback.print_exc(file=sys.stderr)
            job.failed.emit(one_line(e))
            return
        job.succeeded.emit(result)


class Job(QObject):
    """One background task. Signals: progress(obj), succeeded(result), failed(message),
    and ``ended`` after either (the thread has finished)."""

    progress = Signal(object)
    succeeded = Signal(object)
    failed = Signal(str)
    ended = Signal()

    def __init__(self, name: str, fn: Callable[[Callable[[Any], None], Callable[[], bool]], Any]):
        super().__init__()
        self.name, self.fn = name, fn
        self._stop = threading.Event()
        self._thread = _Thread(self)
        self._thread.finished.connect(self.ended.emit)

    def _emit_progress(self, obj: Any) -> None:
        self.progress.emit(obj)

    def should_stop(self) -> bool:
        return self._stop.is_set()

    def start(self) -> None:
        self._thread.start()

    def cancel(self) -> None:
        """Ask the job to stop at its next check."""
        self._stop.set()

    @property
    def cancelled(self) -> bool:
        return self._stop.is_set()

    def is_running(self) -> bool:
        return self._thread is not None and self._thread.isRunning()

    def wait(self, ms: int = 30000) -> bool:
        return self._thread.wait(ms) if self._thread is not None else True

    def release(self) -> None:
        """Drop the finished thread and the connections (no cycles left for the GC)."""
        th, self._thread = self._thread, None
        if th is not None:
            th.job = None
            th.deleteLater()
        self.fn = None
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # "failed to disconnect": none connected
            for sig in (self.progress, self.succeeded, self.failed, self.ended):
                try:
                    sig.disconnect()
                except (RuntimeError, TypeError):
                    pass
        self.deleteLater()
