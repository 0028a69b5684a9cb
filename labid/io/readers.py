"""Readers of recordings made by other systems, each through its field's library.

Every reader returns the file's channels as ``Column`` objects: the samples (float64),
the sampling rate, the time of the first sample relative to the trigger and the unit,
each where the file states it (None otherwise).

| format | library | rate | pre-trigger | unit |
| --- | --- | --- | --- | --- |
| NI TDMS (``.tdms``) | npTDMS | ``wf_increment`` | ``wf_start_offset`` < 0 | ``unit_string`` |
| UFF58 time data (``.uff``, ``.unv``) | pyuff | abscissa increment | abscissa minimum < 0 | ordinate units label |
| WAV (``.wav``) | scipy.io.wavfile | the header's rate | - | - (samples are fractions of full scale) |
| MAT (``.mat``, v4-v7.2) | scipy.io | a scalar ``fs``/``Fs``/``rate_hz``/``sample_rate``/``dt`` or a ``t``/``time`` vector | the time vector's start < 0 | - |
| CSV (``.csv``, ``.txt``) | numpy (+ csv.Sniffer for the delimiter) | a ``time``/``t`` column | the time column's start < 0 | header suffix ``name_mV``, ``name [N]``, ``name (g)`` |

A time axis starting at zero says nothing about a pre-trigger (most writers start every
record at zero): only a negative start gives one. UFF58 keeps the abscissa to 6 digits, so
rates read from files are compared with the rig's to 1e-4 (``labid.io.importers``).

CSV as European labs write it is read too: ``;`` between columns and a decimal comma
(``1,5;2,25``). A file a library cannot read is one ``UserError`` naming it (whatever the
library raised), and the libraries' own warnings (scipy's WavFileWarning, npTDMS's log)
are kept off the console (issue 26 item 8, issue 27).
"""
from __future__ import annotations

import contextlib
import csv
import logging
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import UserError
from ..inputs.units import parse_unit, time_factor

FORMATS = {".tdms": "tdms", ".uff": "uff", ".unv": "uff", ".wav": "wav", ".mat": "mat",
           ".csv": "csv", ".txt": "csv"}
RATE_NAMES = ("fs", "Fs", "FS", "rate", "rate_hz", "sample_rate", "sampling_rate", "samplerate",
              "SampleRate", "sample_rate_hz")
DT_NAMES = ("dt", "Ts", "ts", "dt_s")
TIME_NAMES = ("t", "time", "Time", "time_s", "t_s")


@dataclass
class Column:
    """One channel of one record in a file.

    name: as the file names it (CSV header, TDMS channel, UFF58 ID line 1, MAT variable,
    WAV channel number from 1); qualified: 'group/name' for TDMS, 'var/k' for a MAT
    matrix column, else the name. data: samples (float64). rate_hz: Hz, None if the
    file does not say. t0_s: time of the first sample relative to the trigger (s), None
    if not stated. unit: unit text from the file, None if none. timestamp: Unix time of
    the record if the file says. fmt: the format ('tdms', 'uff', 'wav', 'mat', 'csv').
    """

    file: Path
    name: str
    qualified: str
    data: np.ndarray
    rate_hz: float | None = None
    t0_s: float | None = None
    unit: str | None = None
    timestamp: float | None = None
    fmt: str = ""

    @property
    def where(self) -> str:
        return f"{self.file.name}: {self.qualified}"


def file_format(path: str | Path) -> str:
    """The format of a file from its suffix; UserError for an unknown one."""
    p = Path(path)
    fmt = FORMATS.get(p.suffix.lower())
    if fmt is None:
        raise UserError(f"unknown format {p.suffix!r}; expected one of {sorted(FORMATS)}", file=str(p))
    return fmt


def read_columns(path: str | Path) -> list[Column]:
    """Every channel of every record in ``path`` (format from the suffix)."""
    p = Path(path)
    if p.is_dir():
        raise UserError("a folder; expected a recording (TDMS, UFF58, WAV, MAT or CSV) or a folder of them "
                        "given to labid import", file=str(p))
    if not p.is_file():
        raise UserError("file not found; expected a recording (TDMS, UFF58, WAV, MAT or CSV)", file=str(p))
    fmt = file_format(p)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")       # a damaged file's casts: the checks below say what is wrong
        cols = {"tdms": read_tdms, "uff": read_uff58, "wav": read_wav, "mat": read_mat, "csv": read_csv}[fmt](p)
    if not cols:
        raise UserError("holds no channel of samples", file=str(p))
    for c in cols:
        c.fmt = fmt
        if not np.all(np.isfinite(c.data)):
            raise UserError(f"{int(np.sum(~np.isfinite(c.data)))} sample(s) not finite (NaN or infinite); "
                            "expected numbers", file=str(p), key=c.qualified)
    return cols


def _rate(inc: float | None, p: Path, key: str) -> float | None:
    if inc is None:
        return None
    inc = float(inc)
    if not (np.isfinite(inc) and inc > 0):
        raise UserError(f"value {inc!r}: expected a positive sample interval in s", file=str(p), key=key)
    return 1.0 / inc


@contextlib.contextmanager
def _quiet_nptdms():
    """npTDMS logs its warnings on stderr through its own handler: silenced while reading
    (the one line of the error, if any, says what went wrong)."""
    from nptdms.log import log_manager  # noqa: PLC0415 - only when a TDMS file is imported
    level = log_manager.log_level
    log_manager.set_level(logging.ERROR)
    try:
        yield
    finally:
        log_manager.set_level(level)


# ------------------------------------------------------------------ TDMS (npTDMS)
def read_tdms(p: Path) -> list[Column]:
    """NI TDMS: every numeric channel of every group (npTDMS applies the DAQmx scaling it
    finds); channels of text or timestamps are left out."""
    from nptdms import TdmsFile  # noqa: PLC0415 - only when a TDMS file is imported
    out = []
    with _quiet_nptdms():
        try:
            f = TdmsFile.read(p)
            chans = [(g, ch, ch[:]) for g in f.groups() for ch in g.channels()]
        except Exception as e:  # noqa: BLE001 - npTDMS raises bare ValueError/KeyError on bad files
            raise UserError(f"not a readable TDMS file ({type(e).__name__}: {e})", file=str(p)) from None
    for g, ch, raw in chans:
        props = ch.properties
        raw = np.asarray(raw)
        if raw.dtype.kind not in "iufb" or raw.ndim != 1 or raw.size < 2:
            continue
        data = raw.astype(float)
        key = f"{g.name}/{ch.name}"
        rate = _rate(_number(props.get("wf_increment"), p, f"{key}: wf_increment"), p, f"{key}: wf_increment")
        off = _number(props.get("wf_start_offset"), p, f"{key}: wf_start_offset")
        t0 = float(off) if off is not None and rate is not None and float(off) != 0.0 else None
        unit = props.get("unit_string") or props.get("NI_UnitDescription") or None
        ts = props.get("wf_start_time")
        stamp = None
        if ts is not None:
            try:
                stamp = float((np.datetime64(ts, "ns") - np.datetime64(0, "s")) / np.timedelta64(1, "s"))
            except (TypeError, ValueError):
                stamp = None
        out.append(Column(p, ch.name, key, data, rate, t0, str(unit) if unit else None, stamp))
    return out


def _number(v, p: Path, key: str) -> float | None:
    """A numeric property of a file (None if absent); UserError for text or the like."""
    if v is None:
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        raise UserError(f"value {v!r}: expected a number", file=str(p), key=key) from None


# ------------------------------------------------------------------ UFF58 (pyuff)
_DIRS = {1: "X+", -1: "X-", 2: "Y+", -2: "Y-", 3: "Z+", -3: "Z-", 0: "S"}


def read_uff58(p: Path) -> list[Column]:
    """UFF58 time responses (function type 1); other data sets (FRFs, modes) are skipped.
    Name: ID line 1, or '<node><dir>' (e.g. '3Z+') when it is empty."""
    import pyuff  # noqa: PLC0415 - only when a UFF file is imported
    try:
        sets = pyuff.UFF(str(p)).read_sets()
    except Exception as e:  # noqa: BLE001 - pyuff raises bare Exception on bad files
        raise UserError(f"not a readable UFF file ({e})", file=str(p)) from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    out = []
    for i, s in enumerate(sets):
        if s.get("type") != 58 or int(s.get("func_type", -1)) != 1:
            continue
        name = str(s.get("id1", "")).strip()
        if not name or name == "NONE":
            name = f"{s.get('rsp_node', i + 1)}{_DIRS.get(int(s.get('rsp_dir', 0)), '')}"
        data = np.asarray(s["data"])
        if np.iscomplexobj(data):
            raise UserError(f"data set {i + 1} ({name}): complex time data; expected a real time response",
                            file=str(p))
        x = np.asarray(s.get("x"), float)
        inc = float(s.get("abscissa_inc") or 0.0) or (float(x[1] - x[0]) if x.size > 1 else None)
        rate = _rate(inc, p, f"data set {i + 1}: abscissa increment")
        x0 = float(s.get("abscissa_min", x[0] if x.size else 0.0))
        unit = str(s.get("ordinate_axis_units_lab", "")).strip()
        out.append(Column(p, name, name, data.astype(float), rate, x0 if x0 != 0.0 else None,
                          unit if unit and unit != "NONE" else None))
    if not out and sets:
        raise UserError("holds no UFF58 time response (function type 1); expected time data", file=str(p))
    return out


# ------------------------------------------------------------------ WAV (scipy.io.wavfile)
def read_wav(p: Path) -> list[Column]:
    """WAV: channels '1', '2', ... as fractions of full scale (integer PCM divided by
    2^(bits-1), 8-bit unsigned about 128; float as stored). The unit is the full scale,
    given by --units (e.g. 2.5V)."""
    from scipy.io import wavfile  # noqa: PLC0415 - only when a WAV file is imported
    try:
        with warnings.catch_warnings():       # WavFileWarning on chunks it skips (float WAVs' 'fact')
            warnings.simplefilter("ignore", wavfile.WavFileWarning)
            rate, x = wavfile.read(p)
    except Exception as e:  # noqa: BLE001 - scipy's reader raises many kinds on a damaged file
        raise UserError(f"not a readable WAV file ({type(e).__name__}: {e})", file=str(p)) from None
    if x.size == 0 or not rate > 0:
        raise UserError(f"holds no samples ({x.shape[0] if x.ndim else 0} frames at {rate} Hz); expected a "
                        "recording", file=str(p))
    if x.dtype.kind == "u":
        x = (x.astype(float) - 128.0) / 128.0
    elif x.dtype.kind == "i":
        x = x.astype(float) / float(2 ** (8 * x.dtype.itemsize - 1))
    else:
        x = x.astype(float)
    x = x.reshape(len(x), -1)
    return [Column(p, str(k + 1), str(k + 1), x[:, k].copy(), float(rate)) for k in range(x.shape[1])]


# ------------------------------------------------------------------ MAT (scipy.io)
def read_mat(p: Path) -> list[Column]:
    """MAT (v4 to v7.2): every numeric vector is a channel, every matrix gives one channel per
    column ('var/1', ...; the longer dimension is time). The rate from a scalar ``fs``
    (and the like) or ``dt``, or from a time vector ``t``/``time``."""
    from scipy.io import loadmat  # noqa: PLC0415 - only when a MAT file is imported
    try:
        m = loadmat(p, squeeze_me=True)
    except NotImplementedError:
        raise UserError("MAT v7.3 (HDF5) is not read by scipy.io; expected a file saved with -v7",
                        file=str(p)) from None
    except Exception as e:  # noqa: BLE001 - scipy.io raises MatReadError, ValueError... on a damaged file
        raise UserError(f"not a readable MAT file ({type(e).__name__}: {e})", file=str(p)) from None
    num = {k: np.asarray(v) for k, v in m.items() if not k.startswith("__")
           and isinstance(v, (np.ndarray, int, float)) and np.asarray(v).dtype.kind in "iuf"}
    rate = t0 = None
    for k in RATE_NAMES:
        if k in num and num[k].size == 1:
            rate = float(num[k])
            if not (np.isfinite(rate) and rate > 0):
                raise UserError(f"value {rate!r}: expected a positive sample rate in Hz", file=str(p), key=k)
            break
    if rate is None:
        for k in DT_NAMES:
            if k in num and num[k].size == 1:
                rate = _rate(float(num[k]), p, k)
                break
    tname = next((k for k in TIME_NAMES if k in num and num[k].ndim == 1 and num[k].size > 1), None)
    if tname is not None:
        dt, t0 = _time_axis(num[tname], 1.0, p, tname)
        trate = 1.0 / dt
        if rate is not None and abs(trate - rate) > 1e-4 * rate:
            raise UserError(f"time vector gives {trate:g} Hz, the rate variable {rate:g} Hz; expected one rate",
                            file=str(p), key=tname)
        rate = rate or trate
        t0 = t0 if t0 != 0.0 else None
    out = []
    for k, v in num.items():
        if k == tname or v.size < 2 or k in RATE_NAMES or k in DT_NAMES:
            continue
        if v.ndim == 1:
            out.append(Column(p, k, k, v.astype(float), rate, t0))
        elif v.ndim == 2:
            a = v if v.shape[0] >= v.shape[1] else v.T
            for j in range(a.shape[1]):
                out.append(Column(p, f"{k}/{j + 1}", f"{k}/{j + 1}", a[:, j].astype(float), rate, t0))
    return out


# ------------------------------------------------------------------ CSV (numpy)
_SUFFIX = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]\s*$")


def split_header(name: str) -> tuple[str, str | None]:
    """(name, unit) of a CSV header: 'force [N]', 'force (N)' or 'force_N' ('time_us')."""
    m = _SUFFIX.match(name)
    if m and (parse_unit(m.group(2)) or time_factor(m.group(2))):
        return m.group(1), m.group(2)
    if "_" in name:
        base, _, u = name.rpartition("_")
        if base and (parse_unit(u) or time_factor(u)):
            return base, u
    return name, None


def _time_axis(t: np.ndarray, factor: float, p: Path, key: str) -> tuple[float, float]:
    """(interval s, start s) of an evenly spaced time column (its values may be rounded to
    the digits printed: each within 1 % of an interval of the fitted line)."""
    t = np.asarray(t, float) * factor
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise UserError(f"{t.size} time value(s), or not all finite; expected at least two evenly spaced times",
                        file=str(p), key=key)
    k = np.arange(t.size)
    dt, start = np.polyfit(k, t, 1)
    if not dt > 0 or np.max(np.abs(t - (start + dt * k))) > 0.01 * dt:
        raise UserError("time column is not evenly spaced; expected a constant sample interval",
                        file=str(p), key=key)
    return float(dt), float(t[0])


def read_csv(p: Path) -> list[Column]:
    """CSV: '#' comment lines, an optional header row, one column per channel; a column
    named 'time'/'t' (seconds, or the unit of its suffix: 'time_us') gives the rate and,
    when it starts below zero, the pre-trigger."""
    try:
        lines = p.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise UserError(f"cannot read: {e}", file=str(p)) from None
    body = [(i, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    if not body:
        raise UserError("no data rows", file=str(p))
    sample = body[min(1, len(body) - 1)][1]
    delim = ";" if ";" in sample else "\t" if "\t" in sample else None
    if delim is None:
        try:
            delim = csv.Sniffer().sniff(sample, delimiters=",\t ").delimiter
        except csv.Error:
            delim = ","
    first = next(csv.reader([body[0][1]], delimiter=delim, skipinitialspace=True))
    comma = delim != ","                         # a decimal comma is possible: '1,5;2,25'
    header = None
    try:
        [float(v.replace(",", ".") if comma else v) for v in first]
        rows = body
    except ValueError:
        header = [h.strip() for h in first]
        rows = body[1:]
    if len(rows) < 2:
        raise UserError(f"{len(rows)} data row(s); expected at least two samples per channel", file=str(p))
    lines = [ln.replace(",", ".") if comma else ln for _, ln in rows]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # numpy's 'empty input' and the like: the error says it
            a = np.loadtxt(lines, delimiter=None if delim == " " else delim, ndmin=2)
    except ValueError as e:
        raise UserError(f"not a table of numbers ({str(e).splitlines()[0] if str(e) else e}); expected one "
                        "numeric column per channel (a decimal point, or a decimal comma with ';' between "
                        "columns)", file=str(p)) from None
    names = header or [str(j + 1) for j in range(a.shape[1])]
    if len(names) != a.shape[1]:
        raise UserError(f"{len(names)} header names for {a.shape[1]} columns; expected one name per column",
                        file=str(p))
    rate = t0 = None
    tcol = None
    for j, h in enumerate(names):
        base, unit = split_header(h)
        if base.strip().lower() in ("t", "time"):
            f = time_factor(unit) if unit else 1.0
            if f is None:
                raise UserError(f"time unit {unit!r}; expected s, ms, us or ns", file=str(p), key=h)
            dt, start = _time_axis(a[:, j], f, p, h)
            rate, t0, tcol = 1.0 / dt, (start if start != 0.0 else None), j
            break
    out = []
    for j, h in enumerate(names):
        if j == tcol:
            continue
        _, unit = split_header(h)
        out.append(Column(p, h, h, a[:, j].copy(), rate, t0, unit))
    return out
