"""The run store: one HDF5 file per test session (h5py), crash-safe shot by shot.
(Just over 500 lines, most of it this schema and the crash-safety notes; issue 15 splits the store.)

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

Crash safety: shots are written in HDF5 SWMR mode (``libver='latest'``), whose
ordered metadata writes keep the file readable whatever the moment the writer
dies. A shot counts only once its row of ``committed`` is written and flushed;
rows past it (a shot cut short) are dropped on reopening. A file left with the
"open for writing" flags by a killed writer is repaired on the next ``"a"``
open by copying it (read through SWMR) to a fresh file, atomically renamed over
the old one; a ``"r"`` open reads it through SWMR without touching it. A writer
killed outside SWMR mode (creating a table, writing results: not crash-safe,
but flushed after each change) leaves the flags without SWMR; such a file is
read from a copy whose superblock flags are cleared (checksum recomputed).
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

from ..errors import UserError
from ..jsonio import to_jsonable
from .h5repair import is_consistency_flag_error, open_flagged, repair

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
        self._unlocked: Path | None = None
        self._f: h5py.File | None = None
        if mode == "r":
            if not self.path.exists():
                raise UserError("file not found; expected a run file (HDF5)", file=str(self.path))
            try:
                self._f = h5py.File(self.path, "r")
            except OSError as e:
                if not is_consistency_flag_error(e):
                    raise UserError(f"not a readable HDF5 run file ({e})", file=str(self.path)) from None
                self._f, self._unlocked = open_flagged(self.path)
                self._live = self._unlocked is None
            self._check_schema()
            return
        if self.path.exists():
            self._f = self._open_append()
            self._check_schema()
            self._drop_uncommitted()
        else:                      # created complete under a temporary name, then renamed
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_name(self.path.name + ".new")
            with h5py.File(tmp, "w", libver="latest") as f:
                self._init(f, self.path.name)
            os.replace(tmp, self.path)
            self._f = h5py.File(self.path, "a", libver="latest")

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
            return h5py.File(self.path, "a", libver="latest")
        except OSError as e:
            if not is_consistency_flag_error(e):
                raise UserError(f"cannot open for appending ({e})", file=str(self.path)) from None
        repair(self.path)
        return h5py.File(self.path, "a", libver="latest")

    def _check_schema(self) -> None:
        v = self._f.attrs.get("labid_schema")
        if v is None or int(v) > SCHEMA:
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
            self._f = h5py.File(self.path, "a", libver="latest")
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
        if self._f is not None:
            if self.mode == "a":
                self._f.flush()
            self._f.close()
            self._f = None
        if self._unlocked is not None:
            self._unlocked.unlink(missing_ok=True)
            self._unlocked = None

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
            _write_tree(cfg.create_group(key), parsed)
        f.flush()

    def write_config_text(self, name: str, text: str) -> None:
        """Store or replace the text ``/config/<name>`` (e.g. ``calibration_csv``, the calibration sheet)."""
        if self.config_text(name) != text:
            self._normal()["config"].pop(name, None)
            self._f["config"][name] = text
            self._f.flush()

    def config_text(self, name: str) -> str:
        """The text ``/config/<name>`` ('' if absent)."""
        return _text(self._f["config"][name][()]) if name in self._f["config"] else ""

    def specimen_toml(self) -> str:
        return _text(self._f["config/specimen_toml"][()]) if "config/specimen_toml" in self._f else ""

    def rig_toml(self) -> str:
        return _text(self._f["config/rig_toml"][()]) if "config/rig_toml" in self._f else ""

    def attributes(self) -> dict[str, Any]:
        """The file's root attributes (schema version, NeXus class, software), strings decoded."""
        return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in self._f.attrs.items()}

    def result_names(self) -> list[str]:
        """Names of the groups under ``/results`` (``write_group``/``write_result``)."""
        return list(self._f["results"]) if "results" in self._f else []

    # -- shots ---------------------------------------------------------
    def declare(self, kind: str, channels: tuple[ChannelConfig, ...], timing: Timing,
                trigger: Trigger | None, dtype: str = "f8") -> None:
        """Create the table for one shot kind (before any shot: structure changes
        are not crash-safe, appends are). Idempotent when the layout matches.
        ``dtype``: of the sample tables, 'f8' or 'f4' (holds ADC samples of up to 23 bits
        to better than half a step: ``labid.acquisition.sample_dtype``)."""
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
        meta = json.dumps(record.meta, default=_json_default).encode()
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
        self._refresh()
        kinds = [kind] if kind else list(self._f["shots"])
        return sum(self._f["shots"][k]["committed"].shape[0] for k in kinds if k in self._f["shots"])

    def metas(self, kind: str) -> list[dict]:
        """The ``meta`` dict of every committed shot of ``kind`` (no sample data read)."""
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
        self._refresh()
        out: list[Record] = []
        kinds = [kind] if kind else sorted(self._f["shots"])
        for k in kinds:
            if k not in self._f["shots"]:
                continue
            g = self._f["shots"][k]
            chans = tuple(ChannelConfig(**d) for d in json.loads(g.attrs["channels"]))
            timing = Timing(float(g.attrs["rate_hz"]), int(g.attrs["samples"]), int(g.attrs["pretrigger"]))
            trig = json.loads(g.attrs["trigger"])
            trigger = Trigger(**trig) if trig else None
            n = g["committed"].shape[0]
            if limit is not None:
                n = min(n, max(0, int(limit)))
            if n == 0:
                continue
            data = {c.name: np.asarray(g[c.name][:n], dtype="f8") for c in chans}
            ts, ov = g["timestamp"][:n], g["overload"][:n]
            be, sv, me = g["backend"][:n], g["software_version"][:n], g["meta"][:n]
            for i in range(n):
                meta = json.loads(me[i].decode() or "{}")
                meta.update(kind=k, shot=f"{k}_{i + 1:04d}", software_version=sv[i].decode())
                out.append(Record(data={c.name: data[c.name][i] for c in chans}, channels=chans,
                                  timing=timing, trigger=trigger,
                                  overload={c.name: bool(ov[i, j]) for j, c in enumerate(chans)},
                                  timestamp=float(ts[i]), backend=be[i].decode(), meta=meta))
        return out

    # -- results -------------------------------------------------------
    def write_group(self, path: str, data: dict) -> None:
        """Write a nested dict (arrays, scalars, strings, dicts) under ``/results/<path>``,
        replacing any previous content of that group."""
        f = self._normal()
        full = f"results/{path.strip('/')}"
        if full in f:
            del f[full]
        _write_tree(f.require_group(full), data)
        f.flush()

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
        return _read_tree(self._f[full])

    def read_result(self, path: str) -> Any:
        """The result under ``/results/<path>`` as ``write_result`` wrote it: its JSON copy
        when it has one, else the nested dict of ``read_group``. KeyError if absent."""
        return decode_result(self.read_group(path))


def decode_result(g: Any) -> Any:
    """A results group as written by ``write_result``: its JSON copy when it has one."""
    if isinstance(g, dict) and isinstance(g.get("json"), str):
        try:
            return json.loads(g["json"])
        except ValueError:
            return g
    return g


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _write_tree(g: h5py.Group, data: dict) -> None:
    g.attrs.setdefault("NX_class", "NXcollection")
    for k, v in data.items():
        k = str(k)
        if isinstance(v, dict):
            _write_tree(g.create_group(k), v)
        elif isinstance(v, str):
            g.create_dataset(k, data=v, dtype=h5py.string_dtype())
        elif v is None:
            g.create_dataset(k, data=h5py.Empty("f8"))
        elif isinstance(v, (list, tuple)) and v and all(isinstance(x, dict) for x in v):
            sub = g.create_group(k)
            sub.attrs["list_of"] = len(v)
            for i, x in enumerate(v):
                _write_tree(sub.create_group(str(i)), x)
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


def _read_tree(g: h5py.Group) -> Any:
    if "list_of" in g.attrs:
        return [_read_tree(g[str(i)]) for i in range(int(g.attrs["list_of"]))]
    out: dict[str, Any] = {}
    for k, v in g.items():
        if isinstance(v, h5py.Group):
            out[k] = _read_tree(v)
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
