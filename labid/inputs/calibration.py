"""Sensor calibration: the lab's calibration sheet (CSV), TEDS, and what a shot was recorded with.

A rig file references its sheet with ``calibration = "sheet.csv"`` (relative to the rig
file; docs/rig-file.md). The sheet is CSV with the header

    channel,serial,sensitivity,unit,calibration_date,due_date

one row per rig channel: ``channel`` is the rig's channel name, ``sensitivity`` in ``unit``
(``mV/g``, ``V/(m/s^2)``, ``mV/N``, ``V/N``, ``V/V``; ``labid.inputs.units``), dates ISO
``YYYY-MM-DD``. Its sensitivities override the rig file's. TEDS (IEEE 1451.4, read through
nidaqmx by ``drivers.nidaq.read_teds`` on the NI backend) fills the channels the sheet does
not list; where both exist, the sheet wins and a different serial number or a sensitivity
more than 2 % apart is reported. A channel in neither keeps the rig file's sensitivity.

What a shot was recorded with goes into its ``meta`` (``Calibration.meta``, compact: per
channel [serial, sensitivity V/SI, calibration date, due date, source]) and the sheet text
into ``/config/calibration_csv`` of the run. An overdue calibration (due date before today)
is warned about once per process (``warn_lines``); ``status`` gives the panel and the
report what to show.
"""
from __future__ import annotations

import csv
import datetime as dt
import io
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterable

from drivers.nidaq import TedsInfo, physical_name, read_teds

from ..base.errors import UserError
from .files import read_text_file
from .rigtypes import Rig
from .units import QUANTITY, sensitivity_si

COLUMNS = ("channel", "serial", "sensitivity", "unit", "calibration_date", "due_date")
#: relative difference between the sheet's and the TEDS sensitivity that is reported
TEDS_TOLERANCE = 0.02


@dataclass(frozen=True)
class CalEntry:
    """The calibration of one channel: serial, sensitivity in V per SI unit (and as written),
    calibration and due dates (None if not known), source 'sheet', 'teds' or 'rig'."""

    channel: str
    serial: str
    sensitivity: float
    written: str = ""
    calibrated: dt.date | None = None
    due: dt.date | None = None
    source: str = "sheet"

    def overdue(self, today: dt.date) -> bool:
        return self.due is not None and self.due < today

    def to_dict(self) -> dict:
        return {"channel": self.channel, "serial": self.serial, "sensitivity": self.sensitivity,
                "sensitivity_as_written": self.written,
                "calibration_date": self.calibrated.isoformat() if self.calibrated else None,
                "due_date": self.due.isoformat() if self.due else None, "source": self.source}


@dataclass(frozen=True)
class Calibration:
    """The calibration a rig is used with: sheet path and text, one entry per calibrated channel,
    and the notes to show the user (overrides, TEDS disagreements)."""

    sheet: str | None
    text: str
    entries: dict[str, CalEntry] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def overdue(self, today: dt.date | None = None) -> list[CalEntry]:
        today = today or dt.date.today()
        return [e for e in self.entries.values() if e.overdue(today)]

    def meta(self, channels: Iterable[str], today: dt.date | None = None) -> dict:
        """The per-shot record of the calibration used for ``channels`` (compact: the shot
        meta of the run file holds at most 4 kB), with the channels overdue ``today``."""
        today = today or dt.date.today()
        out, late = {}, []
        for c in channels:
            e = self.entries.get(c)
            if e is not None:
                out[c] = [e.serial, e.sensitivity, e.calibrated.isoformat() if e.calibrated else None,
                          e.due.isoformat() if e.due else None, e.source]
                if e.overdue(today):
                    late.append(c)
        return {"calibration": {"sheet": Path(self.sheet).name if self.sheet else None,
                                "fields": ["serial", "sensitivity", "calibration_date", "due_date", "source"],
                                "channels": out, "overdue": late}} if out else {}


def _date(text: str, src: str, key: str) -> dt.date | None:
    t = (text or "").strip()
    if not t:
        return None
    try:
        return dt.date.fromisoformat(t)
    except ValueError:
        raise UserError(f"value {t!r}: expected a date YYYY-MM-DD", file=src, key=key) from None


def read_sheet(path: str | Path, rig: Rig | None = None) -> Calibration:
    """Read and validate a calibration sheet; with ``rig``, every row's channel must be one
    of its channels and its unit match the channel's kind."""
    p = Path(path)
    # a regular file of at most 16 MiB (issue 27: every parser bounded; /dev/zero is refused)
    text = read_text_file(p, "the calibration sheet (CSV) the rig file names").removeprefix("\ufeff")
    return parse_sheet(text, str(p), rig)


def parse_sheet(text: str, src: str = "<sheet>", rig: Rig | None = None) -> Calibration:
    """A calibration sheet from its CSV text (see the module docstring)."""
    rows = [r for r in csv.reader(io.StringIO(text)) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise UserError(f"empty; expected the header {','.join(COLUMNS)}", file=src)
    head = [h.strip().lower() for h in rows[0]]
    missing = [c for c in COLUMNS if c not in head]
    if missing:
        raise UserError(f"missing column(s) {missing}; expected the header {','.join(COLUMNS)}",
                        file=src, key="header")
    col = {c: head.index(c) for c in COLUMNS}
    kinds = {c.name: c.kind for d in rig.devices for c in d.channels} if rig is not None else {}
    entries: dict[str, CalEntry] = {}
    for i, r in enumerate(rows[1:], start=2):
        r = r + [""] * (len(head) - len(r))
        get = {c: r[col[c]].strip() for c in COLUMNS}
        where = f"line {i}"
        ch = get["channel"]
        if not ch:
            raise UserError("empty channel; expected a rig channel name", file=src, key=f"{where}.channel")
        if ch in entries:
            raise UserError(f"value {ch!r}: channel listed twice; expected one row per channel",
                            file=src, key=f"{where}.channel")
        if rig is not None and ch not in kinds:
            raise UserError(f"value {ch!r}: not a channel of the rig; expected one of {sorted(kinds)}",
                            file=src, key=f"{where}.channel")
        try:
            value = float(get["sensitivity"])
        except ValueError:
            value = float("nan")
        if not value > 0 or value == float("inf"):
            raise UserError(f"value {get['sensitivity']!r}: expected a positive sensitivity",
                            file=src, key=f"{where}.sensitivity")
        conv = sensitivity_si(value, get["unit"])
        if conv is None:
            raise UserError(f"value {get['unit']!r}: expected a sensitivity unit such as mV/g, V/(m/s^2), "
                            "mV/N, V/N or V/V", file=src, key=f"{where}.unit")
        quantity, si = conv
        if ch in kinds and QUANTITY[kinds[ch]] != quantity:
            raise UserError(f"value {get['unit']!r}: a sensitivity to {quantity} for the {kinds[ch]} channel "
                            f"{ch!r}; expected V per {QUANTITY[kinds[ch]]} unit", file=src, key=f"{where}.unit")
        cal = _date(get["calibration_date"], src, f"{where}.calibration_date")
        due = _date(get["due_date"], src, f"{where}.due_date")
        if cal and due and due < cal:
            raise UserError(f"due date {due} before the calibration date {cal}; expected due >= calibrated",
                            file=src, key=f"{where}.due_date")
        entries[ch] = CalEntry(ch, get["serial"], si, f"{value:g} {get['unit']}", cal, due, "sheet")
    return Calibration(src, text, entries)


def sheet_path(rig: Rig) -> Path | None:
    """The calibration sheet a rig refers to, resolved against the rig file's folder."""
    if not rig.calibration:
        return None
    p = Path(rig.calibration)
    if p.is_absolute():
        return p
    src = Path(rig.source)
    base = src.parent if rig.source and not rig.source.startswith(("builtin:", "<")) and "#" not in rig.source \
        else Path(".")
    return base / p


#: (device spec, channel config, channel index) -> drivers.nidaq.TedsInfo or None
Teds = Callable[[object, object, int], "TedsInfo | None"]


def nidaq_teds(nidaqmx_module=None) -> Teds:
    """A TEDS reader for ``calibrate``: ``drivers.nidaq.read_teds`` on each channel's DAQmx
    physical channel (as ``NiDaqDevice`` names it)."""
    def teds(dev, c, index):
        daq = dev.daq_device or next((x.physical.split("/")[0] for x in dev.channels if "/" in x.physical), "Dev1")
        return read_teds(physical_name(daq, c, index), c.kind, nidaqmx_module=nidaqmx_module)
    return teds


def calibrate(rig: Rig, teds: Teds | None = None) -> tuple[Rig, Calibration | None]:
    """The rig with its channels' sensitivities from the calibration sheet (and TEDS where
    ``teds(device, channel, index)`` returns a ``drivers.nidaq.TedsInfo``), and the
    calibration used (None when the rig has neither)."""
    path = sheet_path(rig)
    cal = read_sheet(path, rig) if path is not None else Calibration(None, "")
    entries = dict(cal.entries)
    notes = list(cal.notes)
    if teds is not None:
        for d in rig.devices:
            for i, c in enumerate(d.channels):
                info = teds(d, c, i)
                if info is None or info.sensitivity is None:
                    continue
                sheet = entries.get(c.name)
                if sheet is None:
                    entries[c.name] = CalEntry(c.name, str(info.serial), float(info.sensitivity),
                                               f"TEDS {info.sensitivity:.6g} V/{QUANTITY[c.kind]} SI unit",
                                               None, None, "teds")
                    notes.append(f"{c.name}: sensitivity {info.sensitivity:.6g} from TEDS (serial {info.serial})")
                    continue
                if str(info.serial) != sheet.serial:
                    notes.append(f"warning: {c.name}: TEDS serial {info.serial} but the calibration sheet says "
                                 f"{sheet.serial!r}: is the right sensor connected?")
                if abs(info.sensitivity - sheet.sensitivity) > TEDS_TOLERANCE * sheet.sensitivity:
                    notes.append(f"warning: {c.name}: TEDS sensitivity {info.sensitivity:.6g} differs from the "
                                 f"sheet's {sheet.sensitivity:.6g} by more than {TEDS_TOLERANCE:.0%}; "
                                 "the sheet's is used")
    if not entries:
        return rig, None
    devices = []
    for d in rig.devices:
        chans = []
        for c in d.channels:
            e = entries.get(c.name)
            if e is not None and e.sensitivity != c.sensitivity:
                if e.source == "sheet":
                    notes.append(f"{c.name}: sensitivity {e.sensitivity:.6g} from the calibration sheet "
                                 f"(serial {e.serial}; the rig file says {c.sensitivity:.6g})")
                c = replace(c, sensitivity=e.sensitivity)
            chans.append(c)
        devices.append(replace(d, channels=tuple(chans)))
    cal = Calibration(str(path) if path else None, cal.text, entries, tuple(notes))
    return replace(rig, devices=tuple(devices)), cal


_WARNED: set[tuple] = set()


def overdue_lines(cal: Calibration | None, today: dt.date | None = None) -> list[str]:
    """One line per overdue calibration of ``cal``."""
    if cal is None:
        return []
    today = today or dt.date.today()
    return [f"calibration of {e.channel} (serial {e.serial}) was due on {e.due.isoformat()}, "
            f"{(today - e.due).days} day(s) ago; the sensitivity used is {e.sensitivity:.6g}"
            for e in cal.overdue(today)]


def warn_lines(lines: Iterable[str], sheet: str | None = None, write: Callable[[str], object] | None = None,
               prefix: str = "labid") -> list[str]:
    """Write each line once per process (the session) to ``write`` (default stderr) as a
    warning; returns the lines written this time."""
    write = write or sys.stderr.write
    out = []
    for line in lines:
        key = (sheet, line.split(" was due")[0])
        if key in _WARNED:
            continue
        _WARNED.add(key)
        write(f"{prefix}: warning: {line}\n")
        out.append(line)
    return out


def status(cal: Calibration | None, today: dt.date | None = None) -> dict:
    """What the panel and the report show: the sheet, every entry and the overdue lines."""
    if cal is None:
        return {"sheet": None, "entries": [], "overdue": [], "notes": []}
    return {"sheet": cal.sheet, "entries": [e.to_dict() for e in cal.entries.values()],
            "overdue": overdue_lines(cal, today), "notes": list(cal.notes)}


def from_shot_meta(metas: Iterable[dict]) -> dict[str, dict]:
    """The calibration each channel was recorded with, from the shot metas of a run
    (the last shot that names it): {channel: {serial, sensitivity, calibration_date, due_date,
    source}}."""
    out: dict[str, dict] = {}
    for m in metas:
        c = (m or {}).get("calibration")
        if not isinstance(c, dict):
            continue
        fields = c.get("fields") or []
        for ch, vals in (c.get("channels") or {}).items():
            out[ch] = dict(zip(fields, vals))
    return out


def overdue_in_metas(metas: Iterable[dict]) -> list[str]:
    """One line per channel recorded past its calibration's due date, from shot metas."""
    out: dict[str, str] = {}
    for m in metas:
        c = (m or {}).get("calibration")
        if not isinstance(c, dict):
            continue
        fields = c.get("fields") or []
        for ch in c.get("overdue") or []:
            e = dict(zip(fields, (c.get("channels") or {}).get(ch, [])))
            out.setdefault(ch, f"{ch} (serial {e.get('serial')}) was recorded after its calibration due date "
                               f"{e.get('due_date')}")
    return list(out.values())
