"""The shot tables of a run file: created (``create_table``), appended to (``append_row``)
and read into ``drivers.protocol.Record`` objects (``read_records``)."""
from __future__ import annotations

import json
import time
from dataclasses import asdict
from importlib.metadata import PackageNotFoundError, version

import h5py
import numpy as np

from drivers.protocol import ChannelConfig, Record, Timing, Trigger


def software_version() -> str:
    """The installed labid version ('0+unknown' when not installed)."""
    try:
        return version("labid")
    except PackageNotFoundError:  # pragma: no cover - not installed
        return "0+unknown"


def text_of(v) -> str:
    """A text value of an HDF5 dataset or attribute (bytes, 0-d array or str) as str."""
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray) and v.shape == ():
        return text_of(v[()])
    return str(v)


def read_records(shots: h5py.Group, kind: str | None, limit: int | None) -> list[Record]:
    """Every committed shot under ``/shots`` (of ``kind``, or all kinds in table order),
    at most ``limit`` of each kind; ``meta`` gains ``kind``, ``shot``, ``software_version``."""
    out: list[Record] = []
    kinds = [kind] if kind else sorted(shots)
    for k in kinds:
        if k not in shots:
            continue
        g = shots[k]
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


def create_table(f: h5py.File, kind: str, channels, timing: Timing, trigger: Trigger | None, dtype: str,
                 str_len: int, meta_len: int) -> None:
    """The empty tables of a shot kind (schema in ``labid.store.runstore``); flushed."""
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
             "backend": (f"S{str_len}", ()), "software_version": (f"S{str_len}", ()),
             "meta": (f"S{meta_len}", ()), "committed": ("i8", ())}
    for name, (dt, extra) in specs.items():
        ds = g.create_dataset(name, shape=(0, *extra), maxshape=(None, *extra), dtype=dt,
                              chunks=(4 if name == "meta" else 64, *extra),
                              compression="gzip" if name == "meta" else None)
    g["timestamp"].attrs["units"] = "s"
    g["overload"].attrs["columns"] = json.dumps([c.name for c in channels])
    f.flush()


def append_row(f: h5py.File, g: dict, row: dict, meta: bytes, record: Record, kind: str, version: str,
               str_len: int) -> str:
    """Append one checked shot to the tables ``g`` (dataset handles): its data, then, once
    that is flushed, the commit marker; returns the shot name."""
    n = g["committed"].shape[0]
    names = list(row)
    for c, arr in row.items():
        ds = g[c]
        ds.resize(n + 1, axis=0)
        ds[n] = arr
    for name, val in (("timestamp", float(record.timestamp)),
                      ("overload", np.array([bool(record.overload.get(c, False)) for c in names], "u1")),
                      ("backend", record.backend.encode()[:str_len]),
                      ("software_version", version.encode()[:str_len]),
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


def drop_uncommitted(f: h5py.File) -> None:
    """Truncate every shot table of ``f`` to its committed rows (a shot cut short by a kill)."""
    for kind in list(f["shots"]):
        g = f["shots"][kind]
        n = g["committed"].shape[0]
        for ds in g.values():
            if ds.maxshape[0] is None and ds.shape[0] != n:
                ds.resize(n, axis=0)
    f.flush()


def init_file(f: h5py.File, name: str, schema: int, creator: str) -> None:
    """Root attributes and top-level groups of a new run file."""
    a = f.attrs
    a["NX_class"] = "NXroot"
    a["labid_schema"] = schema
    a["creator"] = creator
    a["file_name"] = name
    a["file_time"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    a["HDF5_Version"] = h5py.version.hdf5_version
    a["h5py_version"] = h5py.version.version
    for group, cls in (("config", "NXcollection"), ("shots", "NXentry"), ("results", "NXcollection")):
        f.create_group(group).attrs["NX_class"] = cls
