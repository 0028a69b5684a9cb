"""The ``/results`` groups of a run file: the part of ``RunStore`` that writes and reads them
(schema: ``labid.store.runstore``'s docstring). A result is written into a synced copy of
the run renamed over it (``tree.replace_group``); a kept result's predecessor is moved
aside in the same copy (``keep_as``), and its number is learnt from names and one integer,
never by reading whole trees (issue 29, session 27: storing an identification read every
kept one and copied the file twice, so its cost grew with each result kept).
"""
from __future__ import annotations

import json
from typing import Any

import h5py
import numpy as np

from ..base.jsonio import to_jsonable
from .inprocess import changing
from .lock import relock
from .probe import carry, in_child
from .schema import check_result
from .tree import decode_result, not_written, read_json_copy, read_tree, replace_group


class Results:
    """``/results`` of an open ``RunStore`` (mixed into it: uses its file, path and contexts)."""

    def result_names(self) -> list[str]:
        """Names of the groups under ``/results`` (``write_group``/``write_result``)."""
        with self._reading():
            return list(self._f["results"]) if "results" in self._f else []

    def kept_numbers(self, path: str, history: str) -> tuple[bool, int | None, list[int]]:
        """For the result ``/results/<path>``: (present; its ``stored/number`` as its
        structured twin holds it, None when it holds none; the numbers named under
        ``/results/<history>``). Reads link names and one integer dataset (no string, no
        tree): its cost does not grow with the results kept."""
        with self._reading():
            g = self._f.get(f"results/{path.strip('/')}")
            h = self._f.get(f"results/{history.strip('/')}")
            numbers = [int(k) for k in h if k.isdigit()] if isinstance(h, h5py.Group) else []
            if not isinstance(g, h5py.Group):
                return False, None, numbers
            n = g.get("stored/number")
            ok = isinstance(n, h5py.Dataset) and n.shape == () and n.dtype.kind in "iuf"
            x = n[()] if ok else None
            return True, (int(x) if x is not None and np.isfinite(x) else None), numbers

    def write_group(self, path: str, data: dict, keep_as: str | None = None) -> None:
        """Write a nested dict (arrays, scalars, strings, dicts) under ``/results/<path>``,
        replacing any previous content of that group; ``keep_as``: that previous content
        is moved to ``/results/<keep_as>`` instead (no read, no second copy of the run).

        Crash-safe: written into a copy of the run (``.RUN.h5.XXXXXXXX.results``), synced,
        then renamed over it; a kill at any moment leaves the earlier results intact.
        ``UserError`` naming the file when the disk is full or read-only, or the run is
        damaged (the run file is unchanged)."""
        full = f"results/{path.strip('/')}"
        moved = f"results/{keep_as.strip('/')}" if keep_as else None
        with changing(self.path):    # no reader of another thread opens it closed (store.inprocess)
            with self._writing("closing the run before storing a result"):
                self._normal()
                self._handles = (None,)
                self._f.flush()
                self._f.close()
            self._f = None
            try:
                replace_group(self.path, full, data, moved)
            finally:
                relock(self.path)
                self._f = h5py.File(self.path, "a", libver="latest", locking=False)
            self._seen = carry(self._seen, self.path, (full, f"{full}#json"), moved)

    def write_result(self, path: str, data: dict, keep_as: str | None = None) -> None:
        """Write a result (nested dict) under ``/results/<path>`` twice over: its arrays and
        scalars where HDF5 can hold them, and a plain-JSON copy in ``json`` (which
        readers prefer); only the JSON copy when the structure does not fit HDF5.
        ``keep_as``: as ``write_group``'s (the result there before moved aside)."""
        text = json.dumps(to_jsonable(data), allow_nan=False)
        try:
            self.write_group(path, {**data, "json": text}, keep_as)
        except (ValueError, TypeError):
            try:
                self.write_group(path, {"json": text}, keep_as)
            except (ValueError, TypeError) as e:     # even one string does not go in: damaged
                raise not_written(self.path, e) from None

    def read_group(self, path: str) -> dict:
        """The nested dict written by ``write_group`` (arrays as numpy, strings as str)."""
        full = f"results/{path.strip('/')}"

        def read():
            with self._reading():
                return read_tree(self._f[full]) if full in self._f else None
        tree = in_child(self.path, full, read)    # a group the library would loop on: refused (store.probe)
        if tree is None:
            raise KeyError(f"no results group {path!r} in {self.path}")
        check_result(path.strip("/"), decode_result(tree), str(self.path))
        return tree

    def read_stored(self, paths: list[str]) -> dict[str, dict]:
        """``{path: its "stored" dict}`` of the results ``/results/<path>`` (kept results:
        number, time, by), read from their structured twins alone (in a child the first
        time, as ``read_group``); a result whose twin holds none: from its JSON copy ({}
        when that has none either, or the result is absent)."""
        keys = [p.strip("/") for p in paths]

        def read():
            with self._reading():
                g = [self._f.get(f"results/{k}/stored") for k in keys]
                return {k: read_tree(x) if isinstance(x, h5py.Group) else None for k, x in zip(keys, g)}
        out = in_child(self.path, "results#stored:" + ",".join(keys), read)
        for k, meta in out.items():
            if meta is None:
                try:
                    got = self.read_result(k)
                except KeyError:
                    got = None
                out[k] = (got.get("stored") or {}) if isinstance(got, dict) else {}
        return out

    def read_result(self, path: str) -> Any:
        """``/results/<path>``: its JSON copy when it has one (read alone, in a child the first
        time as ``read_group``), else ``read_group``'s; checked against the shape labid writes."""
        key = path.strip("/")

        def read():
            with self._reading():
                return read_json_copy(self._f.get(f"results/{key}"))
        got = in_child(self.path, f"results/{key}#json", read)
        if got is None:
            return decode_result(self.read_group(path))
        check_result(key, got, str(self.path))
        return got
