"""Progress on stderr for long work, silent under ``--quiet``.

One seam for every command and service: ``progress.bar(total, desc)`` is a
``tqdm`` bar on stderr (the field's library; nothing hand-written), or a no-op
object with the same ``update``/``close``/context-manager surface when quiet or
when stderr is not a terminal and ``LABID_PROGRESS`` is not set to 1. The summary
a command prints on stdout is never affected.
"""
from __future__ import annotations

import os
import sys

_QUIET = False


def set_quiet(quiet: bool) -> None:
    """Silence (True) or allow (False) progress for this process."""
    global _QUIET
    _QUIET = bool(quiet)


def enabled() -> bool:
    """True when progress is shown: not quiet, and stderr is a terminal or LABID_PROGRESS=1."""
    if _QUIET or os.environ.get("LABID_PROGRESS") == "0":
        return False
    if os.environ.get("LABID_PROGRESS") == "1":
        return True
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


class _Null:
    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, s: str) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass


def bar(total: int | None, desc: str, unit: str = "it"):
    """A progress bar on stderr for ``total`` steps (None: unknown), or a silent stand-in."""
    if not enabled():
        return _Null()
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                dynamic_ncols=True, mininterval=0.5)


def note(line: str) -> None:
    """One status line on stderr (e.g. 'fitting start 3/8'), unless quiet."""
    if not _QUIET:
        sys.stderr.write(line.rstrip("\n") + "\n")
        sys.stderr.flush()
