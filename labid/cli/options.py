"""What every ``labid`` command shares: the ``--json`` option and writing its result, and
the checks of output paths made before any computing (``check_output_file``,
``check_output_dir``: a typo costs one line, never a fit or a stored result).

Imported by ``labid.cli.main`` and by each ``labid/cli/<name>.py``; it imports neither
(no command module imports the CLI back) and no numerical library, so that
``labid --help`` stays fast.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from ..base import atomic
from ..base.errors import UserError
from ..base.jsonio import to_jsonable


def add_json_option(p: argparse.ArgumentParser) -> None:
    """Add ``--json PATH`` ('-' for standard output) to a command's parser."""
    p.add_argument("--json", metavar="PATH", help="write the machine-readable result ('-' for stdout)")


def write_json(result: dict, path: str) -> None:
    """Write a result as JSON to ``path`` (atomically: ``labid.base.atomic``); '-' is standard
    output. NaN -> null."""
    text = json.dumps(to_jsonable(result), indent=2, allow_nan=False)
    if path == "-":
        sys.stdout.write(text + "\n")
    else:
        atomic.write_text(Path(path), text + "\n", key="--json")


def check_output_file(path: str | None, key: str) -> None:
    """UserError naming ``key`` unless ``path`` (None or '-': nothing to check) can be written:
    not a folder, in an existing folder this process may write in."""
    if path is None or path == "-":
        return
    p = Path(path)
    if p.is_dir():
        raise UserError("is a folder; expected a file to write", file=str(p), key=key)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise UserError(f"folder {str(parent)!r} does not exist; expected a file in an existing folder",
                        file=str(p), key=key)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"folder {str(parent)!r} is not writable", file=str(p), key=key)


def check_output_dir(path: str | None, key: str) -> None:
    """UserError naming ``key`` unless ``path`` (None: nothing to check) is a writable folder,
    or can be created as one (its nearest existing ancestor is a writable folder)."""
    if path is None:
        return
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise UserError("exists and is not a folder; expected a folder for the tables", file=str(p), key=key)
        if not os.access(p, os.W_OK | os.X_OK):
            raise UserError("folder is not writable", file=str(p), key=key)
        return
    a = p.absolute().parent
    while not a.exists():
        a = a.parent
    if not a.is_dir():
        raise UserError(f"{str(a)!r} is a file; expected a folder for the tables", file=str(p), key=key)
    if not os.access(a, os.W_OK | os.X_OK):
        raise UserError(f"cannot create the folder: {str(a)!r} is not writable", file=str(p), key=key)
