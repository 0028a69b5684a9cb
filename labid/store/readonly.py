"""A read path that never writes: open a run file as it is on disk, whatever flags a
killed writer left in its superblock, without repairing or copying it.

A writer killed outside SWMR mode leaves the superblock's "open for writing" flags
set, and HDF5 then refuses a plain read-only open. ``FlagClearedView`` is a
read-only file object over the file whose first bytes (the superblock) are seen
with those flags cleared and the superblock checksum recomputed; h5py reads
through it (``driver="fileobj"``). Nothing is written anywhere: a reader on a
full disk or a read-only directory reads all the same (issue 15).
"""
from __future__ import annotations

import io
from pathlib import Path

import h5py

from .h5repair import lookup3

_SIGNATURE = b"\x89HDF\r\n\x1a\n"


class FlagClearedView(io.RawIOBase):
    """Read-only, seekable view of an HDF5 file with the superblock flags seen cleared."""

    def __init__(self, path: str | Path):
        super().__init__()
        self._fh = open(path, "rb")
        head = bytearray(self._fh.read(64))
        if head[:8] != _SIGNATURE or len(head) < 12 or head[8] not in (2, 3):
            self._fh.close()
            raise OSError(f"{path}: not an HDF5 file with a version 2/3 superblock")
        n = 12 + 4 * head[9]
        head[11] = 0
        head[n:n + 4] = lookup3(bytes(head[:n])).to_bytes(4, "little")
        self._head = bytes(head[:n + 4])
        self._fh.seek(0)

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def writable(self) -> bool:
        return False

    def seek(self, pos: int, whence: int = 0) -> int:
        return self._fh.seek(pos, whence)

    def tell(self) -> int:
        return self._fh.tell()

    def readinto(self, b) -> int:
        pos = self._fh.tell()
        n = self._fh.readinto(b)
        if n and pos < len(self._head):
            k = min(n, len(self._head) - pos)
            memoryview(b)[:k] = self._head[pos:pos + k]
        return n

    def close(self) -> None:
        if not self.closed:
            self._fh.close()
        super().close()


def superblock_flags(path: str | Path) -> int | None:
    """The status flags of a version 2/3 superblock at the start of ``path`` (bit 0: open
    for writing, bit 2: open for SWMR writing); None for another layout."""
    with open(path, "rb") as fh:
        head = fh.read(12)
    if len(head) < 12 or head[:8] != _SIGNATURE or head[8] not in (2, 3):
        return None
    return head[11]


def open_read_only(path: str | Path) -> h5py.File:
    """``h5py.File`` of ``path`` for reading only, never writing. By the superblock's
    flags: through SWMR when a writer is appending in SWMR mode, through
    ``FlagClearedView`` when the flags say "open for writing" without SWMR (a killed
    writer), else plainly. SWMR is used only then: an SWMR reader retries unreadable
    metadata with pauses, which a damaged file would turn into a long wait. No HDF5
    file lock is required (the writer lock is ``labid.store.lock``). OSError when the
    file cannot be read."""
    flags = superblock_flags(path)
    if flags is not None and flags & 0x04:
        last: OSError | None = None
        for kw in ({}, {"locking": False}):  # in-process, the locking flag must match the writer's
            try:
                return h5py.File(path, "r", swmr=True, **kw)
            except OSError as e:
                last = e
        raise last
    if flags is not None and flags & 0x01:
        view = FlagClearedView(path)
        try:
            f = h5py.File(view, "r", locking=False)
        except BaseException:
            view.close()
            raise
        f._labid_view = view  # noqa: SLF001 - keeps the file object alive with the h5py file
        return f
    try:        # no HDF5 shared lock held while reading: it would refuse the writer's lock on the
        return h5py.File(path, "r", locking=False)     # inode (store.lock) as "another writer"
    except OSError:
        return h5py.File(path, "r")     # already open here by code that asked for HDF5's lock
