"""Disk space for the run file's HDF5 writes, and the temporary files beside it (issue 27:
a full disk or ``ulimit -f`` made HDF5 fail half-way through a shot, and the library then
crashed the process when the file was closed).

HDF5 cannot recover from a write that fails inside the library: the file can no longer be
flushed or closed, and freeing its objects segfaults. So the store never lets HDF5 meet a
full disk: ``reserved(f, nbytes)`` allocates the bytes a write will need at the file's
end (``labid.base.atomic.reserve``: ``posix_fallocate``) before HDF5 writes, refuses the
write in one line when they cannot be had (ENOSPC, EFBIG), and gives back the unused
tail afterwards. Should a write fail all the same, ``poison(f)`` keeps the library's
objects alive (never closed, never freed) and the command line ends the process without
running the library's exit handlers (``labid.cli.main``).
"""
from __future__ import annotations

import contextlib
import errno
import os
import re
from pathlib import Path
from typing import Iterator

import h5py

from ..base.atomic import FULL, reason, reserve
from ..base.errors import UserError

#: reserved besides the data for HDF5's metadata (chunk index, object headers, superblock)
MARGIN = 256 << 10
_POISONED: list = []
_WRITE_FAILED = re.compile(r"write failed|unable to extend|errno = (27|28|122)\b|No space left|File too large")


def poisoned() -> bool:
    """True if an HDF5 file of this process could not be written and must never be closed."""
    return bool(_POISONED)


def poison(*objects) -> None:
    """Keep HDF5 objects whose file failed a write alive for the process's lifetime."""
    _POISONED.extend(objects)


def is_write_failure(e: BaseException) -> bool:
    """True for an HDF5 (or OS) error that says a write to the file failed."""
    if isinstance(e, OSError) and e.errno in FULL:
        return True
    return isinstance(e, (RuntimeError, OSError, ValueError)) and bool(_WRITE_FAILED.search(str(e)))


def _size(f: h5py.File) -> int:
    """The end of what HDF5 has allocated or written in ``f`` (its idea, not the file's)."""
    return int(f.id.get_filesize())


@contextlib.contextmanager
def reserved(f: h5py.File, nbytes: float, path: Path, what: str, trim: bool = True) -> Iterator[None]:
    """Reserve ``nbytes`` (+ ``MARGIN``) at the end of the open file ``f`` for the writes
    of the block; UserError naming ``path`` and ``what`` was refused when the disk or the
    file-size limit cannot hold them. ``trim``: the unused reservation is given back after
    the block (the file cut to HDF5's own end; the block must end with a flush); else the
    reservation also covers closing the file, and ``trim_file`` gives it back after."""
    fd = f.id.get_vfd_handle()
    start = _size(f)
    try:
        reserve(fd, start, int(nbytes) + MARGIN)
    except OSError as e:
        if e.errno not in FULL:
            raise
        with contextlib.suppress(OSError):       # nothing of it was used
            if os.fstat(fd).st_size > start:
                os.ftruncate(fd, start)
        raise UserError(f"{what} refused: {reason(e)}; needs up to {(nbytes + MARGIN) / 1e6:.2g} MB more. "
                        "Everything written before is kept", file=str(path)) from None
    yield
    if trim:
        with contextlib.suppress(OSError):
            end = _size(f)
            if os.fstat(fd).st_size > end >= start:
                os.ftruncate(fd, end)


def trim_file(path: Path) -> None:
    """Cut a closed HDF5 file to the end its superblock records (version 2/3: the base
    address plus the end-of-file address): gives back a reservation made with
    ``trim=False``. Nothing for another layout."""
    with open(path, "r+b") as fh:
        head = fh.read(48)
        if head[:8] != b"\x89HDF\r\n\x1a\n" or len(head) < 12 or head[8] not in (2, 3):
            return
        n = head[9]
        base = int.from_bytes(head[12:12 + n], "little")
        end = base + int.from_bytes(head[12 + 2 * n:12 + 3 * n], "little")
        if 0 < end < os.fstat(fh.fileno()).st_size:
            fh.truncate(end)


def remove_stale(path: Path, suffixes: tuple[str, ...]) -> None:
    """Temporary files a killed writer left beside the run ``path`` (the caller holds the
    lock: none is live): ``.RUN.h5.XXXXXXXX.results`` and the like (``atomic.temp_beside``),
    and the fixed names of earlier versions (``RUN.h5.results``...). Unlinking never
    follows a link."""
    name = re.escape(f".{path.name}.") + r"[a-z0-9_]{8}(" + "|".join(re.escape(s) for s in suffixes) + ")"
    old = {path.name + s for s in suffixes}
    for p in path.parent.iterdir():
        if p.name in old or re.fullmatch(name, p.name):
            with contextlib.suppress(OSError):
                p.unlink()


def write_failed(path: Path, e: BaseException, what: str) -> UserError:
    """The one line for an HDF5 write that failed despite the reservation."""
    text = reason(e) if isinstance(e, OSError) and e.errno is not None else (
        str(e).split("error message = ")[-1].split(",")[0].strip("' ") or type(e).__name__)
    if isinstance(e, RuntimeError) and "errno = 28" in str(e):
        text = os.strerror(errno.ENOSPC) + " (disk full)"
    return UserError(f"{what} failed: {text}; the shots committed before are kept", file=str(path))
