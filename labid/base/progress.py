"""Progress on stderr for long work, silent under ``--quiet``.

One seam for every command and service: ``progress.bar(total, desc)`` is a
``tqdm`` bar on stderr (the field's library; nothing hand-written), or a no-op
object with the same ``update``/``close``/context-manager surface when quiet or
when stderr is not a terminal and ``LABID_PROGRESS`` is not set to 1. The summary
a command prints on stdout is never affected. ``watch_fit(blocks, desc)``: a fit's model
evaluations and chi^2 on a bar; ``counter(n, desc)``: k of n starts finished.
"""
from __future__ import annotations

import os
import sys
from dataclasses import replace
from typing import Any

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


def watch_fit(blocks: list, desc: str) -> tuple[list, Any]:
    """The data blocks of a fit (``engine.fit.DataBlock``-like: ``observed``, ``sigma``,
    ``predict``, ``jacobian``), wrapped so that each model evaluation advances a bar on
    stderr showing the evaluations and chi^2 = sum ((predicted - observed) / sigma)^2 of the
    last evaluation of every block; and the bar (close it when the fit ends). Unpaired
    predictions (NaN) are left out of chi^2. Without progress the blocks are returned as
    they are."""
    b = bar(None, desc, unit="eval")
    if isinstance(b, _Null):
        return list(blocks), b
    import numpy as np     # here: labid --help imports this module and must not pay numpy's import
    last: dict[int, float] = {}

    def wrap(i: int, block, fn, returns_pair: bool):
        if fn is None:
            return None

        def inner(*a, **kw):
            out = fn(*a, **kw)
            pred = out[0] if returns_pair else out
            r = (np.asarray(pred, float) - np.asarray(block.observed, float)) / np.asarray(block.sigma, float)
            last[i] = float(np.nansum(r * r))
            b.update(1)
            b.set_postfix_str(f"chi^2 {sum(last.values()):.4g}")
            return out
        return inner

    return [replace(blk, predict=wrap(i, blk, blk.predict, False), jacobian=wrap(i, blk, blk.jacobian, True))
            for i, blk in enumerate(blocks)], b


def counter(total: int, desc: str, unit: str = "start"):
    """``done(k, n)`` for work reported as k of n finished (multi-start, cluster starts): a
    bar on stderr, and the bar (close it at the end)."""
    b = bar(total, desc, unit=unit)
    seen = {"k": 0}

    def done(k: int, n: int) -> None:
        b.update(max(k - seen["k"], 0))
        seen["k"] = k
    return done, b
