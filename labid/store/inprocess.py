"""Readers and writers of one run file in one process (the panel: a worker thread reads
while the GUI thread writes).

HDF5 keeps one open file per process and file: an open for writing is refused while the
file is open read-only in the same process ("file is already open for read-only"), and
the writer's lock on the run file's inode (``labid.store.lock``) is refused while a
reader holds HDF5's shared lock on it. Neither says anything about the file, yet the
store used to call the first one "damaged" and the second one "another writer": after
an Abort under load, the panel's autosave met the Hammer checks job still reading the
hits and told the technician the sound run was damaged (CI, session 22).

Here, by the run's real path:

* ``Reading(path)``: a ``RunStore`` read-only open registers from before its HDF5 open
  to after its close; it waits while a writer of another thread is ``changing`` the file;
* ``changing(path)``: a writer's lock-and-open, and each of its close-and-reopen steps
  (``write_group``, leaving SWMR mode), wait until no reader of another thread has the
  file open, and keep new readers of other threads out until they end.

A reader of the writer's own thread is not waited for (it would wait on itself): that
open still fails, and ``busy`` says so in one line. A reader holding the file longer
than :data:`WAIT_S` s (an analysis reading the whole run) makes the writer give up with
that line instead of freezing the panel.
"""
from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path

from ..base.errors import UserError

#: seconds a writer waits for the readers of other threads of this process to close the
#: file (the panel's reads of a run take well under a second)
WAIT_S = 60.0

_cond = threading.Condition()
_readers: dict[str, dict[int, int]] = {}      # real path -> {thread id: open readers}
_changing: dict[str, list] = {}               # real path -> [thread id of the writer, depth]


def _key(path: str | Path) -> str:
    return os.path.realpath(path)


def busy(path: str | Path) -> UserError:
    """The line for a run open for reading elsewhere in this process when a writer needs it."""
    return UserError("open for reading by another task of this program; expected it closed before "
                     "writing (try again when that task has finished)", file=str(path))


def readers_elsewhere(path: str | Path) -> int:
    """Readers of ``path`` open in other threads of this process."""
    me = threading.get_ident()
    with _cond:
        return sum(n for t, n in _readers.get(_key(path), {}).items() if t != me)


class Reading:
    """One read-only open of ``path`` by this thread, registered until ``release()``."""

    def __init__(self, path: str | Path):
        self.key, self.me = _key(path), threading.get_ident()
        with _cond:
            mine = _readers.get(self.key, {}).get(self.me, 0)
            if not mine:      # a thread already reading goes on (a writer may be waiting for it)
                _cond.wait_for(lambda: _changing.get(self.key, [self.me])[0] == self.me)
            _readers.setdefault(self.key, {})[self.me] = mine + 1
        self._held = True

    def release(self) -> None:
        if not getattr(self, "_held", False):
            return
        self._held = False
        with _cond:
            mine = _readers[self.key]
            mine[self.me] -= 1
            if not mine[self.me]:
                del mine[self.me]
            if not mine:
                del _readers[self.key]
            _cond.notify_all()


@contextlib.contextmanager
def changing(path: str | Path):
    """Context of a writer opening, closing or reopening ``path`` (module docstring);
    ``busy(path)`` when readers of other threads keep it open more than ``WAIT_S`` s."""
    key, me = _key(path), threading.get_ident()

    def clear() -> bool:
        return (_changing.get(key, [me])[0] == me
                and not any(t != me for t in _readers.get(key, {})))

    with _cond:
        if not _cond.wait_for(clear, timeout=WAIT_S):
            raise busy(path)
        entry = _changing.setdefault(key, [me, 0])
        entry[1] += 1
    try:
        yield
    finally:
        with _cond:
            entry[1] -= 1
            if not entry[1]:
                del _changing[key]
            _cond.notify_all()
