"""Repair of HDF5 run files left "open for writing" by a killed writer.

Kept hand-written because h5py has no ``h5clear`` (the HDF5 command-line tool
is not part of the wheels h5py ships, and h5py exposes neither ``H5Fclear`` nor
a "clear the consistency flags" open mode): a file whose writer died outside
SWMR mode refuses to open with "file is already open for write (may use
<h5clear file> to clear file consistency flags)". ``tests/test_runstore.py``
pins both halves of that reason: h5py alone cannot open such a file, and
``lookup3`` reproduces the checksum the HDF5 library writes into a superblock.

* ``open_flagged(path)``: a read-only view, through SWMR, else through
  ``cleared_copy`` (a copy whose superblock flags are cleared, its lookup3
  checksum recomputed);
* ``repair(path)``: copy the file (read that way) into a fresh file,
  atomically renamed over the old one.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import h5py

from ..base.atomic import temp_beside
from .space import is_write_failure, poison, reserved, trim_file


def is_consistency_flag_error(e: OSError) -> bool:
    """True if ``e`` is h5py refusing a file whose "open for writing" flags are set."""
    return "consistency flags" in str(e) or "h5clear" in str(e)


def copy_attrs(src, dst) -> None:
    """Copy the HDF5 attributes of ``src`` onto ``dst``."""
    for k, v in src.attrs.items():
        dst.attrs[k] = v


_M32 = 0xFFFFFFFF


def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & _M32


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 hashlittle, byte-wise (HDF5 H5_checksumlookup3)."""
    n = len(data)
    a = b = c = (0xDEADBEEF + n + initval) & _M32
    i = 0
    while n > 12:
        k = data[i:i + 12]
        a = (a + int.from_bytes(k[0:4], "little")) & _M32
        b = (b + int.from_bytes(k[4:8], "little")) & _M32
        c = (c + int.from_bytes(k[8:12], "little")) & _M32
        a = (a - c) & _M32; a ^= _rot(c, 4); c = (c + b) & _M32
        b = (b - a) & _M32; b ^= _rot(a, 6); a = (a + c) & _M32
        c = (c - b) & _M32; c ^= _rot(b, 8); b = (b + a) & _M32
        a = (a - c) & _M32; a ^= _rot(c, 16); c = (c + b) & _M32
        b = (b - a) & _M32; b ^= _rot(a, 19); a = (a + c) & _M32
        c = (c - b) & _M32; c ^= _rot(b, 4); b = (b + a) & _M32
        n -= 12
        i += 12
    if n == 0:
        return c
    k = data[i:i + n] + bytes(12 - n)
    a = (a + int.from_bytes(k[0:4], "little")) & _M32
    b = (b + int.from_bytes(k[4:8], "little")) & _M32
    c = (c + int.from_bytes(k[8:12], "little")) & _M32
    c ^= b; c = (c - _rot(b, 14)) & _M32
    a ^= c; a = (a - _rot(c, 11)) & _M32
    b ^= a; b = (b - _rot(a, 25)) & _M32
    c ^= b; c = (c - _rot(b, 16)) & _M32
    a ^= c; a = (a - _rot(c, 4)) & _M32
    b ^= a; b = (b - _rot(a, 14)) & _M32
    c ^= b; c = (c - _rot(b, 24)) & _M32
    return c


def cleared_copy(path: Path) -> Path:
    """A copy of ``path`` with the superblock's "open for writing" flags cleared.

    A writer killed outside SWMR mode (while it created tables or wrote results)
    leaves these flags set; nothing but the flags is wrong once its last flush
    completed. Superblock v2/v3: flags at byte 11, lookup3 checksum after
    12 + 4 * sizeof(offsets) bytes.
    """
    tmp = temp_beside(path, ".unlocked")
    try:
        shutil.copyfile(path, tmp)
        with open(tmp, "r+b") as fh:
            head = bytearray(fh.read(64))
            if head[:8] != b"\x89HDF\r\n\x1a\n" or head[8] not in (2, 3):
                raise OSError(f"{path}: not an HDF5 file with a version 2/3 superblock")
            n = 12 + 4 * head[9]
            head[11] = 0
            fh.seek(11)
            fh.write(b"\x00")
            fh.seek(n)
            fh.write(lookup3(bytes(head[:n])).to_bytes(4, "little"))
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


def open_flagged(path: Path) -> tuple[h5py.File, Path | None]:
    """Read-only view of a file left open by a killed writer: (file, temporary copy or None)."""
    try:
        return h5py.File(path, "r", swmr=True), None
    except OSError:
        tmp = cleared_copy(path)
        return h5py.File(tmp, "r"), tmp


def repair(path: Path, opener=None) -> None:
    """Rewrite a file left open by a killed writer into a clean copy (``.RUN.h5.XXXXXXXX.repair``,
    renamed over the run once complete; removed on failure), its bytes reserved first
    (``space.reserved``). ``opener(path) -> h5py.File`` reads the flagged file (default
    ``open_flagged``); the caller holds the writer lock."""
    unlocked = tmp = None
    if opener is None:
        src, unlocked = open_flagged(path)
    else:
        src = opener(path)
    try:
        tmp = temp_beside(path, ".repair")
        dst = h5py.File(tmp, "w", libver="latest", locking=False)
        try:
            with reserved(dst, 2 * path.stat().st_size, path, "repairing the run file", trim=False):
                copy_attrs(src, dst)
                for name in src:
                    src.copy(src[name], dst, name)
                dst.flush()
                dst.close()
        except BaseException as e:
            if is_write_failure(e):
                poison(dst)
            elif dst.id.valid:
                try:
                    dst.close()
                except Exception:  # noqa: BLE001 - the copy is discarded anyway
                    poison(dst)
            raise
        trim_file(tmp)
        shutil.copymode(path, tmp)               # the run keeps its permissions (mkstemp: 0600)
        os.replace(tmp, path)
    finally:
        view = getattr(src, "_labid_view", None)
        src.close()
        if view is not None:
            view.close()
        if unlocked:
            unlocked.unlink()
        if tmp is not None:
            tmp.unlink(missing_ok=True)
