"""``labid import``: recordings of other systems into a run file, under a rig file.

``import_records(files, rig, specimen, out, ...)`` reads the files (``labid.io.readers``),
maps their channels onto the rig's (``--map 'file_channel=rig_channel,...'``), checks the
sampling rate, the pre-trigger, the lengths and the units, converts the samples to the
volts at the ADC input that a run stores (``volts = value x unit factor x sensitivity``,
the sensitivity from the calibration sheet when the rig names one) and appends the shots
through ``RunStore`` (``declare`` + ``append_shot``), so that ``labid analyze`` reads them
as it reads acquired shots.

Files: a folder stands for the recordings in it (the files of a known suffix, in name
order). Without ``--map``, the file channels named as rig channels (a CSV column with or
without its unit suffix) are imported; when they belong to several devices (a UFF file
written by ``labid export`` holds hammer and wave shots) each device's become shots of
its kind, all written in one session once every check has passed.

Shots. Each map key is looked up in every file, in the order given: the n-th record of
every mapped channel makes shot n. Several files on a common trigger (one channel or a
few each) make one shot; files holding the same channels (one hit each), or a file of
several records of each channel (UFF58 data sets, TDMS groups), make several shots. A key
``FILE:channel`` (FILE: a file's name or stem) looks in that file only; a CSV column is
named by its header with or without its unit suffix (``force [N]`` or ``force``).

Rate, pre-trigger, units: from the file where it states them, else from ``--rate``,
``--pretrigger``, ``--units`` (a file and an option that disagree are refused), else the
rate and pre-trigger of the rig's device (said in the notes); a unit is required. A rate
must equal the rig device's to 1e-4 (files keep rates to a few digits: UFF58 to six); the
run stores the rig's. Records of different lengths or pre-triggers are refused unless
``crop``: then all are cut to the span every record covers around its trigger.
"""
from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from drivers.protocol import Record, Timing

from ..base.errors import UserError
from ..inputs.rig import Rig, load_rig
from ..inputs.specimen import Specimen, load_specimen, specimen_text
from ..store import RunStore
from ..inputs import calibration as calib
from .readers import FORMATS, Column, read_columns, split_header
from ..inputs.units import QUANTITY, known_units, parse_unit, unit_matches

#: relative tolerance between a file's sampling rate and the rig's (files keep 6 digits or fewer)
RATE_TOLERANCE = 1e-4
#: a sample at or beyond this fraction of the channel's range flags it overloaded (as drivers.nidaq)
CLIP_FRACTION = 0.999
_META_BUDGET = 3800       # bytes of the 4096 a shot's meta may hold


@dataclass
class ImportResult:
    """What ``import_records`` wrote: the run, the kind and names of the shots, the
    channel map, the timing and units used, and notes for the user."""

    out: str
    kind: str
    shots: list[str]
    channels: dict[str, str]
    rate_hz: float
    samples: int
    pretrigger: int
    units: dict[str, str]
    notes: list[str] = field(default_factory=list)
    calibration: dict = field(default_factory=dict)
    parts: list["ImportResult"] = field(default_factory=list)

    def to_dict(self) -> dict:
        out = {"out": self.out, "kind": self.kind, "shots": self.shots, "channels": self.channels,
               "rate_hz": self.rate_hz, "samples": self.samples, "pretrigger": self.pretrigger,
               "units": self.units, "notes": self.notes, "calibration": self.calibration}
        if self.parts:             # several devices in one import: each kind's own figures
            out["parts"] = [p.to_dict() for p in self.parts]
        return out


@dataclass
class _Plan:
    """The shots of one device, checked and converted, ready to be written."""

    kind: str
    chans: tuple
    timing: Timing
    trigger: object
    records: list
    keys: dict
    units: dict
    notes: list


def expand_files(files: Sequence[str | Path]) -> list[Path]:
    """The recordings named: a folder stands for its files of a known suffix, in name order."""
    out: list[Path] = []
    for f in map(Path, files):
        if f.is_dir():
            inside = sorted(p for p in f.iterdir() if p.is_file() and p.suffix.lower() in FORMATS)
            if not inside:
                raise UserError(f"a folder holding no recording; expected files ending in {sorted(FORMATS)}",
                                file=str(f))
            out += inside
        else:
            out.append(f)
    return out


def parse_pairs(text: str | None, option: str) -> list[tuple[str, str]]:
    """'a=b,c=d' -> [(a, b), (c, d)] (split on the last '=' of each item)."""
    out = []
    for item in (text or "").split(","):
        if not item.strip():
            continue
        left, eq, right = item.rpartition("=")
        if not eq or not left.strip() or not right.strip():
            raise UserError(f"value {item.strip()!r}: expected NAME=VALUE", key=option)
        out.append((left.strip(), right.strip()))
    return out


def _find(key: str, files: Sequence[Path], columns: dict[Path, list[Column]]) -> list[Column]:
    """The columns a map key names, in file order (``FILE:channel`` restricts to one file)."""
    scope, name = list(files), key
    if ":" in key:
        prefix, rest = key.split(":", 1)
        hit = [f for f in files if prefix in (f.name, f.stem)]
        if hit:
            scope, name = hit, rest
    out = []
    for f in scope:
        out += [c for c in columns[f] if name in (c.qualified, c.name, split_header(c.name)[0])]
    return out


def _pretrigger(c: Column, rate: float) -> int | None:
    if c.t0_s is None:
        return None
    pre = -c.t0_s * rate
    if pre < -0.5:
        raise UserError(f"record starts {c.t0_s:g} s after its trigger; expected the trigger within the record",
                        file=str(c.file), key=c.qualified)
    return int(round(pre))


def import_records(files: Sequence[str | Path], rig: Rig | str, specimen: Specimen | str, out: str | Path,
                   map_text: str | None = None, *, rate_hz: float | None = None, pretrigger: int | None = None,
                   units_text: str | None = None, kind: str | None = None, crop: bool = False) -> ImportResult:
    """Import ``files`` into the run ``out`` (created or appended to) under ``rig`` and
    ``specimen``; see the module docstring. UserError (one line) on any mismatch."""
    files = expand_files(files)
    if not files:
        raise UserError("no file to import; expected one or more recordings", key="FILES")
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise UserError(f"value {rate_hz!r}: expected a positive sample rate in Hz", key="--rate")
    if pretrigger is not None and pretrigger < 0:
        raise UserError(f"value {pretrigger!r}: expected a non-negative number of samples", key="--pretrigger")
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    specimen = specimen if isinstance(specimen, Specimen) else load_specimen(specimen)
    rig.check_specimen(specimen.length, specimen.width)
    rig, cal = calib.calibrate(rig)
    notes = list(cal.notes) if cal else []
    columns = {f: read_columns(f) for f in files}
    rig_chans = {c.name: (d, c) for d in rig.devices for c in d.channels}

    # -- the channel map (without --map: one group per device whose channels the files name)
    pairs = parse_pairs(map_text, "--map")
    groups = [pairs] if pairs else _auto_map(files, columns, rig, rig_chans, kind, notes)
    plans = [_plan(g, files, columns, rig, rig_chans, cal, kind, rate_hz, pretrigger, units_text, crop,
                   len(groups) > 1) for g in groups]
    out = Path(out)
    results = []
    with RunStore(out, "a") as st:
        st.write_config(specimen_text(specimen), rig.text)
        if cal is not None and cal.text:
            st.write_config_text("calibration_csv", cal.text)
        for pl in plans:
            st.declare(pl.kind, pl.chans, pl.timing, pl.trigger)
            names = [st.append_shot(rec, pl.kind) for rec in pl.records]
            results.append(ImportResult(str(out), pl.kind, names, {t: pl.keys[t] for t in pl.keys},
                                        pl.timing.rate_hz, pl.timing.samples, pl.timing.pretrigger, pl.units,
                                        pl.notes, calib.status(cal)))
    if len(results) == 1:
        res = results[0]
        res.notes = notes + res.notes
        return res
    first = results[0]
    return ImportResult(str(out), "+".join(r.kind for r in results), [n for r in results for n in r.shots],
                        {t: k for r in results for t, k in r.channels.items()}, first.rate_hz, first.samples,
                        first.pretrigger, {t: u for r in results for t, u in r.units.items()},
                        notes + [n for r in results for n in r.notes], calib.status(cal), results)


def _auto_map(files: list[Path], columns: dict, rig: Rig, rig_chans: dict, kind: str | None,
              notes: list[str]) -> list[list[tuple[str, str]]]:
    """The channel map without --map: file channels named as rig channels (a CSV header
    with or without its unit suffix), one group per device (only ``kind``'s when given)."""
    seen: dict[str, str] = {}
    for c in (c for f in files for c in columns[f]):
        for name in (c.name, split_header(c.name)[0]):
            if name in rig_chans and name not in seen.values() and (
                    kind is None or rig_chans[name][0].role == kind):
                seen[c.name] = name
                break
    if not seen:
        avail = sorted({c.qualified for f in files for c in columns[f]})
        raise UserError(f"no file channel is named like a rig channel; expected --map 'file_channel=rig_channel,"
                        f"...' (file channels: {', '.join(avail[:12])}; rig channels: {', '.join(rig_chans)})",
                        key="--map")
    notes.append("no --map: file channels named as rig channels (" + ", ".join(
        k if k == t else f"{k} -> {t}" for k, t in seen.items()) + ")")
    by_dev: dict[str, list[tuple[str, str]]] = {}
    for key, target in seen.items():
        by_dev.setdefault(rig_chans[target][0].name, []).append((key, target))
    return [by_dev[d.name] for d in rig.devices if d.name in by_dev]


def _plan(pairs: list[tuple[str, str]], files: list[Path], columns: dict, rig: Rig, rig_chans: dict, cal,
          kind: str | None, rate_hz: float | None, pretrigger: int | None, units_text: str | None,
          crop: bool, several: bool = False) -> _Plan:
    """The checked and converted shots of one device from the channel map ``pairs``
    (``several``: one of several devices imported together)."""
    notes: list[str] = []
    found: dict[str, list[Column]] = {}
    keys: dict[str, str] = {}
    for key, target in pairs:
        if target not in rig_chans:
            raise UserError(f"value {target!r}: unknown rig channel; expected one of {list(rig_chans)}",
                            file=rig.source, key=f"--map {key}")
        if target in found:
            raise UserError(f"rig channel {target!r} mapped twice; expected one file channel per rig channel",
                            key="--map")
        cols = _find(key, files, columns)
        if not cols:
            avail = sorted({c.qualified for f in files for c in columns[f]})
            raise UserError(f"value {key!r}: no such channel in the files; expected one of "
                            f"{', '.join(avail[:20])}" + (" ..." if len(avail) > 20 else ""), key="--map")
        found[target], keys[target] = cols, key
    devs = {rig_chans[t][0].name for t in found}
    if len(devs) > 1:
        raise UserError(f"the mapped channels belong to devices {sorted(devs)}; expected the channels of one "
                        "device (import hammer and wave records separately)", key="--map")
    dev = rig_chans[next(iter(found))][0]
    if kind is not None and kind != dev.role:
        raise UserError(f"value {kind!r}: the mapped channels are on device {dev.name!r} of role {dev.role!r}",
                        file=rig.source, key="--kind")
    kind = dev.role
    counts = {t: len(c) for t, c in found.items()}
    if len(set(counts.values())) != 1:
        raise UserError("channels found a different number of times: " + ", ".join(
            f"{keys[t]} x{n}" for t, n in counts.items()) + "; expected each mapped channel once per shot",
                        key="--map")
    n_shots = next(iter(counts.values()))

    # -- rate, pre-trigger, units
    rate = float(dev.timing.rate_hz)
    for t, cols in found.items():
        for c in cols:
            if c.rate_hz is not None and rate_hz is not None and abs(c.rate_hz - rate_hz) > RATE_TOLERANCE * rate_hz:
                raise UserError(f"sample rate {c.rate_hz:.9g} Hz in the file, {rate_hz:g} Hz given; expected one rate",
                                file=str(c.file), key=c.qualified)
            r = c.rate_hz if c.rate_hz is not None else rate_hz
            if r is not None and abs(r - rate) > RATE_TOLERANCE * rate:
                raise UserError(f"sample rate {r:.9g} Hz differs from the {rate:g} Hz of device {dev.name!r}; "
                                "expected the rig's rate (or a rig file for this recording)",
                                file=str(c.file), key=c.qualified)
    if all(c.rate_hz is None for cols in found.values() for c in cols) and rate_hz is None:
        notes.append(f"sample rate {rate:g} Hz from the rig file (the files do not state it)")
    pre_opt = pretrigger
    pres: dict[tuple[str, int], int] = {}
    fallback = False
    for t, cols in found.items():
        for i, c in enumerate(cols):
            p = _pretrigger(c, rate)
            if p is not None and pre_opt is not None and p != pre_opt:
                raise UserError(f"pre-trigger {p} samples in the file, {pre_opt} given; expected one pre-trigger",
                                file=str(c.file), key=c.qualified)
            if p is not None and abs(-c.t0_s * rate - p) > 1e-3:
                notes.append(f"{c.where}: its trigger lies {(-c.t0_s * rate - p):+.2f} sample off the sample grid; "
                             "aligned to the nearest sample")
            if p is None:
                p = pre_opt if pre_opt is not None else int(dev.timing.pretrigger)
                fallback = fallback or pre_opt is None
            pres[(t, i)] = p
    if fallback:
        notes.append(f"pre-trigger {dev.timing.pretrigger} samples from the rig file (not in the files nor "
                     "--pretrigger)")
    unit_opt = dict(parse_pairs(units_text, "--units"))
    for u in unit_opt:
        if u not in found and not (several and u in rig_chans):   # several: another device's channel
            raise UserError(f"value {u!r}: not a mapped rig channel; expected one of {list(found)}", key="--units")
    factors: dict[tuple[str, int], tuple[str, float]] = {}
    units_used: dict[str, str] = {}
    for t, cols in found.items():
        ch = rig_chans[t][1]
        for i, c in enumerate(cols):
            u = c.unit
            if u is not None and t in unit_opt and parse_unit(u) != parse_unit(unit_opt[t]):
                raise UserError(f"unit {u!r} in the file, {unit_opt[t]!r} given for {t}; expected one unit",
                                file=str(c.file), key=c.qualified)
            u = u if u is not None else unit_opt.get(t)
            if u is None:
                hint = " (a WAV sample is a fraction of full scale: give the full scale, e.g. 2.5V)" \
                    if c.fmt == "wav" else ""
                raise UserError(f"no unit in the file; expected --units {t}=UNIT, UNIT one of "
                                f"{', '.join(known_units())}{hint}", file=str(c.file), key=c.qualified)
            q = parse_unit(u)
            if q is None:
                raise UserError(f"unit {u!r}: not recognised; expected one of {', '.join(known_units())}",
                                file=str(c.file), key=c.qualified)
            if not unit_matches(ch.kind, q[0]):
                raise UserError(f"unit {u!r} measures {q[0]} but {t} is a {ch.kind} channel; expected "
                                f"{QUANTITY[ch.kind]} or volts", file=str(c.file), key=c.qualified)
            factors[(t, i)] = q
            units_used[t] = u

    # -- lengths and alignment on the trigger
    for (t, i), p in pres.items():
        c = found[t][i]
        if p >= c.data.size:
            src = "given" if pre_opt is not None else "stated" if c.t0_s is not None else "the rig's"
            raise UserError(f"pre-trigger {p} samples ({src}), but the record holds {c.data.size}; expected the "
                            "trigger within the record (--pretrigger below its length)",
                            file=str(c.file), key=c.qualified)
    spans = {k: (pres[k], found[k[0]][k[1]].data.size - pres[k]) for k in pres}
    if len(set(spans.values())) != 1:
        if not crop:
            (k1, s1), (k2, s2) = next(iter(spans.items())), next((k, s) for k, s in spans.items()
                                                                 if s != next(iter(spans.values())))
            c1, c2 = found[k1[0]][k1[1]], found[k2[0]][k2[1]]
            raise UserError(f"{s2[0] + s2[1]} samples with {s2[0]} before the trigger, but {c1.where} has "
                            f"{s1[0] + s1[1]} with {s1[0]}; expected records of one length on a common trigger "
                            "(or --crop to keep the span they share)", file=str(c2.file), key=c2.qualified)
        before = min(s[0] for s in spans.values())
        after = min(s[1] for s in spans.values())
        if after < 2:
            raise UserError("the records share no span after their trigger; expected overlapping records",
                            key="--crop")
        notes.append(f"cropped to the common span: {before} samples before the trigger, {after} from it")
    else:
        before, after = next(iter(spans.values()))
    n = before + after
    if n < 2:
        raise UserError(f"{n} sample(s); expected at least 2", file=str(files[0]))

    # -- the records
    chans = tuple(c for c in dev.channels if c.name in found)
    timing = Timing(rate, n, before)
    trigger = dev.trigger if dev.trigger is not None and dev.trigger.channel in found else None
    fmt = {c.fmt for cols in found.values() for c in cols}
    records = []
    over_notes = []
    for i in range(n_shots):
        data, over = {}, {}
        src = {}
        stamp = None
        for ch in chans:
            c = found[ch.name][i]
            k0 = pres[(ch.name, i)] - before
            x = c.data[k0:k0 + n]
            quantity, f = factors[(ch.name, i)]
            volts = x * f if quantity == "voltage" else x * f * ch.sensitivity
            data[ch.name] = np.asarray(volts, float)
            over[ch.name] = bool(np.any(np.abs(volts) >= CLIP_FRACTION * ch.range_v))
            if over[ch.name]:
                over_notes.append(f"shot {i + 1}: {ch.name} reaches {np.max(np.abs(volts)):.4g} V, the +/-"
                                  f"{ch.range_v:g} V range of the rig: flagged overloaded")
            src[ch.name] = f"{c.file.name}:{c.qualified}"
            stamp = stamp if stamp is not None else c.timestamp
        if stamp is None:
            stamp = os.path.getmtime(found[chans[0].name][i].file)
        meta = {"imported": {"format": "+".join(sorted(fmt)), "channels": src,
                             "units": {c: units_used[c] for c in src}}}
        if cal is not None:
            meta.update(cal.meta(src))
        records.append(Record(data=data, channels=chans, timing=timing, trigger=trigger, overload=over,
                              timestamp=float(stamp), backend=f"import:{'+'.join(sorted(fmt))}"[:32],
                              meta=_fit_meta(meta)))
    notes += over_notes
    return _Plan(kind, chans, timing, trigger, records, {t: keys[t] for t in found}, units_used, notes)


def _fit_meta(meta: dict) -> dict:
    """The shot meta within the store's 4 kB: long source names are shortened first."""
    if len(json.dumps(meta).encode()) <= _META_BUDGET:
        return meta
    src = meta["imported"]["channels"]
    meta["imported"]["channels"] = {k: re.sub(r"^(.{20}).*(.{20})$", r"\1...\2", v) for k, v in src.items()}
    if len(json.dumps(meta).encode()) > _META_BUDGET:
        meta["imported"].pop("channels")
    return meta
