"""Rig files (TOML): devices, channels, positions, trigger, sources, session defaults.

The format is documented in ``docs/rig-file.md``. Everything is validated where
it enters: each mistake raises ``UserError`` naming the file, the key, the value
found and what was expected. The result is a frozen ``Rig`` whose devices carry
the ``drivers.protocol`` ChannelConfig / Timing / Trigger objects.
"""
from __future__ import annotations

import math
import re
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

from drivers.protocol import ChannelConfig, Timing, Trigger

from ..base.errors import UserError
from .files import parse_toml, read_text_file
from .keys import check_keys as _keys   # the one key check (labid.inputs.keys)
from .rigtypes import (BUILTIN, ROLES, KINDS, COUPLINGS, FILTERS, DEFAULT_MAX_RATE_HZ, FACES, SOURCE_KINDS,
                       WINDOWS, PAIRS, BREAK_ON, AntiAlias, DeviceSpec, WaveSensor, Burst, Source, SimSettings, Rig)

#: a channel name: a table of the run file is named after it (HDF5: no '/', not '.'), and so
#: are CSV columns and UFF records; the run file's own tables take the names in RESERVED_NAMES
CHANNEL_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,63}")
RESERVED_NAMES = ("timestamp", "overload", "backend", "software_version", "meta", "committed")


def _err(src: str, key: str, msg: str) -> UserError:
    return UserError(msg, file=src, key=key)


def _table(doc: Mapping[str, Any], key: str, src: str, where: str = "", required=False) -> Mapping:
    v = doc.get(key)
    if v is None:
        if required:
            raise _err(src, where + key, "missing table")
        return {}
    if not isinstance(v, Mapping):
        raise _err(src, where + key, f"value {v!r}: expected a table")
    return v


def _num(tab: Mapping[str, Any], key: str, where: str, src: str, *, default: Any = ...,
         lo: float | None = None, lo_open=False, hi: float | None = None, what="a number") -> float:
    if key not in tab:
        if default is ...:
            raise _err(src, where + key, f"missing key; expected {what}")
        return default
    v = tab[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _err(src, where + key, f"value {v!r}: expected {what}")
    v = float(v)
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise _err(src, where + key, f"value {v:g}: expected {what} {'>' if lo_open else '>='} {lo:g}")
    if hi is not None and v > hi:
        raise _err(src, where + key, f"value {v:g}: expected {what} <= {hi:g}")
    return v


def _int(tab, key, where, src, *, default: Any = ..., lo: int = 0, hi: int | None = None) -> int:
    if key not in tab and default is not ...:
        return default
    v = tab.get(key)
    if isinstance(v, bool) or not isinstance(v, int):
        if key not in tab:
            raise _err(src, where + key, "missing key; expected an integer")
        raise _err(src, where + key, f"value {v!r}: expected an integer")
    if v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise _err(src, where + key, f"value {v}: expected an integer {rng}")
    return v


def _str(tab, key, where, src, *, choices: tuple[str, ...] | None = None, default: Any = ...) -> str:
    if key not in tab:
        if default is ...:
            raise _err(src, where + key, "missing key; expected a string"
                       + (f" among {list(choices)}" if choices else ""))
        return default
    v = tab[key]
    if not isinstance(v, str) or (choices and v not in choices):
        raise _err(src, where + key, f"value {v!r}: expected "
                   + (f"one of {list(choices)}" if choices else "a string"))
    return v


_CHANNEL_KEYS = {"name", "kind", "physical", "sensitivity", "range_v", "coupling", "x", "y",
                 "mass_kg", "length_m", "excitation_current_a", "distance_m", "direction_deg",
                 "volts_per_strain", "face", "highpass_hz", "resonance_hz", "resonance_q", "acquisition"}
_DEVICE_KEYS = {"role", "product", "daq_device", "max_rate_hz", "rate_hz", "samples", "pretrigger",
                "adc_bits", "noise_v", "trigger_jitter_s", "antialias", "trigger", "channels",
                "trigger_timeout_s", "crosstalk_db"}


def _channel(tab: Any, where: str, src: str, source: Source | None
             ) -> tuple[ChannelConfig, WaveSensor | None, int]:
    if not isinstance(tab, Mapping):
        raise _err(src, where.rstrip("."), f"value {tab!r}: expected a [[channels]] table")
    _keys(tab, _CHANNEL_KEYS, where, src)
    name = _str(tab, "name", where, src)
    if not CHANNEL_NAME.fullmatch(name) or name in RESERVED_NAMES:
        raise _err(src, where + "name", f"value {name!r}: expected 1 to 64 letters, digits, '_', '.', '+' or "
                   f"'-', not starting with '.', '+' or '-', and none of {list(RESERVED_NAMES)} (the run "
                   "file's own tables)")
    kind = _str(tab, "kind", where, src, choices=KINDS, default="voltage")
    coupling = _str(tab, "coupling", where, src, choices=COUPLINGS,
                    default="IEPE" if kind in ("accelerometer", "force") else "DC")
    sens = _num(tab, "sensitivity", where, src, lo=0.0, lo_open=True,
                what="a positive sensitivity in V per physical unit")
    rng = _num(tab, "range_v", where, src, default=5.0, lo=0.0, lo_open=True,
               what="a positive input range in V")
    x = _num(tab, "x", where, src, default=None, what="a position in m")
    y = _num(tab, "y", where, src, default=None, what="a position in m")
    if (x is None) != (y is None):
        raise _err(src, where + ("y" if y is None else "x"), "expected both x and y (m), or neither")
    mass = _num(tab, "mass_kg", where, src, default=0.0, lo=0.0, what="a mass in kg")
    length = _num(tab, "length_m", where, src, default=0.0, lo=0.0, what="a length in m")
    iexc = _num(tab, "excitation_current_a", where, src, default=0.004, lo=0.0, what="a current in A")
    acq = _int(tab, "acquisition", where, src, default=0, lo=0, hi=64)
    wave = None
    if "distance_m" in tab:
        if source is None:
            raise _err(src, where + "distance_m", "a wave sensor needs a wave source; expected a "
                       "[wave_source] table (or [hammer]) with its position")
        d = _num(tab, "distance_m", where, src, lo=0.0, lo_open=True, what="a positive distance in m")
        ang = _num(tab, "direction_deg", where, src, default=0.0, what="an angle in degrees")
        vps = _num(tab, "volts_per_strain", where, src, default=1.0e4, lo=0.0, lo_open=True,
                   what="a positive transduction in V per unit strain")
        hp = _num(tab, "highpass_hz", where, src, default=None, lo=0.0, lo_open=True,
                  what="a high-pass corner in Hz")
        res = _num(tab, "resonance_hz", where, src, default=None, lo=0.0, lo_open=True,
                   what="a resonance frequency in Hz")
        q = _num(tab, "resonance_q", where, src, default=5.0, lo=0.5, hi=1e4, what="a quality factor")
        wave = WaveSensor(name, d, ang, vps, length, _str(tab, "face", where, src, choices=FACES, default="top"),
                          hp, res, q, acq)
        if x is None:
            x = source.x + d * math.cos(math.radians(ang))
            y = source.y + d * math.sin(math.radians(ang))
    else:
        for k in ("face", "highpass_hz", "resonance_hz", "resonance_q"):
            if k in tab:
                raise _err(src, where + k, "only for a guided-wave sensor; expected distance_m too")
        if kind == "accelerometer" and x is None:
            raise _err(src, where + "x", "missing key; an accelerometer needs its position x, y in m")
    return ChannelConfig(name=name, kind=kind, physical=_str(tab, "physical", where, src, default=""),
                         sensitivity=sens, range_v=rng, coupling=coupling, x=x, y=y, mass_kg=mass,
                         length_m=length, excitation_current_a=iexc), wave, acq


def _device(name: str, tab: Any, src: str, wave_source: Source | None) -> tuple[DeviceSpec, list[WaveSensor]]:
    where = f"devices.{name}."
    if not isinstance(tab, Mapping):
        raise _err(src, where.rstrip("."), f"value {tab!r}: expected a table")
    _keys(tab, _DEVICE_KEYS, where, src)
    role = _str(tab, "role", where, src, choices=ROLES)
    max_rate = _num(tab, "max_rate_hz", where, src, default=DEFAULT_MAX_RATE_HZ, lo=0.0, lo_open=True,
                    what="a positive maximum rate in Hz")
    rate = _num(tab, "rate_hz", where, src, what="a sample rate in Hz")
    if rate <= 0:
        raise _err(src, where + "rate_hz", f"value {rate:g}: impossible sample rate; expected a rate > 0 Hz")
    if rate > max_rate:
        raise _err(src, where + "rate_hz", f"value {rate:g}: impossible sample rate; expected at most "
                   f"max_rate_hz = {max_rate:g} Hz for this device")
    samples = _int(tab, "samples", where, src, lo=2, hi=100_000_000)
    pre = _int(tab, "pretrigger", where, src, default=0, lo=0, hi=samples - 1)
    chans_raw = tab.get("channels")
    if not isinstance(chans_raw, list) or not chans_raw:
        raise _err(src, where + "channels", "missing or empty; expected [[devices.NAME.channels]] tables")
    chans, waves, acqs = [], [], []
    for i, ct in enumerate(chans_raw):
        c, w, a = _channel(ct, f"{where}channels[{i}].", src, wave_source)
        if any(o.name == c.name for o in chans):
            raise _err(src, f"{where}channels[{i}].name", f"value {c.name!r}: duplicate channel name")
        chans.append(c)
        acqs.append(a)
        if w:
            waves.append(w)
    names = [c.name for c in chans]
    trigger = None
    if "trigger" in tab:
        tt = _table(tab, "trigger", src, where)
        tw = where + "trigger."
        _keys(tt, {"channel", "level_v", "slope"}, tw, src)
        ch = _str(tt, "channel", tw, src)
        if ch not in names:
            raise _err(src, tw + "channel", f"value {ch!r}: unknown channel; expected one of {names}")
        level = _num(tt, "level_v", tw, src, default=0.5, what="a trigger level in V")
        rng = next(c.range_v for c in chans if c.name == ch)
        if abs(level) >= rng:
            raise _err(src, tw + "level_v", f"value {level:g}: expected a level inside the "
                       f"+/-{rng:g} V range of channel {ch!r}")
        trigger = Trigger(ch, level, _str(tt, "slope", tw, src, choices=("rising", "falling"),
                                          default="rising"))
        tkind = next(c.kind for c in chans if c.name == ch)
        if role == "hammer" and tkind == "voltage":
            raise _err(src, tw + "channel", f"value {ch!r}: a voltage channel (its kind is \"voltage\", the "
                       "default when none is given); expected the hammer's force channel (kind = \"force\") "
                       "or an accelerometer")
    groups = tuple(tuple(c.name for c, a in zip(chans, acqs) if a == k) for k in range(max(acqs) + 1))
    if len(groups) > 1:
        empty = [k for k, g in enumerate(groups) if not g]
        if empty:
            raise _err(src, where + "channels", f"acquisition {empty[0]} has no channel; expected "
                       f"acquisitions numbered 0..{len(groups) - 1} without gaps")
        if trigger is None or any(w.channel == trigger.channel for w in waves):
            raise _err(src, where + "trigger.channel", "separate acquisitions need a common trigger; "
                       "expected the trigger on the channel recording the source (the wave_source "
                       "channel or a force channel), not on a sensor")
    aa_tab = _table(tab, "antialias", src, where)
    aw = where + "antialias."
    _keys(aa_tab, {"kind", "order", "cutoff_ratio"}, aw, src)
    aa = AntiAlias(_str(aa_tab, "kind", aw, src, choices=FILTERS, default="butterworth"),
                   _int(aa_tab, "order", aw, src, default=6, lo=1, hi=12),
                   _num(aa_tab, "cutoff_ratio", aw, src, default=0.45, lo=0.0, lo_open=True, hi=0.5,
                        what="a cutoff as a fraction of the sample rate"))
    dev = DeviceSpec(
        name=name, role=role, channels=tuple(chans), timing=Timing(rate, samples, pre), trigger=trigger,
        product=_str(tab, "product", where, src, default=""), max_rate_hz=max_rate,
        daq_device=_str(tab, "daq_device", where, src, default=""),
        adc_bits=_int(tab, "adc_bits", where, src, default=16, lo=8, hi=32),
        noise_v=_num(tab, "noise_v", where, src, default=0.0, lo=0.0, what="a noise level in V rms"),
        crosstalk_db=_num(tab, "crosstalk_db", where, src, default=None, hi=0.0,
                          what="a coupling in dB (negative)"),
        acquisitions=groups,
        trigger_jitter_s=_num(tab, "trigger_jitter_s", where, src, default=0.0, lo=0.0,
                              what="a jitter in s"),
        antialias=aa,
        trigger_timeout_s=_num(tab, "trigger_timeout_s", where, src, default=10.0, lo=0.0, lo_open=True,
                               what="a timeout in s"))
    return dev, waves


_SOURCE_KEYS = {
    "pencil": {"rise_s", "force_n", "break_on", "force_deg"},
    "hammer": {"contact_s", "force_n"},
    "tone_burst": {"frequency_hz", "cycles", "window", "force_n"},
    "pzt": {"diameter_m", "face", "pair", "excitation", "newton_per_volt"},
}


def _burst(tab: Mapping, where: str, src: str, amplitude_key: str, amplitude_what: str) -> Burst:
    """The burst keys of a tone_burst source or a pzt's excitation table."""
    f = tab.get("frequency_hz")
    sweep: tuple[float, ...] = ()
    if isinstance(f, list):          # a sweep of centre frequencies
        if not f or len(f) > 64:
            raise _err(src, where + "frequency_hz", f"value {f!r}: expected a centre frequency in Hz or a "
                       "list of 1 to 64 of them (a sweep)")
        sweep = tuple(_num({"frequency_hz": x}, "frequency_hz", where, src, lo=0.0, lo_open=True,
                           what="a centre frequency in Hz") for x in f)
        tab = {**tab, "frequency_hz": sweep[0]}
    b = Burst(_num(tab, "frequency_hz", where, src, lo=0.0, lo_open=True, what="a centre frequency in Hz"),
              _num(tab, "cycles", where, src, default=5.0, lo=0.5, hi=1000.0, what="a number of cycles"),
              _str(tab, "window", where, src, choices=WINDOWS, default="hann"),
              _num(tab, amplitude_key, where, src, default=1.0, lo=0.0, lo_open=True, what=amplitude_what),
              sweep if len(sweep) > 1 else ())
    return b


def _source(tab: Mapping, key: str, src: str, kinds: tuple[str, ...], default_kind: str) -> Source:
    where = key + "."
    kind = _str(tab, "kind", where, src, choices=kinds, default=default_kind)
    _keys(tab, {"kind", "x", "y", "channel"} | _SOURCE_KEYS[kind], where, src)
    chan = tab.get("channel")
    if chan is not None and not isinstance(chan, str):
        raise _err(src, where + "channel", f"value {chan!r}: expected a channel name")
    common = dict(kind=kind, x=_num(tab, "x", where, src, what="a position in m"),
                  y=_num(tab, "y", where, src, what="a position in m"), channel=chan)
    if kind == "tone_burst":
        b = _burst(tab, where, src, "force_n", "a peak force in N")
        return Source(**common, force_n=b.amplitude, burst=b)
    if kind == "pzt":
        ex = _table(tab, "excitation", src, where, required=True)
        ew = where + "excitation."
        _keys(ex, {"kind", "frequency_hz", "cycles", "window", "amplitude_v"}, ew, src)
        _str(ex, "kind", ew, src, choices=("tone_burst",), default="tone_burst")
        pair = _str(tab, "pair", where, src, choices=PAIRS, default=None)
        return Source(**common, burst=_burst(ex, ew, src, "amplitude_v", "a peak voltage in V"),
                      diameter_m=_num(tab, "diameter_m", where, src, default=0.01, lo=0.0, lo_open=True,
                                      what="a disc diameter in m"),
                      face=_str(tab, "face", where, src, choices=FACES, default="top"), pair=pair,
                      newton_per_volt=_num(tab, "newton_per_volt", where, src, default=1.0, lo=0.0,
                                           lo_open=True, what="a pin force per volt in N/V"))
    edge = {}
    if kind == "pencil":
        edge = dict(break_on=_str(tab, "break_on", where, src, choices=BREAK_ON, default="face"),
                    force_deg=_num(tab, "force_deg", where, src, default=None, lo=-360.0, hi=360.0,
                                   what="an in-plane force direction in deg from x"))
        if edge["force_deg"] is not None and edge["break_on"] != "edge":
            raise _err(src, where + "force_deg", "is only read with break_on = \"edge\" (a lead broken on the "
                       "plate's edge)")
    return Source(
        **common, **edge,
        force_n=_num(tab, "force_n", where, src, default=1.0, lo=0.0, lo_open=True, what="a force in N"),
        contact_s=_num(tab, "contact_s", where, src, default=2.0e-4, lo=0.0, lo_open=True,
                       what="a contact duration in s"),
        rise_s=_num(tab, "rise_s", where, src, default=1.0e-6, lo=0.0, lo_open=True,
                    what="a rise time in s"))


def rig_from_dict(doc: Mapping[str, Any], src: str = "<inline>", text: str = "") -> Rig:
    """Build and validate a Rig from a parsed TOML table."""
    _keys(doc, {"name", "session", "hammer", "wave_source", "supports", "simulation", "devices", "calibration"},
          "", src)
    cal = doc.get("calibration")
    if cal is not None and (not isinstance(cal, str) or not cal.strip()):
        raise _err(src, "calibration", f"value {cal!r}: expected the path of a calibration sheet (CSV)")
    roles = _device_roles(doc, src)
    ham_tab = _table(doc, "hammer", src, required="hammer" in roles)
    ham = _source(ham_tab, "hammer", src, ("hammer",), "hammer") if ham_tab else None
    ws_tab = _table(doc, "wave_source", src, required="wave" in roles and ham is None)
    wsrc = _source(ws_tab, "wave_source", src, SOURCE_KINDS, "pencil") if ws_tab else ham
    sess = _table(doc, "session", src)
    _keys(sess, {"hits", "waves", "max_retries"}, "session.", src)
    simt = _table(doc, "simulation", src)
    sw = "simulation."
    _keys(simt, set(SimSettings.__dataclass_fields__), sw, src)
    d0 = SimSettings()
    sim = SimSettings(
        modal_damping=_num(simt, "modal_damping", sw, src, default=d0.modal_damping, lo=0.0, hi=0.5,
                           what="a damping ratio"),
        n_modes=_int(simt, "n_modes", sw, src, default=d0.n_modes, lo=1, hi=500),
        force_spread=_num(simt, "force_spread", sw, src, default=d0.force_spread, lo=0.0, hi=1.0,
                          what="a relative scatter"),
        double_hit_probability=_num(simt, "double_hit_probability", sw, src,
                                    default=d0.double_hit_probability, lo=0.0, hi=1.0, what="a probability"),
        double_hit_delay_s=_num(simt, "double_hit_delay_s", sw, src, default=d0.double_hit_delay_s,
                                lo=0.0, lo_open=True, what="a delay in s"),
        double_hit_ratio=_num(simt, "double_hit_ratio", sw, src, default=d0.double_hit_ratio, lo=0.0,
                              what="a force ratio"),
        miss_probability=_num(simt, "miss_probability", sw, src, default=d0.miss_probability, lo=0.0,
                              hi=1.0, what="a probability"),
        wave_fmax_hz=_num(simt, "wave_fmax_hz", sw, src, default=d0.wave_fmax_hz, lo=0.0, lo_open=True,
                          what="a frequency in Hz"),
        reflections=_int(simt, "reflections", sw, src, default=d0.reflections, lo=0, hi=2),
        truth_scale=parse_truth_scale(simt.get("truth_scale", ()), f"{sw}truth_scale", src))
    devs_tab = _table(doc, "devices", src, required=True)
    if not devs_tab:
        raise _err(src, "devices", "empty; expected at least one [devices.NAME] table")
    devices, waves = [], []
    for name, tab in devs_tab.items():
        dev, w = _device(name, tab, src, wsrc)
        if any(d.role == dev.role for d in devices):
            raise _err(src, f"devices.{name}.role", f"value {dev.role!r}: another device already has this role")
        devices.append(dev)
        waves += w
    names = [c.name for d in devices for c in d.channels]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise _err(src, "devices", f"channel name(s) {sorted(dup)} used on two devices; expected unique names")
    wdev = next((d for d in devices if d.role == "wave"), None)
    if ws_tab and wsrc.channel is not None:
        wn = [c.name for c in wdev.channels] if wdev else []
        if wsrc.channel not in wn or any(w.channel == wsrc.channel for w in waves):
            raise _err(src, "wave_source.channel", f"value {wsrc.channel!r}: expected a channel of the "
                       f"wave device that records the source (not a sensor), one of {wn}")
    sup = doc.get("supports", [])
    if not isinstance(sup, list):
        raise _err(src, "supports", f"value {sup!r}: expected [[supports]] tables with x, y in m")
    supports = []
    for i, s in enumerate(sup):
        if not isinstance(s, Mapping):
            raise _err(src, f"supports[{i}]", f"value {s!r}: expected a table with x, y in m")
        _keys(s, {"x", "y"}, f"supports[{i}].", src)
        supports.append((_num(s, "x", f"supports[{i}].", src, what="a position in m"),
                         _num(s, "y", f"supports[{i}].", src, what="a position in m")))
    return Rig(name=str(doc.get("name", Path(src).stem)), devices=tuple(devices), hammer=ham,
               wave_source=wsrc, wave_sensors=tuple(waves), supports=tuple(supports), sim=sim,
               hits=_int(sess, "hits", "session.", src, default=5, lo=0),
               waves=_int(sess, "waves", "session.", src, default=3, lo=0),
               max_retries=_int(sess, "max_retries", "session.", src, default=5, lo=0),
               text=text, source=src, calibration=cal)


TRUTH_NAMES = ("E1", "E2", "E3", "G12", "G13", "G23", "E", "G")


def parse_truth_scale(value, key: str = "simulation.truth_scale", src: str = "<inline>"
                      ) -> tuple[tuple[str, float], ...]:
    """The simulated plate's modulus factors: a number (every modulus), a table
    {G13 = 0.6, ...} or the text 'G13=0.6,E2=1.2' / '0.7' (the --truth option); each
    factor in [0.2, 5]. UserError naming ``key`` otherwise."""
    if isinstance(value, str):
        text = value.strip()
        try:
            value = float(text)
        except ValueError:
            items = {}
            for item in filter(None, (t.strip() for t in text.split(","))):
                name, sep, v = item.partition("=")
                try:
                    items[name.strip()] = float(v) if sep else None
                except ValueError:
                    items[name.strip()] = None
            value = items
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        pairs = [("*", float(value))]
    elif isinstance(value, Mapping):
        pairs = list(value.items())
    elif value == () or value == []:
        return ()
    else:
        raise _err(src, key, f"value {value!r}: expected a factor (e.g. 0.7) or NAME=FACTOR pairs with NAME "
                   f"one of {list(TRUTH_NAMES)}")
    out = []
    for name, f in pairs:
        if name != "*" and name not in TRUTH_NAMES:
            raise _err(src, key, f"name {name!r}: expected one of {list(TRUTH_NAMES)}")
        if not isinstance(f, (int, float)) or isinstance(f, bool) or not 0.2 <= float(f) <= 5.0:
            raise _err(src, key, f"{name}: factor {f!r}: expected a number in [0.2, 5]")
        out.append((str(name), float(f)))
    return tuple(out)


def _device_roles(doc: Mapping[str, Any], src: str) -> set[str]:
    """The roles of the devices a rig document declares (validated again in ``_device``)."""
    devs = _table(doc, "devices", src, required=True)
    return {t.get("role") for t in devs.values()
            if isinstance(t, Mapping) and isinstance(t.get("role"), str)}   # others: _device says why


def read_rig_text(path: str | Path | None) -> tuple[str, str]:
    """(TOML text, source label) of a rig file, or of the built-in rig for None/'default'."""
    p = "default" if path is None else str(path)
    if p in BUILTIN:
        return resources.files("labid.data").joinpath(BUILTIN[p]).read_text(), f"builtin:{p}"
    return read_text_file(p, "a rig TOML file (or 'default')"), p


def rig_from_text(text: str, src: str = "<inline>") -> Rig:
    return rig_from_dict(parse_toml(text, src, "a rig file as in docs/rig-file.md"), src, text)


def load_rig(path: str | Path | None = None) -> Rig:
    """Read and validate a rig file; None or 'default' is the built-in simulated rig."""
    text, src = read_rig_text(path)
    return rig_from_text(text, src)
