"""What every ``labid`` command shares: the ``--json`` option and writing its result, and
the checks of output paths made before any computing (``check_output_file``,
``check_output_dir``: a typo costs one line, never a fit or a stored result), and
the bounds of the counts and sizes a user gives (issue 27: ``--workers 1000000`` forked
hundreds of processes, ``--starts``, ``--mcmc``, ``--wavelet`` allocated without limit).

Imported by ``labid.cli.main`` and by each ``labid/cli/<name>.py``; it imports neither
(no command module imports the CLI back) and no numerical library, so that
``labid --help`` stays fast.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Callable

from ..base import atomic
from ..base.errors import UserError, clip
from ..base.jsonio import to_jsonable

#: the largest counts the commands accept (each enters before any allocation or fork)
MAX_STARTS = 10_000            # identify --starts: ~100 CPU-hours at 36 s a start
MAX_MCMC_STEPS = 100_000       # identify --mcmc: steps per walker (~0.2 GB of samples)
MAX_SHOTS = 10_000             # acquire/demo --hits, --waves
MAX_MODES = 1_000              # modes --n
MAX_FREQUENCIES = 100_000      # dispersion --n
MAX_WAVELET = 100.0            # analyze --wavelet B,C (each <= 20): bandwidth x centre of the Morlet (the
                               # CWT's memory grows with it: 0.28 GB at 2,5, 0.73 GB at 10,10, 1.8 GB
                               # at 20,20, 18 GB and 630 s at 100,100; bench/RESULTS.md issue 27)
MAX_SEED = 2 ** 32 - 1


def cpu_count() -> int:
    """The CPUs this process may run on (its affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def bounded(kind: type = int, lo: float | None = None, hi: float | Callable[[], float] | None = None,
            what: str = "a number") -> Callable[[str], float]:
    """An argparse ``type``: ``kind(text)`` within [``lo``, ``hi``] (``hi`` may be a function,
    e.g. ``cpu_count``), finite; otherwise one line naming the value (at most 80
    characters of it) and the bounds. Checked when the option is read: before any
    allocation or fork."""
    def parse(text: str):
        try:
            v = kind(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"value {clip(repr(text))}: expected {what}") from None
        top = hi() if callable(hi) else hi
        if isinstance(v, float) and not math.isfinite(v) or (lo is not None and v < lo) or (
                top is not None and v > top):
            show = (lambda x: str(int(x))) if kind is int else (lambda x: f"{x:g}")
            rng = (f"from {show(lo)} to {show(top)}" if lo is not None and top is not None else
                   f"at least {show(lo)}" if lo is not None else f"at most {show(top)}")
            raise argparse.ArgumentTypeError(f"value {clip(repr(text))}: expected {what} {rng}")
        return v
    parse.__name__ = what          # argparse names the type in its own messages
    return parse


def count(hi: int | Callable[[], int], what: str, lo: int = 0) -> Callable[[str], int]:
    """``bounded(int, lo, hi, what)``: a count of things."""
    return bounded(int, lo, hi, what)


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
