"""The run store: one HDF5 file per test session (h5py), crash-safe shot by shot.

Schema ``labid_schema = 1`` (NeXus-style ``NX_class`` and ``units`` attributes)::

    /                      NX_class=NXroot, labid_schema=1, creator, file_time
    /config                NXcollection: specimen_toml, rig_toml (text datasets)
    /config/rig, /config/specimen   parsed values (nested groups of datasets)
    /shots                 NXentry
    /shots/<kind>          NXdata, one table per shot kind ("hammer", "wave"),
                           attrs: rate_hz (Hz), samples, pretrigger, channels (JSON),
                           trigger (JSON), signal (first channel name)
        <channel>          (n, samples) float64, or float32 for wave shots of an ADC of <= 23 bits
                           (to better than half a step), volts at the ADC input (units "V"),
                           attrs: sensitivity, physical_units, kind, range_v, ...
                           chunked one row per shot, gzip + shuffle
        timestamp          (n,) float64 Unix time, units "s"
        overload           (n, n_channels) uint8, 1 if the channel overloaded
        backend            (n,) fixed-length ASCII
        software_version   (n,) fixed-length ASCII
        meta               (n,) fixed-length UTF-8 JSON of ``Record.meta``
        committed          (n,) int64 shot numbers: the commit marker, written last
    /results               NXcollection: processing/identification (``write_group``)
    /results/history/<name>/<n>  older identifications/diagnoses (labid.runresults; newest: /results/<name>)

Crash safety: shots are written in HDF5 SWMR mode (``libver='latest'``), whose ordered metadata
writes keep the file readable whatever the moment the writer dies. A shot counts only once its row
of ``committed`` is written and flushed; rows past it (a shot cut short) are dropped on reopening.

One writer at a time (issue 15): an ``"a"`` open takes the advisory lock
``RUN.h5.lock`` (``labid.store.lock``) and a second writer is refused in one line
naming the holder. Results (``write_group``) are written into a copy of the file
that replaces it atomically (``os.replace``) once complete and synced: a kill at
any moment leaves either the old file or the new one, never a half-written
results group. Under the lock, stale temporary files of a killed writer
(``.new``, ``.repair``, ``.results``, ``.unlocked``) are removed.

A ``"r"`` open never writes, repairs or copies (``labid.store.readonly``): it
reads plainly, through SWMR (a live writer), or through a view with the flags a
killed writer left seen cleared. A file left flagged is repaired on the next
``"a"`` open (copied into a fresh file, atomically renamed over the old one).
A damaged file (not HDF5, bit flips, missing groups, bad attributes) is a
``UserError`` naming the file and what is wrong.
"""
from __future__ import annotations

import json
import os
import time
import tomllib
from dataclasses import asdict
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from drivers.protocol import ChannelConfig, Record, Timing, Trigger

from ..base.errors import UserError
from ..base.jsonio import to_jsonable
from .h5repair import is_consistency_flag_error, repair
from .lock import WriterLock
from .readonly import open_read_only
from .tables import read_records
from .tree import decode_result, json_default, read_json_copy, read_tree, replace_group, write_tree
from .validate import check_run, damaged, reading

#: suffixes of the temporary files a writer makes beside the run (removed under the lock)
TEMP_SUFFIXES = (".new", ".repair", ".results", ".unlocked")

SCHEMA = 1
KINDS = ("hammer", "wave")
_META_LEN = 4096
_STR_LEN = 32


def software_version() -> str:
    """The installed labid version ('0+unknown' when not installed)."""
    try:
        return version("labid")
    except PackageNotFoundError:  # pragma: no cover - not installed
        return "0+unknown"


def _text(v: Any) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray) and v.shape == ():
        return _text(v[()])
    return str(v)


class RunStore:
    """One session file. ``mode``: "a" creates or resumes (appends), "r" read-only.

    Use as a context manager. Shots are appended with ``append_shot`` (each
    flushed at once) and read back as ``drivers.protocol.Record`` objects.
    """

    def __init__(self, path: str | Path, mode: str = "a"):
        if mode not in ("a", "r"):
            raise ValueError(f"mode {mode!r}: expected 'a' or 'r'")
        self.path = Path(path)
        self.mode = mode
        self._swmr = False
        self._live = False          # read-only view of a file a writer may still be appending to
        self._lock: WriterLock | None = None
        self._f: h5py.File | None = None
        if mode == "r":
            if not self.path.exists():
                raise UserError("file not found; expected a run file (HDF5)", file=str(self.path))
            if not self.path.is_file():
                raise UserError("not a regular file; expected a run file (HDF5)", file=str(self.path))
            try:
                self._f = open_read_only(self.path)
                self._live = bool(self._f.swmr_mode)
                self._check_schema()
                check_run(self._f, str(self.path))
            except Exception as e:
                self.close()
                if isinstance(e, UserError):
                    raise
                raise damaged(self.path, e) from None
            return
        if self.path.exists() and not self.path.is_file():
            raise UserError("not a regular file; expected a run file (HDF5)", file=str(self.path))
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise UserError(f"cannot create the directory ({e.strerror})", file=str(self.path.parent)) from None
        self._lock = WriterLock(self.path)
        try:
            self._open_writer()
        except BaseException as e:
            self.close()
            if isinstance(e, (UserError, KeyboardInterrupt, SystemExit)) or (
                    isinstance(e, OSError) and e.errno is not None):
                raise
            raise damaged(self.path, e) from None

    def _open_writer(self) -> None:
        self._remove_stale()
        if self.path.exists():
            self._f = self._open_append()
            self._check_schema()
            check_run(self._f, str(self.path))
            self._drop_uncommitted()
        else:                      # created complete under a temporary name, then renamed
            tmp = self.path.with_name(self.path.name + ".new")
            try:
                with h5py.File(tmp, "w", libver="latest") as f:
                    self._init(f, self.path.name)
                os.replace(tmp, self.path)
            finally:
                tmp.unlink(missing_ok=True)
            self._f = h5py.File(self.path, "a", libver="latest", locking=False)

    def _remove_stale(self) -> None:
        """Temporary files a killed writer left beside the run (we hold the lock: none is live)."""
        for suffix in TEMP_SUFFIXES:
            self.path.with_name(self.path.name + suffix).unlink(missing_ok=True)

    @staticmethod
    def _init(f: h5py.File, name: str) -> None:
        """Root attributes and top-level groups of a new run file."""
        a = f.attrs
        a["NX_class"] = "NXroot"
        a["labid_schema"] = SCHEMA
        a["creator"] = f"labid {software_version()}"
        a["file_name"] = name
        a["file_time"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        a["HDF5_Version"] = h5py.version.hdf5_version
        a["h5py_version"] = h5py.version.version
        for name, cls in (("config", "NXcollection"), ("shots", "NXentry"),
                          ("results", "NXcollection")):
            f.create_group(name).attrs["NX_class"] = cls

    # -- opening -------------------------------------------------------
    def _open_append(self) -> h5py.File:
        try:
            return h5py.File(self.path, "a", libver="latest", locking=False)
        except OSError as e:
            if e.errno is not None:            # permissions, read-only file system...
                raise
            if not is_consistency_flag_error(e):
                raise damaged(self.path, e) from None
        repair(self.path, open_read_only)
        return h5py.File(self.path, "a", libver="latest", locking=False)

    def _check_schema(self) -> None:
        v = self._f.attrs.get("labid_schema")
        try:
            ok = v is not None and 0 < int(v) <= SCHEMA
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise UserError(f"labid_schema {v!r}: expected a labid run file with schema <= {SCHEMA}",
                            file=str(self.path))

    def _drop_uncommitted(self) -> None:
        """Truncate every table to its committed rows (a shot cut short by a kill)."""
        for kind in list(self._f["shots"]):
            g = self._f["shots"][kind]
            n = g["committed"].shape[0]
            for name, ds in g.items():
                if ds.maxshape[0] is None and ds.shape[0] != n:
                    ds.resize(n, axis=0)
        self._f.flush()

    def _normal(self) -> h5py.File:
        """The file in normal (structure-changing) mode."""
        if self.mode != "a":
            raise UserError("run file opened read-only", file=str(self.path))
        if self._swmr:
            self._handles = (None,)
            self._f.close()
            self._f = h5py.File(self.path, "a", libver="latest", locking=False)
            self._swmr = False
        return self._f

    def _swmr_on(self) -> h5py.File:
        if not self._swmr:
            self._f.flush()
            self._f.swmr_mode = True
            self._swmr = True
        return self._f

    def close(self) -> None:
        self._handles = (None,)
        try:
            if self._f is not None:
                f, self._f = self._f, None
                try:
                    if self.mode == "a" and f.id.valid:
                        f.flush()
                finally:
                    view = getattr(f, "_labid_view", None)
                    f.close()
                    if view is not None:
                        view.close()
        finally:
            if self._lock is not None:
                self._lock.release()
                self._lock = None

    def __enter__(self) -> "RunStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- configuration -------------------------------------------------
    def write_config(self, specimen_toml: str, rig_toml: str) -> None:
        """Store the specimen and rig TOML texts (and their parsed values).

        On a resumed file the texts must equal those already stored: one file
        holds one session on one rig and one specimen.
        """
        f = self._f
        cfg = f["config"]
        if "specimen_toml" in cfg:
            for key, new in (("specimen_toml", specimen_toml), ("rig_toml", rig_toml)):
                old = _text(cfg[key][()])
                if old != new:
                    raise UserError(f"differs from the {key[:-5]} this file was recorded with; "
                                    "expected the same configuration to resume (or a new --out file)",
                                    file=str(self.path), key=f"config/{key}")
            return
        f = self._normal()
        cfg = f["config"]
        for key, text in (("specimen_toml", specimen_toml), ("rig_toml", rig_toml)):
            ds = cfg.create_dataset(key, data=text, dtype=h5py.string_dtype())
            ds.attrs["mime_type"] = "application/toml"
        for key, text in (("specimen", specimen_toml), ("rig", rig_toml)):
            try:
                parsed = tomllib.loads(text)
            except tomllib.TOMLDecodeError:
                parsed = {}
            write_tree(cfg.create_group(key), parsed)
        f.flush()

    def write_config_text(self, name: str, text: str) -> None:
        """Store or replace the text ``/config/<name>`` (e.g. ``calibration_csv``, the calibration sheet)."""
        if self.config_text(name) != text:
            self._normal()["config"].pop(name, None)
            self._f["config"][name] = text
            self._f.flush()

    def config_text(self, name: str) -> str:
        """The text ``/config/<name>`` ('' if absent)."""
        with self._reading():
            return _text(self._f["config"][name][()]) if name in self._f["config"] else ""

    def specimen_toml(self) -> str:
        return self.config_text("specimen_toml")

    def rig_toml(self) -> str:
        return self.config_text("rig_toml")

    def attributes(self) -> dict[str, Any]:
        """The file's root attributes (schema version, NeXus class, software), strings decoded."""
        with self._reading():
            return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in self._f.attrs.items()}

    def result_names(self) -> list[str]:
        """Names of the groups under ``/results`` (``write_group``/``write_result``)."""
        with self._reading():
            return list(self._f["results"]) if "results" in self._f else []

    # -- shots ---------------------------------------------------------
    def declare(self, kind: str, channels: tuple[ChannelConfig, ...], timing: Timing,
                trigger: Trigger | None, dtype: str = "f8") -> None:
        """Create the table for one shot kind (before any shot: structure changes
        are not crash-safe, appends are). Idempotent when the layout matches.
        ``dtype``: of the sample tables, 'f8' or 'f4' (holds ADC samples of up to 23 bits
        to better than half a step: ``labid.workflows.acquisition.sample_dtype``)."""
        if kind not in KINDS:
            raise ValueError(f"shot kind {kind!r}: expected one of {KINDS}")
        shots = self._f["shots"]
        if kind in shots:
            g = shots[kind]
            same = (json.loads(g.attrs["channels"]) == [asdict(c) for c in channels]
                    and int(g.attrs["samples"]) == timing.samples
                    and float(g.attrs["rate_hz"]) == timing.rate_hz
                    and int(g.attrs["pretrigger"]) == timing.pretrigger)
            if not same:
                raise UserError(f"the {kind} channels/timing differ from those already recorded; "
                                "expected the same rig to resume (or a new --out file)",
                                file=str(self.path), key=f"shots/{kind}")
            return
        f = self._normal()
        g = f["shots"].create_group(kind)
        g.attrs["NX_class"] = "NXdata"
        g.attrs["kind"] = kind
        g.attrs["rate_hz"] = float(timing.rate_hz)
        g.attrs["rate_hz_units"] = "Hz"
        g.attrs["samples"] = int(timing.samples)
        g.attrs["pretrigger"] = int(timing.pretrigger)
        g.attrs["channels"] = json.dumps([asdict(c) for c in channels])
        g.attrs["trigger"] = json.dumps(asdict(trigger) if trigger else None)
        g.attrs["signal"] = channels[0].name
        n = timing.samples
        for c in channels:
            ds = g.create_dataset(c.name, shape=(0, n), maxshape=(None, n), dtype=dtype,
                                  chunks=(1, n), compression="gzip", compression_opts=1,
                                  shuffle=True)
            ds.attrs.update(units="V", sensitivity=c.sensitivity, physical_units=c.unit,
                            kind=c.kind, physical_channel=c.physical, range_v=c.range_v,
                            coupling=c.coupling, long_name=f"{c.name} ({c.kind}) at the ADC input")
        ncol = len(channels)
        specs = {"timestamp": ("f8", ()), "overload": ("u1", (ncol,)),
                 "backend": (f"S{_STR_LEN}", ()), "software_version": (f"S{_STR_LEN}", ()),
                 "meta": (f"S{_META_LEN}", ()), "committed": ("i8", ())}
        for name, (dt, extra) in specs.items():
            ds = g.create_dataset(name, shape=(0, *extra), maxshape=(None, *extra), dtype=dt,
                                  chunks=(4 if name == "meta" else 64, *extra),
                                  compression="gzip" if name == "meta" else None)
        g["timestamp"].attrs["units"] = "s"
        g["overload"].attrs["columns"] = json.dumps([c.name for c in channels])
        f.flush()

    def append_shot(self, record: Record, kind: str) -> str:
        """Append one record as a shot of ``kind``; flushed before returning.

        Returns the shot name ``"<kind>_<number>"`` (numbers from 1).
        """
        if self.mode != "a":
            raise UserError("run file opened read-only", file=str(self.path))
        if kind not in self._f["shots"]:
            self.declare(kind, record.channels, record.timing, record.trigger)
        f = self._swmr_on()
        g, cols = self._table(kind)
        n = g["committed"].shape[0]
        names = [c.name for c in record.channels]
        if cols != names:
            raise UserError(f"record channels {names} differ from the recorded table",
                            file=str(self.path), key=f"shots/{kind}")
        meta = json.dumps(record.meta, default=json_default).encode()
        if len(meta) > _META_LEN:
            raise ValueError(f"record meta too long ({len(meta)} > {_META_LEN} bytes)")
        row = {c: np.asarray(record.data[c], dtype=g[c].dtype) for c in names}
        for c, arr in row.items():
            ds = g[c]
            if arr.shape != (ds.shape[1],):
                raise ValueError(f"channel {c}: {arr.shape[0]} samples, table has {ds.shape[1]}")
            ds.resize(n + 1, axis=0)
            ds[n] = arr
        for name, val in (("timestamp", float(record.timestamp)),
                          ("overload", np.array([bool(record.overload.get(c, False)) for c in names], "u1")),
                          ("backend", record.backend.encode()[:_STR_LEN]),
                          ("software_version", software_version().encode()[:_STR_LEN]),
                          ("meta", meta)):
            ds = g[name]
            ds.resize(n + 1, axis=0)
            ds[n] = val
        f.flush()                      # data first ...
        ds = g["committed"]            # ... then the commit marker
        ds.resize(n + 1, axis=0)
        ds[n] = n + 1
        f.flush()
        return f"{kind}_{n + 1:04d}"

    def _table(self, kind: str) -> tuple[dict, list[str]]:
        """Dataset handles of a shot table (cached while the file stays open)."""
        key = kind
        if getattr(self, "_handles", (None,))[0] != key:
            g = self._f["shots"][kind]
            self._handles = (key, ({name: ds for name, ds in g.items()},
                                   json.loads(g["overload"].attrs["columns"])))
        return self._handles[1]

    def _refresh(self) -> None:
        if self._live:
            for g in self._f["shots"].values():
                for ds in g.values():
                    ds.refresh()

    def n_shots(self, kind: str | None = None) -> int:
        with self._reading():
            return self._n_shots(kind)

    def _reading(self):
        """Context: HDF5 errors while reading (bit flips, bad chunks) -> UserError naming the file."""
        return reading(self.path)

    def _n_shots(self, kind: str | None = None) -> int:
        self._refresh()
        kinds = [kind] if kind else list(self._f["shots"])
        return sum(self._f["shots"][k]["committed"].shape[0] for k in kinds if k in self._f["shots"])

    def metas(self, kind: str) -> list[dict]:
        """The ``meta`` dict of every committed shot of ``kind`` (no sample data read)."""
        with self._reading():
            return self._metas(kind)

    def _metas(self, kind: str) -> list[dict]:
        self._refresh()
        if kind not in self._f["shots"]:
            return []
        g = self._f["shots"][kind]
        n = g["committed"].shape[0]
        return [json.loads(m.decode() or "{}") for m in g["meta"][:n]]

    def shots(self, kind: str | None = None, limit: int | None = None) -> list[Record]:
        """Every committed shot (of ``kind``, or all kinds in table order) as Records;
        ``limit``: at most that many (the first) of each kind.

        ``meta`` carries ``kind``, ``shot`` (name), ``software_version`` besides
        what the device recorded.
        """
        with self._reading():
            return self._shots(kind, limit)

    def _shots(self, kind: str | None, limit: int | None) -> list[Record]:
        self._refresh()
        return read_records(self._f["shots"], kind, limit)

    # -- results -------------------------------------------------------
    def write_group(self, path: str, data: dict) -> None:
        """Write a nested dict (arrays, scalars, strings, dicts) under ``/results/<path>``,
        replacing any previous content of that group.

        Crash-safe: written into a copy of the run (``RUN.h5.results``), synced, then
        renamed over it; a kill at any moment leaves the earlier results intact.
        ``UserError`` naming the file when the disk is full or read-only (the run
        file is unchanged)."""
        self._normal()
        self._handles = (None,)
        self._f.flush()
        self._f.close()
        self._f = None
        try:
            replace_group(self.path, f"results/{path.strip('/')}", data)
        finally:
            self._f = h5py.File(self.path, "a", libver="latest", locking=False)

    def write_result(self, path: str, data: dict) -> None:
        """Write a result (nested dict) under ``/results/<path>`` twice over: its arrays and
        scalars where HDF5 can hold them, and a plain-JSON copy in ``json`` (which
        readers prefer); only the JSON copy when the structure does not fit HDF5."""
        text = json.dumps(to_jsonable(data), allow_nan=False)
        try:
            self.write_group(path, {**data, "json": text})
        except (ValueError, TypeError):
            self.write_group(path, {"json": text})

    def read_group(self, path: str) -> dict:
        """The nested dict written by ``write_group`` (arrays as numpy, strings as str)."""
        full = f"results/{path.strip('/')}"
        if full not in self._f:
            raise KeyError(f"no results group {path!r} in {self.path}")
        with self._reading():
            return read_tree(self._f[full])

    def read_result(self, path: str) -> Any:
        """``/results/<path>``: its JSON copy when it has one (read alone), else ``read_group``'s."""
        with self._reading():
            got = read_json_copy(self._f.get(f"results/{path.strip('/')}"))
        return got if got is not None else decode_result(self.read_group(path))
