"""Reading the small text files a user names (specimen, rig, features): only regular
files, at most ``MAX_BYTES``, UTF-8; every refusal one ``UserError`` naming the file and
never echoing its content (``/dev/zero`` read to the end exhausted the memory)."""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

from ..base.errors import UserError

#: the largest specimen, rig or features file read, bytes
MAX_BYTES = 16 << 20


def read_text_file(path: str | Path, what: str, max_bytes: int = MAX_BYTES) -> str:
    """The UTF-8 text of the regular file ``path``; ``what`` names the expected file."""
    p = str(path)
    if "\0" in p:
        raise UserError(f"path holds a NUL byte; expected {what}", file=p.replace("\0", "\\0"))
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise UserError(f"file not found; expected {what}", file=p) from None
    except OSError as e:
        raise UserError(f"cannot read: {e.strerror}; expected {what}", file=p) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UserError(f"not a regular file; expected {what}", file=p)
        if st.st_size > max_bytes:
            raise UserError(f"{st.st_size} bytes: expected {what} of at most {max_bytes}", file=p)
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(max_bytes + 1)
    except OSError as e:
        raise UserError(f"cannot read: {e.strerror}; expected {what}", file=p) from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise UserError(f"more than {max_bytes} bytes: expected {what}", file=p)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise UserError(f"not UTF-8 text (byte {e.start}); expected {what}", file=p) from None


def read_json_file(path: str | Path, what: str) -> Any:
    """The parsed JSON of ``path`` (``read_text_file``); invalid JSON is one ``UserError``
    naming the file, line and column."""
    text = read_text_file(path, what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise UserError(f"not valid JSON ({e.msg} at line {e.lineno}, column {e.colno})", file=str(path)) from None
