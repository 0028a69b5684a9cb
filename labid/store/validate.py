"""Structural checks of a run file before anything reads it (issue 15: damaged files are
one line, exit 2, never a traceback): groups present, shot tables consistent, the
attributes the reader trusts (``rate_hz``, ``samples``, ``channels``...) parseable and
physical."""
from __future__ import annotations

import json
import math
from dataclasses import fields
from pathlib import Path

import h5py

from drivers.protocol import ChannelConfig

from ..base.errors import UserError

_CHANNEL_FIELDS = {f.name for f in fields(ChannelConfig)}
#: the tables of a shot kind besides its channels (rig channels may not take these names)
TABLES = ("timestamp", "overload", "backend", "software_version", "meta", "committed")


def damaged(path: str | Path, e: BaseException) -> UserError:
    """The one-line error for a run file the HDF5 library (or our checks) cannot read."""
    reason = str(e).splitlines()[0][:160] if str(e) else type(e).__name__
    return UserError(f"damaged or not a labid run file ({type(e).__name__}: {reason}); "
                     "expected an HDF5 run file written by labid", file=str(path))


def _bad(src: str, key: str, what: str) -> UserError:
    return UserError(f"damaged run file: {what}", file=src, key=key)


def check_run(f: h5py.File, src: str) -> None:
    """UserError naming the file and the object when ``f`` is not a sound run file."""
    for name in ("config", "shots"):
        if name not in f or not isinstance(f[name], h5py.Group):
            raise _bad(src, f"/{name}", "group missing; expected a labid run file")
    for kind, g in f["shots"].items():
        key = f"/shots/{kind}"
        if not isinstance(g, h5py.Group):
            raise _bad(src, key, "not a group")
        a = g.attrs
        attr = "rate_hz"
        try:                       # ``attr`` names the attribute that failed in the one line
            rate = float(a[attr])
            attr = "samples"
            samples = int(a[attr])
            attr = "pretrigger"
            pre = int(a[attr])
            attr = "channels"
            chans = json.loads(a[attr])
            attr = "trigger"
            json.loads(a[attr])
        except (KeyError, TypeError, ValueError, OSError) as e:
            raise _bad(src, f"{key}.{attr}", f"attribute unreadable ({type(e).__name__}: {str(e)[:80]})") from None
        if not (math.isfinite(rate) and rate > 0):
            raise _bad(src, key + ".rate_hz", f"value {rate!r}; expected a positive sample rate in Hz")
        if not 0 < samples <= 1 << 31 or not 0 <= pre <= 1 << 31:
            raise _bad(src, key + ".samples", f"samples {samples}, pretrigger {pre}; "
                                               "expected samples > 0 and pretrigger >= 0")
        if not isinstance(chans, list) or not chans or not all(
                isinstance(c, dict) and isinstance(c.get("name"), str) and set(c) <= _CHANNEL_FIELDS
                for c in chans):
            raise _bad(src, key + ".channels", "expected a JSON list of channel objects")
        for t in TABLES:
            if t not in g or not isinstance(g[t], h5py.Dataset):
                raise _bad(src, f"{key}/{t}", "table missing")
        n = g["committed"].shape[0] if g["committed"].shape else -1
        if n < 0:
            raise _bad(src, f"{key}/committed", "not a table")
        for c in chans:
            name = c["name"]
            ds = g.get(name)
            if not isinstance(ds, h5py.Dataset) or ds.ndim != 2 or ds.shape[1] != samples:
                raise _bad(src, f"{key}/{name}", f"expected a table of rows of {samples} samples")
        for t in (*TABLES, *(c["name"] for c in chans)):
            if g[t].shape[0] < n:
                raise _bad(src, f"{key}/{t}", f"{g[t].shape[0]} rows, fewer than the {n} committed shots")


class _Reading:
    """HDF5/JSON errors while reading a damaged file -> ``UserError`` naming the file."""

    def __init__(self, path: Path):
        self.path = path

    def __enter__(self) -> None:
        return None

    def __exit__(self, tp, e, tb) -> bool:
        if e is not None and isinstance(e, (OSError, KeyError, ValueError, TypeError, IndexError, AttributeError,
                                            UnicodeDecodeError, RuntimeError)):
            raise damaged(self.path, e) from None
        return False


def reading(path: Path) -> _Reading:
    """Context: HDF5/JSON errors while reading a damaged file -> ``UserError`` naming it."""
    return _Reading(path)
