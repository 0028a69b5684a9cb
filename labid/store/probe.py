"""A damaged run file that would make the HDF5 library loop forever is refused in one line
(issue 27: reading a string of a run whose global heap was damaged by bit flips spun in the
library's C code, out of reach of any Python signal handler; 1 of 28 files with 60 random
byte flips did).

The first read of a run's metadata is done in a forked child whose CPU time is bounded
(``RLIMIT_CPU``: a bound on work, not on the wall clock): ``probe(path)`` opens the file and
reads what every reader reads first (the root and shot-table attributes, the configuration),
and ``in_child(key, fn)`` runs a read (``RunStore.read_group``) there once per file version
and hands its value back. A child stopped by the bound means the library would not return:
``UserError``. Any other failure lets the caller read in-process, where its own checks say
what is wrong in one line. Each file version (device, inode, size, modification time) is
probed once, each group read in a child once; later reads are in-process. A file this
process wrote itself under the writer's lock (``carry``, at each result written and at
close) keeps what was probed of the version it changed, and the groups it wrote count as
read: it is not probed again (issue 29, session 27: ``labid identify`` forked a probe for
each version of the run it had just written). Where ``fork`` is missing, nothing is probed.

Cost (bench/RESULTS.md, issue 27): a fork of ~10 ms per file version and per results group.
"""
from __future__ import annotations

import os
import pickle
import resource
import signal
from pathlib import Path
from typing import Any, Callable

import h5py
from h5py._objects import phil   # h5py's global lock: held across fork, so no thread is mid-call

from ..base.errors import UserError

#: CPU seconds a child may spend reading; a sound run's metadata takes well under one
#: ($LABID_PROBE_CPU_S sets another bound, e.g. for a test of a looping file)
PROBE_CPU_S = max(1, int(float(os.environ.get("LABID_PROBE_CPU_S", "10"))))
_done: set[tuple] = set()


def identity(path: str | Path) -> tuple | None:
    """(real path, device, inode, size, modification time) of ``path``; None if absent."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (os.path.realpath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def _looping(path: Path) -> UserError:
    return UserError(f"damaged run file: reading its metadata did not end within {PROBE_CPU_S} s of CPU "
                     "(the HDF5 library loops on it); expected an HDF5 run file written by labid", file=str(path))


def _fork(fn: Callable[[], Any]) -> tuple[str, Any]:
    """``fn()`` in a forked child with bounded CPU: ('ok', value), ('error', exception) or
    ('loop', None) when the bound stopped it."""
    r, w = os.pipe()
    with phil:
        pid = os.fork()
    if pid == 0:                                # the child: read, send, end without any cleanup
        os.close(r)
        try:
            resource.setrlimit(resource.RLIMIT_CPU, (PROBE_CPU_S, PROBE_CPU_S + 2))
            signal.signal(signal.SIGXCPU, signal.SIG_DFL)
            try:
                out = ("ok", fn())
            except BaseException as e:  # noqa: BLE001 - handed to the parent
                out = ("error", e)
            try:
                data = pickle.dumps(out)
            except Exception:  # noqa: BLE001 - an exception that does not pickle
                data = pickle.dumps(("error", RuntimeError(str(out[1])[:300])))
            view = memoryview(data)
            while view:
                view = view[os.write(w, view):]
        finally:
            os._exit(0)
    os.close(w)
    chunks = []
    with os.fdopen(r, "rb") as fh:
        while chunk := fh.read(1 << 20):
            chunks.append(chunk)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGXCPU, signal.SIGKILL):
        return "loop", None
    try:
        return pickle.loads(b"".join(chunks))
    except Exception as e:  # noqa: BLE001 - a child that died otherwise: read in-process
        return "error", e


def _read_metadata(path: Path) -> None:
    """What readers read first: the root, shot-table and configuration attributes and texts."""
    from .readonly import open_read_only  # noqa: PLC0415 - readonly imports nothing of this module

    f = open_read_only(path)

    def visit(name, obj):
        for k in obj.attrs:
            obj.attrs[k]
        if isinstance(obj, h5py.Dataset) and (obj.dtype.kind == "O" or h5py.check_string_dtype(obj.dtype)):
            obj[()]

    for k in f.attrs:
        f.attrs[k]
    for name in ("shots", "config", "results"):
        g = f.get(name)
        if isinstance(g, h5py.Group):
            for k in g.attrs:
                g.attrs[k]
            if name == "config":
                g.visititems(visit)
            elif name == "shots":
                for t in g.values():
                    if isinstance(t, h5py.Group):
                        for k in t.attrs:
                            t.attrs[k]


def probe(path: str | Path) -> None:
    """UserError naming ``path`` when opening it and reading its first metadata does not
    end within ``PROBE_CPU_S`` s of CPU (module docstring)."""
    path = Path(path)
    key = identity(path)
    if key is None or key in _done or not hasattr(os, "fork"):
        return
    if _fork(lambda: _read_metadata(path))[0] == "loop":
        raise _looping(path)
    _done.add(key)


def carry(old: tuple | None, path: str | Path, written: tuple[str, ...] = (), moved: str | None = None) -> tuple | None:
    """``path`` was changed by this process, holding the writer's lock, since it was at
    identity ``old`` (None: this process created it): what was probed of that version
    counts for the new one, except the group ``moved`` to (its ancestors and descendants:
    they now hold a group that may never have been read), and the groups ``written`` (keys
    as ``in_child``'s ``what``) count as read. Returns the new identity."""
    new = identity(path)
    if new is None or not hasattr(os, "fork"):
        return new
    n = len(new)
    if old is None:
        _done.add(new)
    elif new != old:
        def fresh(what: str) -> bool:
            w = what.split("#")[0]
            return moved is not None and (moved.startswith(w + "/") or w == moved or w.startswith(moved + "/"))
        _done.update((*new, *k[n:]) for k in list(_done) if k[:n] == old and not (len(k) > n and fresh(k[n])))
    _done.update((*new, w) for w in written)
    return new


def in_child(path: str | Path, what: str, fn: Callable[[], Any]) -> Any:
    """``fn()`` (a read of ``what`` in the open run ``path``), the first time for this file
    version in a forked child with bounded CPU, its value handed back; later in-process.
    UserError when the child's read does not end; other errors are those of an in-process
    read."""
    key = identity(path)
    if key is None or not hasattr(os, "fork"):
        return fn()
    key = (*key, what)
    if key in _done:
        return fn()
    kind, value = _fork(fn)
    if kind == "loop":
        raise _looping(Path(path))
    if kind == "error":
        return fn()                             # the same error, raised in-process with its context
    _done.add(key)
    return value
