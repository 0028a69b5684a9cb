"""One writer at a time: an advisory lock beside the run file (``RUN.h5.lock``).

``WriterLock(run)`` takes an exclusive ``fcntl.flock`` on ``RUN.h5.lock`` and writes
the holder's PID and host into it; a second writer (another ``labid acquire``,
``labid analyze``, the panel) is refused at once with a ``UserError`` naming them.
The kernel drops the lock when its holder dies, so a killed writer never leaves a
stale lock (the file left behind is just a note). Re-entrant within one process:
the same process may open the run for writing again while it holds the lock
(the panel saving its session during a live acquisition).

Readers take no lock: they read through SWMR or a never-writing view
(``labid.store.readonly``).
"""
from __future__ import annotations

import errno
import fcntl
import os
import socket
import threading
from pathlib import Path

from ..base.errors import UserError

_held: dict[str, list] = {}        # lock path -> [fd, count]
_guard = threading.Lock()


def lock_path(run: str | Path) -> Path:
    """Where the lock of ``run`` lives: ``RUN.h5.lock`` beside it."""
    run = Path(run)
    return run.with_name(run.name + ".lock")


def holder(run: str | Path) -> str:
    """'PID 123 on host h' as written by the lock's holder ('' when unknown)."""
    try:
        return lock_path(run).read_text(errors="replace").strip()[:200]
    except OSError:
        return ""


class WriterLock:
    """Exclusive writer lock of a run file; ``release()`` (or leave the ``with``) to free it."""

    def __init__(self, run: str | Path):
        self.run = Path(run)
        self.path = lock_path(run)
        self._key = str(self.path.absolute())
        self._owned = False
        with _guard:
            if self._key in _held:
                _held[self._key][1] += 1
                self._owned = True
                return
            fd = self._acquire()
            _held[self._key] = [fd, 1]
            self._owned = True

    def _acquire(self) -> int:
        for _ in range(20):          # the lock file may be unlinked by a releasing holder
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except OSError as e:
                if e.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
                    raise UserError(f"cannot lock for writing ({e.strerror}); expected a writable "
                                    "directory (the run can still be read)", file=str(self.run)) from None
                raise
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                who = holder(self.run) or "another process"
                raise UserError(f"in use by another writer ({who}); expected one writer at a time "
                                "(wait for it to finish, or read the run only)", file=str(self.run)) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            try:
                os.ftruncate(fd, 0)
                os.write(fd, f"PID {os.getpid()} on host {socket.gethostname()}\n".encode())
            except OSError:
                pass                 # the note is a courtesy; the flock is the lock
            return fd
        raise UserError("cannot take the writer lock (lock file keeps changing)", file=str(self.run))

    def release(self) -> None:
        if not self._owned:
            return
        self._owned = False
        with _guard:
            entry = _held.get(self._key)
            if entry is None:
                return
            entry[1] -= 1
            if entry[1] > 0:
                return
            del _held[self._key]
            fd = entry[0]
            try:
                self.path.unlink(missing_ok=True)   # while still locked: no one else holds this inode
            except OSError:
                pass
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def __enter__(self) -> "WriterLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self) -> None:  # pragma: no cover - safety net
        try:
            self.release()
        except Exception:  # noqa: BLE001
            pass


def held(run: str | Path) -> bool:
    """True if this process holds the writer lock of ``run``."""
    return str(lock_path(run).absolute()) in _held
