"""Atomic file outputs (issue 15): a file is written under a temporary name beside it,
synced, then renamed over the target (``os.replace``), so that a reader or a kill
never meets a half-written JSON, HTML or PNG file.

``write_text(path, text)``, ``write_bytes(path, data)``, and ``replacing(path)``: a
context manager yielding the temporary path for writers that want a file name
(``fig.savefig(tmp)``). A failure to write is a ``UserError`` naming the file and
the reason (disk full, read-only directory...); the target is left as it was.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

from .errors import UserError


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def _fail(path: Path, e: OSError, key: str | None) -> UserError:
    return UserError(f"cannot write ({e.strerror or e}); the file is left as it was", file=str(path), key=key)


@contextlib.contextmanager
def replacing(path: str | Path, key: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path`` atomically."""
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except OSError as e:
        if e.errno is None:
            raise
        raise _fail(path, e, key) from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()


def write_bytes(path: str | Path, data: bytes, key: str | None = None) -> None:
    """Write ``data`` to ``path`` atomically."""
    with replacing(path, key) as tmp:
        with open(tmp, "wb") as fh:
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
