"""Nested dicts <-> HDF5 groups (the ``/results`` and ``/config`` trees of a run file)."""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..base.atomic import fsync_dir, reason, temp_beside
from ..base.errors import UserError
from .space import is_write_failure, poison, reserved, trim_file

__all__ = ["decode_result", "json_default", "write_tree", "read_tree", "replace_group", "tree_bytes", "not_written"]


def decode_result(g: Any) -> Any:
    """A results group as written by ``write_result``: its JSON copy when it has one."""
    if isinstance(g, dict) and isinstance(g.get("json"), str):
        try:
            return json.loads(g["json"])
        except ValueError:
            return g
    return g


def read_json_copy(g: Any) -> Any:
    """The parsed JSON copy (``json``) of a results group as ``write_result`` writes it, read
    without its structured twin (issue 26: decoding that twin cost ~0.4 s CPU per
    identification, and the panel read it 8 times); None when it has no readable copy."""
    t = g.get("json") if isinstance(g, h5py.Group) else None
    if isinstance(t, h5py.Dataset) and h5py.check_string_dtype(t.dtype) and t.shape == ():
        got = decode_result({"json": t.asstr()[()]})
        if not (isinstance(got, dict) and "json" in got):     # a copy that parses
            return got
    return None


def json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def write_tree(g: h5py.Group, data: dict) -> None:
    g.attrs.setdefault("NX_class", "NXcollection")
    for k, v in data.items():
        k = str(k)
        if isinstance(v, dict):
            write_tree(g.create_group(k), v)
        elif isinstance(v, str):
            g.create_dataset(k, data=v, dtype=h5py.string_dtype())
        elif v is None:
            g.create_dataset(k, data=h5py.Empty("f8"))
        elif isinstance(v, (list, tuple)) and v and all(isinstance(x, dict) for x in v):
            sub = g.create_group(k)
            sub.attrs["list_of"] = len(v)
            for i, x in enumerate(v):
                write_tree(sub.create_group(str(i)), x)
        elif isinstance(v, (list, tuple)) and v and all(isinstance(x, str) for x in v):
            g.create_dataset(k, data=list(v), dtype=h5py.string_dtype())
        else:
            try:
                arr = np.asarray(v)
            except (ValueError, TypeError):
                arr = np.empty(0, dtype=object)
            if arr.dtype == object or arr.dtype.kind in "MmU":
                # mixed lists, dates...: kept as JSON text
                ds = g.create_dataset(k, data=json.dumps(v, default=str), dtype=h5py.string_dtype())
                ds.attrs["encoding"] = "json"
            else:
                g.create_dataset(k, data=arr)


def tree_bytes(data: Any) -> int:
    """About how many bytes ``write_tree`` stores for ``data`` (arrays, text, and 1 kB of
    HDF5 objects per key): what ``replace_group`` reserves before writing."""
    if isinstance(data, dict):
        return sum(1024 + len(str(k)) + tree_bytes(v) for k, v in data.items())
    if isinstance(data, (list, tuple)):
        return 1024 + sum(tree_bytes(v) for v in data)
    if isinstance(data, (str, bytes)):
        return 4 * len(data) + 64
    nbytes = getattr(data, "nbytes", None)
    return int(nbytes) + 64 if isinstance(nbytes, int) else 64


def read_tree(g: h5py.Group) -> Any:
    if not isinstance(g, h5py.Group):
        raise TypeError(f"{g.name}: a dataset where a group of results was expected")
    if "list_of" in g.attrs:
        return [read_tree(g[str(i)]) for i in range(int(g.attrs["list_of"]))]
    out: dict[str, Any] = {}
    for k, v in g.items():
        if isinstance(v, h5py.Group):
            out[k] = read_tree(v)
            continue
        if v.shape is None:
            out[k] = None
            continue
        x = v[()]
        if v.attrs.get("encoding") == "json":
            out[k] = json.loads(x.decode() if isinstance(x, bytes) else x)
        elif v.dtype.kind == "O" or h5py.check_string_dtype(v.dtype):
            out[k] = x.decode() if isinstance(x, bytes) else [s.decode() for s in x]
        elif isinstance(x, np.ndarray):
            out[k] = x
        else:
            out[k] = x.item() if isinstance(x, np.generic) else x
    return out


def replace_group(run: Path, full: str, data: dict, keep_as: str | None = None) -> None:
    """Replace the group ``full`` of the closed file ``run`` by ``data``, crash-safely: the
    file is copied to ``.RUN.h5.XXXXXXXX.results`` (``temp_beside``), the group written
    there with its bytes reserved first (``space.reserved``), the copy synced and renamed
    over ``run`` (a kill at any moment leaves the old file or the new one). ``keep_as``:
    the group ``full`` there before is first moved (an HDF5 link move: nothing read or
    copied) to that path of the same copy, replacing what was there; one copy, one rename
    for both. UserError naming the file when the disk is full or read-only, or the run too
    damaged to take the group (``run`` unchanged)."""
    tmp = None
    try:
        tmp = temp_beside(run, ".results")
        shutil.copyfile(run, tmp)
        shutil.copymode(run, tmp)                # the run keeps its permissions (mkstemp: 0600)
        _write_copy(tmp, run, full, data, keep_as)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, run)
        fsync_dir(run.parent)
    except OSError as e:
        if e.errno is None and "errno" not in str(e):
            raise not_written(run, e) from None
        raise UserError(f"results not written ({reason(e)}); the run file is unchanged", file=str(run)) from None
    finally:
        if tmp is not None:
            tmp.unlink(missing_ok=True)


def _write_copy(tmp: Path, run: Path, full: str, data: dict, keep_as: str | None = None) -> None:
    """Write ``data`` as the group ``full`` of the copy ``tmp`` of ``run`` (the group there
    before moved to ``keep_as`` first, when given). A failed write leaves the HDF5 file
    unclosable (``space.poison``); any other error of a damaged copy is one UserError."""
    f = h5py.File(tmp, "a", libver="latest", locking=False)
    try:
        with reserved(f, tree_bytes(data), run, "storing the result", trim=False):
            if keep_as is not None and full in f:
                if keep_as in f:
                    del f[keep_as]
                f.require_group(keep_as.rsplit("/", 1)[0])
                f.move(full, keep_as)
            if full in f:
                del f[full]
            write_tree(f.require_group(full), data)
            f.flush()
    except BaseException as e:
        if is_write_failure(e):
            poison(f)
            raise UserError(f"results not written ({reason(e) if isinstance(e, OSError) else 'a write failed'}); "
                            "the run file is unchanged", file=str(run)) from None
        try:
            f.close()
        except Exception:  # noqa: BLE001 - the copy is discarded anyway
            poison(f)
        if isinstance(e, (UserError, KeyboardInterrupt, SystemExit, ValueError, TypeError)):
            raise                  # ValueError, TypeError: the data does not fit HDF5 (write_result)
        raise not_written(run, e) from None
    try:
        f.close()
    except Exception as e:  # noqa: BLE001 - a close that fails is a failed write
        poison(f)
        raise UserError(f"results not written ({type(e).__name__}); the run file is unchanged",
                        file=str(run)) from None
    trim_file(tmp)


def not_written(run: Path, e: BaseException) -> UserError:
    """The one line for a result the damaged run ``run`` cannot take."""
    text = str(e).splitlines()[0][:120] if str(e) else ""
    return UserError(f"results not written: the run file is damaged ({type(e).__name__}: {text}); "
                     "the run file is unchanged", file=str(run))
