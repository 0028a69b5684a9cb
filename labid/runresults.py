"""Results in the run file, kept: the part of the ``labid.services`` facade that stores and
reads ``/results/<name>`` (front-ends import these names from ``labid.services``).

A new identification or diagnosis (``KEPT``) never replaces an older one silently: the older
one moves to ``/results/history/<name>/<number>`` and the new one, numbered
(``stored``: number, time, writer), takes ``/results/<name>``, where every reader (the
panel, the report, ``labid export``, scripts) finds the newest. ``replace=True``
(``--replace``) overwrites it instead, and says so. Other results (analysis, the panel's
session) are overwritten. Schema: ``labid/store/runstore.py``'s docstring and docs/formats.md.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Mapping

from .base.errors import UserError

__all__ = ["KEPT", "HISTORY_GROUP", "kept", "read_result", "store_result", "result_history", "store_for_features"]

#: results a new one never replaces silently: the older one moves to /results/history/<name>/<n>
KEPT = ("identification", "diagnosis")
HISTORY_GROUP = "history"


def read_result(run: str | Path, name: str, number: int | None = None) -> Any:
    """The result ``/results/<name>`` of ``run`` (its JSON copy preferred; the newest of a kept
    result), or with ``number`` that kept result of this number (``result_history``); None
    if absent."""
    from .store import RunStore  # here: h5py, not needed when no run is at hand
    with RunStore(run, "r") as st:
        try:
            res = st.read_result(name)
        except KeyError:
            res = None
        if number is None or (_number_of(res) == number):
            return res
        try:
            return st.read_result(f"{HISTORY_GROUP}/{name}/{int(number)}")
        except KeyError:
            return None


def kept(name: str) -> bool:
    """True for the results a new one never replaces silently (``KEPT``: identifications, diagnoses)."""
    return name.startswith(KEPT)


def _number_of(res: Any) -> int | None:
    n = (res.get("stored") or {}).get("number") if isinstance(res, Mapping) else None
    return int(n) if isinstance(n, (int, float)) else None


def store_result(run: str | Path, name: str, data: Mapping, *, replace: bool = False, by: str = "labid") -> str:
    """Write ``data`` under ``/results/<name>`` of ``run`` (structured + a JSON copy); returns
    where it went ('/results/<name>', with its number when kept).

    A kept result (``KEPT``) is numbered (``stored``: number, time, ``by``) and the one it
    follows is moved to ``/results/history/<name>/<number>``, unless ``replace`` (then it is
    overwritten, and the returned text says so). Other results are overwritten."""
    from .store import RunStore  # here: h5py, not needed when no run is at hand
    data = dict(data)
    with RunStore(run, "a") as st:
        if not kept(name):
            st.write_result(name, data)
            return f"/results/{name}"
        # the numbers from group names and one integer, never the kept trees (issue 29, s27)
        present, n_old, numbers = st.kept_numbers(name, f"{HISTORY_GROUP}/{name}")
        if present and n_old is None:              # a JSON-only result, or one stored before numbering
            n_old = _number_of(st.read_result(name))
        if present and n_old is None:
            n_old = max(numbers, default=0) + 1    # a result stored before numbering
        n = max(numbers + [n_old or 0]) + (0 if replace and present else 1)
        moved = f"{HISTORY_GROUP}/{name}/{n_old}" if present and not replace else None
        data["stored"] = {"number": n, "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "by": by}
        st.write_result(name, data, keep_as=moved)    # the older one moved aside in the same copy
    if replace and present:
        return f"/results/{name}, no. {n}: replaced the one stored before (--replace)"
    return f"/results/{name}, no. {n}" + (f"; no. {n_old} kept at /results/{moved}" if moved else "")


def result_history(run: str | Path, name: str) -> list[dict]:
    """The kept results ``name`` of ``run``, oldest first: ``{number, time, by, path}`` each
    (the newest at ``/results/<name>``, the others under ``/results/history/<name>``)."""
    from .store import RunStore  # here: h5py, not needed when no run is at hand
    with RunStore(run, "r") as st:          # the "stored" metadata alone, never the kept trees
        present, _, numbers = st.kept_numbers(name, f"{HISTORY_GROUP}/{name}")
        paths = [f"{HISTORY_GROUP}/{name}/{k}" for k in sorted(numbers)] + ([name] if present else [])
        meta = st.read_stored(paths)
    out = [{"number": k, "time": meta[p].get("time"), "by": meta[p].get("by"), "path": f"/results/{p}"}
           for k, p in zip(sorted(numbers), paths)]
    if present:
        m = meta[name]
        out.append({"number": m.get("number", len(out) + 1), "time": m.get("time"), "by": m.get("by"),
                    "path": f"/results/{name}"})
    return sorted(out, key=lambda r: r["number"])


def store_for_features(features_file: str | Path, name: str, result: Mapping, *, replace: bool = False,
                       by: str = "labid") -> str | None:
    """Store a result computed from a features file (``labid identify``, ``labid diagnose``)
    under ``/results/<name>`` of the run the features came from, where the panel and the
    report find it (:func:`store_result`: the older one kept unless ``replace``). Returns a
    one-line note for the user (where it went, or why not: the result itself is never lost
    to it), None when the features came from no run."""
    from .inference import run_of_features  # here: reading a run's results needs no identification
    run = run_of_features(features_file)
    if run is None:
        return None
    try:
        where = store_result(run, name, result, replace=replace, by=by)
    except (UserError, OSError) as e:
        return f"warning: result not stored in the run file: {e}"
    return f"result stored in {run} ({where})"
