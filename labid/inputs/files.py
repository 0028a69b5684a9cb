"""Reading the small text files a user names (specimen, rig, features): only regular
files, at most ``MAX_BYTES``, UTF-8; every refusal one ``UserError`` naming the file and
never echoing its content (``/dev/zero`` read to the end exhausted the memory).

``parse_json`` and ``parse_toml`` bound what a document may hold (issue 27: a document
nested thousands deep ended in RecursionError, exit 1): at most ``MAX_DEPTH`` levels of
tables and lists, strings and keys of at most ``MAX_STRING`` characters.
"""
from __future__ import annotations

import json
import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from ..base.errors import UserError

#: the largest specimen, rig or features file read, bytes
MAX_BYTES = 16 << 20
#: the deepest nesting of tables/objects and lists in a specimen, rig or features document
MAX_DEPTH = 32
#: the longest string (or key) in such a document, characters
MAX_STRING = 4096


def check_document(doc: Any, src: str) -> Any:
    """``doc`` (parsed JSON or TOML) when no table or list in it is nested deeper than
    ``MAX_DEPTH`` and no string or key is longer than ``MAX_STRING``; else UserError
    naming ``src`` and where (walked without recursion)."""
    stack = [(doc, 0, "")]
    while stack:
        v, depth, where = stack.pop()
        if isinstance(v, str):
            if len(v) > MAX_STRING:
                raise UserError(f"a string of {len(v)} characters; expected at most {MAX_STRING}",
                                file=src, key=where or None)
            continue
        if not isinstance(v, (dict, list)):
            continue
        if depth >= MAX_DEPTH:
            raise UserError(f"nested more than {MAX_DEPTH} levels deep; expected a flatter document",
                            file=src, key=where or None)
        items = v.items() if isinstance(v, dict) else enumerate(v)
        for k, x in items:
            if isinstance(k, str) and len(k) > MAX_STRING:
                raise UserError(f"a key of {len(k)} characters; expected at most {MAX_STRING}", file=src,
                                key=where or None)
            stack.append((x, depth + 1, f"{where}.{k}" if isinstance(k, str) and where else
                          (k if isinstance(k, str) else f"{where}[{k}]")))
    return doc


def parse_json(text: str, src: str) -> Any:
    """The JSON document ``text`` (bounded: ``check_document``); invalid JSON is one
    ``UserError`` naming ``src``, the line and the column."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise UserError(f"not valid JSON ({e.msg} at line {e.lineno}, column {e.colno})", file=src) from None
    except RecursionError:
        raise UserError(f"nested more than {MAX_DEPTH} levels deep; expected a flatter document",
                        file=src) from None
    return check_document(doc, src)


def parse_toml(text: str, src: str, expected: str) -> dict:
    """The TOML document ``text`` (bounded: ``check_document``); invalid TOML is one
    ``UserError`` naming ``src`` and saying what was ``expected``."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise UserError(f"malformed TOML ({e}); expected {expected}", file=src) from None
    except RecursionError:
        raise UserError(f"nested more than {MAX_DEPTH} levels deep; expected {expected}", file=src) from None
    return check_document(doc, src)


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
    return parse_json(read_text_file(path, what), str(path))
