"""What every ``labid`` command shares: the ``--json`` option and writing its result.

Imported by ``labid.cli`` and by each ``labid/cmd_<name>.py``; it imports neither
(no command module imports the CLI back) and no numerical library, so that
``labid --help`` stays fast.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .errors import UserError
from .jsonio import to_jsonable


def add_json_option(p: argparse.ArgumentParser) -> None:
    """Add ``--json PATH`` ('-' for standard output) to a command's parser."""
    p.add_argument("--json", metavar="PATH", help="write the machine-readable result ('-' for stdout)")


def write_json(result: dict, path: str) -> None:
    """Write a result as JSON to ``path``; '-' is standard output. NaN -> null."""
    text = json.dumps(to_jsonable(result), indent=2, allow_nan=False)
    if path == "-":
        sys.stdout.write(text + "\n")
    else:
        try:
            Path(path).write_text(text + "\n")
        except OSError as e:
            raise UserError(f"cannot write: {e.strerror}", file=path, key="--json") from None
