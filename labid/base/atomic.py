"""Atomic file outputs (issues 15 and 27): a file is written under a temporary name beside
it, synced, then renamed over the target (``os.replace``), so that a reader, a kill or a
full disk never leaves a half-written JSON, HTML, PNG, CSV or UFF file at the target.

The temporary file is made by ``tempfile.mkstemp`` in the target's directory
(``O_CREAT | O_EXCL``, an unpredictable name ``.NAME.XXXXXXXX.tmp``): a symbolic link
planted at a predictable name is never written through, and neither is one planted at
the target (``os.replace`` replaces the link itself). The result gets the permissions
a plain ``open(path, "w")`` would give (0666 less the umask).

``write_text(path, text)``, ``write_bytes(path, data)``, ``replacing(path)`` (a context
manager yielding the temporary path, for writers that want a file name:
``fig.savefig(tmp)``, pyuff) and ``open_replacing(path)`` (yielding a binary file
object). A failure to write (disk full ENOSPC, file-size limit EFBIG, read-only
directory...) is a ``UserError`` naming the file and the reason; the target is left
as it was and the temporary file removed.

``reserve(fd, offset, nbytes)`` allocates disk space in a file before a library writes
there (``labid.store`` reserves each shot's bytes before HDF5 writes them: an HDF5 write
that fails half-way leaves the library unable to close the file).
"""
from __future__ import annotations

import contextlib
import errno
import os
import resource
from pathlib import Path
from typing import BinaryIO, Iterator

from .errors import UserError

_UMASK = os.umask(0)
os.umask(_UMASK)

#: errors of the storage a user can fix (a full disk, a size limit, permissions)
FULL = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


def temp_beside(path: str | Path, suffix: str = ".tmp") -> Path:
    """A new empty file ``.NAME.XXXXXXXX<suffix>`` beside ``path`` (``mkstemp``: created
    with O_EXCL under an unpredictable name, mode 0600 until ``publish``)."""
    import tempfile     # here: its import (random, shutil) is ~5-8 ms of every command's start

    path = Path(path)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    return Path(name)


def reason(e: OSError) -> str:
    """The one-line reason of a storage error ('No space left on device (disk full)')."""
    text = e.strerror or (str(e).splitlines() or [type(e).__name__])[0]
    if e.errno == errno.ENOSPC:
        text += " (disk full)"
    elif e.errno == errno.EFBIG:
        text += " (the file-size limit, ulimit -f)"
    return text


def _fail(path: Path, e: OSError, key: str | None) -> UserError:
    return UserError(f"cannot write ({reason(e)}); the file is left as it was", file=str(path), key=key)


def default_mode() -> int:
    """The permissions ``open(path, "w")`` gives a new file: 0666 less the umask."""
    return 0o666 & ~_UMASK


def publish(tmp: Path, path: Path) -> None:
    """Sync ``tmp``, give it the default permissions and rename it over ``path``."""
    fd = os.open(tmp, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    try:
        os.fchmod(fd, default_mode())
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    fsync_dir(path.parent)


@contextlib.contextmanager
def replacing(path: str | Path, key: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically.
    The writer may write it by name (it exists, empty, made by ``temp_beside``)."""
    path = Path(path)
    tmp = None
    try:
        tmp = temp_beside(path)
        yield tmp
        publish(tmp, path)
    except OSError as e:
        if e.errno is None:
            raise
        raise _fail(path, e, key) from None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()


@contextlib.contextmanager
def open_replacing(path: str | Path, key: str | None = None) -> Iterator[BinaryIO]:
    """Yield a binary file object on a temporary file beside ``path``; closed, synced and
    renamed over ``path`` on success."""
    with replacing(path, key) as tmp:
        with open(tmp, "r+b") as fh:
            yield fh


def write_bytes(path: str | Path, data: bytes, key: str | None = None) -> None:
    """Write ``data`` to ``path`` atomically."""
    with open_replacing(path, key) as fh:
        fh.write(data)


def write_text(path: str | Path, text: str, key: str | None = None) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes(path, text.encode("utf-8"), key)


def fsync_dir(d: str | Path) -> None:
    """Make a rename in directory ``d`` durable (best effort: not every file system can)."""
    try:
        fd = os.open(d, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def reserve(fd: int, offset: int, nbytes: int) -> None:
    """Allocate ``nbytes`` of disk from ``offset`` in the open file ``fd`` (the file grows
    to ``offset + nbytes`` if shorter): later writes below that end cannot fail for want
    of space or of the file-size limit. OSError (ENOSPC, EFBIG) when they would.

    ``os.posix_fallocate`` where it exists (glibc writes zeros on file systems without
    fallocate); elsewhere the free space and ``RLIMIT_FSIZE`` are compared with the need."""
    end = offset + nbytes
    if hasattr(os, "posix_fallocate"):
        try:
            os.posix_fallocate(fd, offset, nbytes)
            return
        except OSError as e:
            if e.errno not in (errno.EINVAL, errno.EOPNOTSUPP, errno.ENOSYS, errno.ENODEV):
                raise
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if soft != resource.RLIM_INFINITY and end > soft:
        raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))
    st = os.fstatvfs(fd)
    have = os.fstat(fd).st_size
    if end > have and (end - have) > st.f_bavail * st.f_frsize:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
