"""One writer at a time: an advisory lock beside the run file (``RUN.h5.lock``), and one on
the run file itself.

``WriterLock(run)`` takes an exclusive ``fcntl.flock`` on ``RUN.h5.lock`` (beside the
run's real path) and writes the holder's PID and host into it; a second writer (another
``labid acquire``, ``labid analyze``, the panel) is refused at once with a ``UserError``
naming them. It then takes a second ``flock`` on the run file's own inode (device and
inode identify the file): two names of one run (hard links) cannot both write, since
the kernel's lock is on the file, not on a name. After the holder replaces the run file
(results are written into a copy renamed over it) it moves that lock to the new file
(``relock``). The kernel drops the locks when their holder dies, so a killed writer
never leaves a stale lock (the file left behind is just a note). Re-entrant within one
process: the same process may open the run for writing again while it holds the lock
(the panel saving its session during a live acquisition).

Planted links (issue 27): the lock file is created with ``O_CREAT | O_EXCL | O_NOFOLLOW``
or, when it exists, opened with ``O_NOFOLLOW``, and used only if it is a regular file
with one link: a symbolic or hard link planted at ``RUN.h5.lock`` is refused in one
line, never written through.

Readers take no lock: they read through SWMR or a never-writing view
(``labid.store.readonly``).
"""
from __future__ import annotations

import errno
import fcntl
import os
import socket
import stat
import threading
from pathlib import Path

from ..base.errors import UserError

_held: dict[str, list] = {}        # lock path -> [fd, count, run-file fd or -1]
_guard = threading.Lock()
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


def lock_path(run: str | Path) -> Path:
    """Where the lock of ``run`` lives: ``RUN.h5.lock`` beside its real path."""
    run = Path(os.path.realpath(run))
    return run.with_name(run.name + ".lock")


def holder(run: str | Path) -> str:
    """'PID 123 on host h' as written by the lock's holder ('' when unknown)."""
    try:
        fd = os.open(lock_path(run), os.O_RDONLY | _NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return ""
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return ""
        return os.read(fd, 200).decode(errors="replace").strip()
    except OSError:
        return ""
    finally:
        os.close(fd)


def _refuse_link(run: Path, path: Path, what: str) -> UserError:
    return UserError(f"the lock file {path.name} is {what}, not one labid made; expected no file there "
                     "(labid never writes through a link it did not create: remove it)", file=str(run))


class WriterLock:
    """Exclusive writer lock of a run file; ``release()`` (or leave the ``with``) to free it."""

    def __init__(self, run: str | Path):
        self.run = Path(run)
        self.path = lock_path(run)
        self._key = str(self.path)
        self._owned = False
        with _guard:
            if self._key in _held:
                _held[self._key][1] += 1
                self._owned = True
                return
            fd = self._acquire()
            try:
                inode = _lock_inode(self.run)
            except BaseException:
                self._drop(fd)
                raise
            _held[self._key] = [fd, 1, inode]
            self._owned = True

    def _open(self) -> int:
        flags = os.O_RDWR | os.O_CLOEXEC | _NOFOLLOW
        try:
            return os.open(self.path, flags | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            pass
        try:
            fd = os.open(self.path, flags | os.O_NONBLOCK)
        except OSError as e:
            if e.errno == errno.ELOOP:
                raise _refuse_link(self.run, self.path, "a symbolic link") from None
            raise
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_nlink != 1:
            os.close(fd)
            what = "a hard link to another file" if stat.S_ISREG(st.st_mode) else "not a regular file"
            raise _refuse_link(self.run, self.path, what)
        return fd

    def _acquire(self) -> int:
        for _ in range(20):          # the lock file may be unlinked by a releasing holder
            try:
                fd = self._open()
            except FileNotFoundError:
                continue
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
                now = os.stat(self.path, follow_symlinks=False)
                same = os.fstat(fd).st_ino == now.st_ino and stat.S_ISREG(now.st_mode)
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

    def relock(self) -> None:
        """Move the lock on the run file to the file now at its path (after the holder
        renamed a new file over it, or created it)."""
        relock(self.run)

    def _drop(self, fd: int) -> None:
        try:
            self.path.unlink(missing_ok=True)   # while still locked: no one else holds this inode
        except OSError:
            pass
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)

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
            if entry[2] >= 0:
                os.close(entry[2])
            self._drop(entry[0])

    def __enter__(self) -> "WriterLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self) -> None:  # pragma: no cover - safety net
        try:
            self.release()
        except Exception:  # noqa: BLE001
            pass


def _lock_inode(run: Path) -> int:
    """An exclusive flock on the run file itself (-1 when it does not exist yet or is not a
    regular file: the store refuses those). UserError when another writer holds the same
    file under another name."""
    try:
        fd = os.open(run, os.O_RDONLY | os.O_CLOEXEC | _NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return -1
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        return -1
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise UserError("in use by another writer (the same file under another name: a hard link); "
                        "expected one writer at a time (wait for it to finish, or read the run only)",
                        file=str(run)) from None
    except OSError:
        os.close(fd)             # a file system without flock: the lock file still holds
        return -1
    return fd


def held(run: str | Path) -> bool:
    """True if this process holds the writer lock of ``run``."""
    return str(lock_path(run)) in _held


def relock(run: str | Path) -> None:
    """Move this process's lock on the run file ``run`` to the file now at its path (after
    a new file was renamed over it, or created); nothing if the process holds no lock."""
    with _guard:
        entry = _held.get(str(lock_path(run)))
        if entry is None:
            return
        old, entry[2] = entry[2], -1
        if old >= 0:
            os.close(old)
        entry[2] = _lock_inode(Path(run))
