"""Long work off the GUI thread: a ``Job`` runs ``fn(progress, should_stop)`` in a thread.

The function reports through ``progress(obj)`` and polls ``should_stop()`` to end
early after ``cancel()`` (raising ``labid.base.errors.Cancelled``). Errors a user can
cause (``services.USER_ERRORS``: ``UserError``, ``AcquisitionError``, back-end
``ValueError`` subclasses) arrive as
``failed(one line)``; anything else as ``failed('internal error: ...')`` with
the traceback printed to stderr only.

The worker never touches Qt: it puts its events in a queue that a timer of the
GUI thread drains, and the Qt signals (``progress``, ``succeeded``, ``failed``,
``ended``) are emitted there, so every slot runs in the GUI thread.
"""
from __future__ import annotations

import queue
import sys
import threading
import traceback
import warnings
from typing import Any, Callable

from PySide6.QtCore import QObject, QTimer, Signal

from ..base.errors import Cancelled
from ..services import USER_ERRORS

POLL_MS = 15


def one_line(exc: BaseException) -> str:
    """The message a user sees for an exception: one line, no traceback."""
    text = str(exc).strip().splitlines()
    msg = text[0] if text else type(exc).__name__
    if isinstance(exc, USER_ERRORS):
        return msg
    return f"internal error ({type(exc).__name__}: {msg})"


class Job(QObject):
    """One background task. Signals (GUI thread): progress(obj), succeeded(result),
    failed(message), and ``ended`` after either."""

    progress = Signal(object)
    succeeded = Signal(object)
    failed = Signal(str)
    ended = Signal()

    def __init__(self, name: str, fn: Callable[[Callable[[Any], None], Callable[[], bool]], Any]):
        super().__init__()
        self.name, self.fn = name, fn
        #: True once ``ended`` has been emitted (GUI thread)
        self.has_ended = False
        self._stop = threading.Event()
        self._done = threading.Event()
        self._events: queue.SimpleQueue = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, name=f"labid-job-{name}", daemon=True)
        self._timer = QTimer(self)
        self._timer.setInterval(POLL_MS)
        self._timer.timeout.connect(self._drain)

    # -- worker thread ------------------------------------------------------
    def _run(self) -> None:
        put = self._events.put
        try:
            result = self.fn(lambda obj: put(("progress", obj)), self.should_stop)
        except Cancelled:
            put(("failed", "cancelled"))
        except BaseException as e:  # noqa: BLE001 - nothing may escape the thread
            if not isinstance(e, USER_ERRORS):
                traceback.print_exc(file=sys.stderr)
            put(("failed", one_line(e)))
        else:
            put(("succeeded", result))
        finally:
            self._done.set()
            put(("ended", None))

    # -- GUI thread -----------------------------------------------------------
    def _drain(self) -> None:
        while True:
            try:
                kind, obj = self._events.get_nowait()
            except queue.Empty:
                return
            if kind == "progress":
                self.progress.emit(obj)
            elif kind == "succeeded":
                self.succeeded.emit(obj)
            elif kind == "failed":
                self.failed.emit(obj)
            else:
                self._timer.stop()
                self.has_ended = True
                self.ended.emit()
                return

    def should_stop(self) -> bool:
        return self._stop.is_set()

    def start(self) -> None:
        self._timer.start()
        self._thread.start()

    def cancel(self) -> None:
        """Ask the job to stop at its next check."""
        self._stop.set()

    @property
    def cancelled(self) -> bool:
        return self._stop.is_set()

    def is_running(self) -> bool:
        return not self._done.is_set()

    def wait(self, ms: int = 30000) -> bool:
        """Block until the worker has finished (events are delivered by the timer)."""
        return self._done.wait(ms / 1000.0)

    def release(self) -> None:
        """Drop the function and the connections once finished (no cycles left). Idempotent;
        call it after ``ended``'s emission, not from one of its slots (Qt skips the slots
        still to come when a slot disconnects them: a listener connected later would miss it)."""
        if getattr(self, "_released", False):
            return
        self._released = True
        self._timer.stop()
        self.fn = None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # "failed to disconnect": none connected
            for sig in (self.progress, self.succeeded, self.failed, self.ended):
                try:
                    sig.disconnect()
                except (RuntimeError, TypeError):
                    pass
        self.deleteLater()
