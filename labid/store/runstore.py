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

One writer at a time (issue 15): an ``"a"`` open takes the lock ``RUN.h5.lock``
(``labid.store.lock``); a second writer, under any name, is refused in one line naming the
holder. Results (``write_group``, ``labid.store.results``) go into a synced copy renamed over the
file: a kill leaves the old file or the new one. A kept result's predecessor is moved (an HDF5
link move) to ``/results/history`` in that same copy: one copy per result, whatever the history. Temporary files are ``mkstemp`` names beside the run, stale
ones removed under the lock; a run path that is a symbolic link is refused for writing.
In one process, a writer's opens wait for readers of other threads (``labid.store.inprocess``).
Full disk (issue 27): the bytes of every HDF5 write are reserved first (``labid.store.space``):
a full disk or a file-size limit refuses it in one line; the committed shots are kept.

A ``"r"`` open never writes, repairs or copies (``labid.store.readonly``): it
reads plainly, through SWMR (a live writer), or through a view with the flags a
killed writer left seen cleared. A file left flagged is repaired on the next
``"a"`` open (copied into a fresh file, atomically renamed over the old one).
A damaged file (not HDF5, bit flips, missing groups, bad attributes) is a
``UserError`` naming the file and what is wrong.
"""
from __future__ import annotations

import contextlib
import json
import os
import tomllib
from dataclasses import asdict
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from drivers.protocol import ChannelConfig, Record, Timing, Trigger

from ..base.atomic import default_mode, temp_beside
from ..base.errors import UserError
from .h5repair import is_consistency_flag_error, repair
from .inprocess import Reading, busy, changing
from .lock import WriterLock, relock
from .probe import carry, identity, probe
from .readonly import open_read_only
from .tables import append_row, create_table, drop_uncommitted, init_file, read_records, software_version, text_of
from .space import is_write_failure, poison, remove_stale, reserved, trim_file, write_failed
from .results import Results
from .tree import json_default, write_tree
from .validate import TABLES, check_run, damaged, reading

#: suffixes of the temporary files a writer makes beside the run (removed under the lock)
TEMP_SUFFIXES = (".new", ".repair", ".results", ".unlocked")
_STRUCTURE_BYTES = 64 << 10      # reserved for a structure change (tables, configuration)

SCHEMA = 1
KINDS = ("hammer", "wave")
_META_LEN = 4096
_STR_LEN = 32


class RunStore(Results):
    """One session file. ``mode``: "a" creates or resumes (appends), "r" read-only.

    Use as a context manager. Shots are appended with ``append_shot`` (each
    flushed at once) and read back as ``drivers.protocol.Record`` objects; results
    (``/results``) are written and read by the methods of ``labid.store.results``.
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
        self._reader: Reading | None = None      # registered while open (store.inprocess)
        self._seen: tuple | None = None          # identity probed or made by this writer (store.probe)
        if mode == "r":
            if not self.path.exists():
                raise UserError("file not found; expected a run file (HDF5)", file=str(self.path))
            if not self.path.is_file():
                raise UserError("not a regular file; expected a run file (HDF5)", file=str(self.path))
            probe(self.path)          # a file the library would loop on: refused (store.probe)
            self._reader = Reading(self.path)
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
        if self.path.is_symlink():
            raise UserError(f"a symbolic link (to {os.readlink(self.path)!r}); expected the run file itself "
                            "(labid never writes through a link it did not create: give the file's own "
                            "path)", file=str(self.path))
        if self.path.exists() and not self.path.is_file():
            raise UserError("not a regular file; expected a run file (HDF5)", file=str(self.path))
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise UserError(f"cannot create the directory ({e.strerror})", file=str(self.path.parent)) from None
        try:
            with changing(self.path):   # readers of other threads closed first (store.inprocess)
                self._lock = WriterLock(self.path)
                self._open_writer()
        except BaseException as e:
            self.close()
            if isinstance(e, (UserError, KeyboardInterrupt, SystemExit)) or (
                    isinstance(e, OSError) and e.errno is not None):
                raise
            raise damaged(self.path, e) from None

    def _open_writer(self) -> None:
        remove_stale(self.path, TEMP_SUFFIXES)
        if self.path.exists():
            probe(self.path)
            self._seen = identity(self.path)
            self._f = self._open_append()
            self._check_schema()
            check_run(self._f, str(self.path))
            with self._writing("opening the run"):
                drop_uncommitted(self._f)
        else:                      # created complete under a temporary name, then renamed
            tmp = temp_beside(self.path, ".new")
            try:
                f = h5py.File(tmp, "w", libver="latest", locking=False)
                try:
                    with reserved(f, _STRUCTURE_BYTES, self.path, "creating the run file", trim=False):
                        init_file(f, self.path.name, SCHEMA, f"labid {software_version()}")
                        f.flush()
                        f.close()
                except BaseException as e:
                    poison(f)              # never closed after a failure: HDF5 may not survive it
                    if is_write_failure(e):
                        raise write_failed(self.path, e, "creating the run file") from None
                    raise
                trim_file(tmp)
                os.chmod(tmp, default_mode())   # mkstemp made it 0600; a run file is shared as any file
                os.replace(tmp, self.path)
                self._seen = carry(None, self.path)
            finally:
                tmp.unlink(missing_ok=True)
            relock(self.path)
            self._f = h5py.File(self.path, "a", libver="latest", locking=False)

    @contextlib.contextmanager
    def _writing(self, what: str):
        """Context of HDF5 writes: one that failed (a full disk despite the reservation)
        leaves the file unclosable: its objects are kept alive (``space.poison``), the lock
        held until the process ends, and the failure is one ``UserError``."""
        try:
            yield
        except UserError:
            raise
        except BaseException as e:
            if not is_write_failure(e):
                raise
            poison(self._f, getattr(self, "_handles", None), self._lock)
            self._f, self._handles, self._lock = None, (None,), None
            raise write_failed(self.path, e, what) from None

    # -- opening -------------------------------------------------------
    def _open_append(self) -> h5py.File:
        try:
            return h5py.File(self.path, "a", libver="latest", locking=False)
        except OSError as e:
            if e.errno is not None:            # permissions, read-only file system...
                raise
            if "already open for read-only" in str(e):   # by this thread (store.inprocess)
                raise busy(self.path) from None
            if not is_consistency_flag_error(e):
                raise damaged(self.path, e) from None
        repair(self.path, open_read_only)
        relock(self.path)
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

    def _normal(self) -> h5py.File:
        """The file in normal (structure-changing) mode."""
        if self.mode != "a":
            raise UserError("run file opened read-only", file=str(self.path))
        if self._swmr:
            self._handles = (None,)
            with changing(self.path):
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
                    if self.mode == "a":          # what this writer changed is not probed again
                        self._seen = carry(self._seen, self.path)
        finally:
            if self._lock is not None:
                self._lock.release()
                self._lock = None
            if self._reader is not None:
                self._reader.release()

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
                old = text_of(cfg[key][()])
                if old != new:
                    raise UserError(f"differs from the {key[:-5]} this file was recorded with; "
                                    "expected the same configuration to resume (or a new --out file)",
                                    file=str(self.path), key=f"config/{key}")
            return
        with self._structure("storing the configuration", 4 * (len(specimen_toml) + len(rig_toml))) as f:
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
            with self._structure(f"storing /config/{name}", 2 * len(text)) as f:
                f["config"].pop(name, None)
                f["config"][name] = text
                f.flush()

    @contextlib.contextmanager
    def _structure(self, what: str, nbytes: int = 0):
        """Context of a structure change in normal mode: the file (``_normal``), with
        ``nbytes`` reserved and write failures made one line (``_writing``)."""
        f = self._normal()
        with self._writing(what), reserved(f, nbytes + _STRUCTURE_BYTES, self.path, what):
            yield f

    def config_text(self, name: str) -> str:
        """The text ``/config/<name>`` ('' if absent)."""
        with self._reading():
            return text_of(self._f["config"][name][()]) if name in self._f["config"] else ""

    def specimen_toml(self) -> str:
        return self.config_text("specimen_toml")

    def rig_toml(self) -> str:
        return self.config_text("rig_toml")

    def attributes(self) -> dict[str, Any]:
        """The file's root attributes (schema version, NeXus class, software), strings decoded."""
        with self._reading():
            return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in self._f.attrs.items()}

    # -- shots ---------------------------------------------------------
    def declare(self, kind: str, channels: tuple[ChannelConfig, ...], timing: Timing,
                trigger: Trigger | None, dtype: str = "f8") -> None:
        """Create the table for one shot kind (before any shot: structure changes
        are not crash-safe, appends are). Idempotent when the layout matches.
        ``dtype``: of the sample tables, 'f8' or 'f4' (holds ADC samples of up to 23 bits
        to better than half a step: ``labid.workflows.acquisition.sample_dtype``)."""
        if kind not in KINDS:
            raise ValueError(f"shot kind {kind!r}: expected one of {KINDS}")
        for c in channels:
            if c.name in TABLES or "/" in c.name or c.name.strip(".") == "":
                raise UserError(f"channel name {c.name!r}: a name the run file cannot hold (no '/', not one of "
                                f"{list(TABLES)})", file=str(self.path), key=f"shots/{kind}")
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
        with self._structure(f"creating the {kind} shot table", 4096 * len(channels)) as f:
            create_table(f, kind, channels, timing, trigger, dtype, _STR_LEN, _META_LEN)

    def append_shot(self, record: Record, kind: str) -> str:
        """Append one record as a shot of ``kind``; flushed before returning.

        Returns the shot name ``"<kind>_<number>"`` (numbers from 1).
        """
        if self.mode != "a":
            raise UserError("run file opened read-only", file=str(self.path))
        if kind not in self._f["shots"]:
            self.declare(kind, record.channels, record.timing, record.trigger)
        with self._writing(f"writing a {kind} shot"):
            f = self._swmr_on()
            g, cols = self._table(kind)
            names = [c.name for c in record.channels]
            if cols != names:
                raise UserError(f"record channels {names} differ from the recorded table",
                                file=str(self.path), key=f"shots/{kind}")
            meta = json.dumps(record.meta, default=json_default).encode()
            if len(meta) > _META_LEN:
                raise ValueError(f"record meta too long ({len(meta)} > {_META_LEN} bytes)")
            row = {c: np.asarray(record.data[c], dtype=g[c].dtype) for c in names}
            for c, arr in row.items():           # every check before the first write
                if arr.shape != (g[c].shape[1],):
                    raise ValueError(f"channel {c}: {arr.shape[0]} samples, table has {g[c].shape[1]}")
            nbytes = sum(a.nbytes for a in row.values())
            with reserved(f, nbytes * 1.1 + _META_LEN, self.path, f"the {kind} shot"):
                return append_row(f, g, row, meta, record, kind, software_version(), _STR_LEN)

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
