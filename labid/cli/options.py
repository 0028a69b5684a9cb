"""What every ``labid`` command shares: the ``--json`` option and writing its result.

Imported by ``labid.cli.main`` and by each ``labid/cli/<name>.py``; it imports neither
(no command module imports the CLI back) and no numerical library, so that
``labid --help`` stays fast.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..base import atomic
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
