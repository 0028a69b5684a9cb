"""The simulated rig: a ``drivers.protocol.Device`` whose records are synthesised.

Vibration shots (``role='hammer'``, ~10 kHz): the plate modes of
``engine.plate`` respond to a half-sine hammer force at (xh, yh)
(``mock_hw.vibration``). The force channel reads F(t). Rigid-body/suspension
modes are left out (they lie below the IEPE high-pass).

Wave shots (``role='wave'``, 1-5 MHz): ``mock_hw.waves`` (sources: pencil, hammer,
tone burst, piezo disc; direct path and edge reflections by image sources; the
sensors' face, high-pass and resonance), then crosstalk between the channels
(``crosstalk_db``).

What a real record has, in this order: the continuous signal on a grid
``OVERSAMPLE`` times finer than the sample clock, the device's anti-alias
filter (Butterworth/Bessel, causal: its group delay is in the data and in
``meta['antialias_group_delay_s']``), a trigger found where the trigger channel
crosses its level on the next tick of a free-running sample clock (plus
optional extra jitter), pre-trigger samples, noise (V rms), the ADC (range
clipping with an overload flag, quantisation to ``adc_bits``). Force scatter,
double hits and missed triggers on request (rig ``[simulation]``).

Unmodelled effects (``Effects``, CONTRACT names) are injected into the
synthesis; engine results are cached per configuration, so repeated shots cost
only the per-shot randomisation. Every random draw of shot k comes from
``SeedSequence([seed, role, k])``: runs are reproducible shot by shot.
"""
from __future__ import annotations

import functools
import math
import time
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, ClassVar

import numpy as np

from drivers.protocol import ChannelConfig, NoTrigger, Record, Timing, Trigger
from engine.forward.effects import ALPHA_FIBRE, ALPHA_ISOTROPIC, ALPHA_MATRIX, EFFECTS
from engine.laminate import Laminate

from . import waves
from .vibration import vibration_signals
from .waves import OVERSAMPLE
ROLE_IDS = {"hammer": 0, "wave": 1}

#: temperature coefficients of the moduli (ALPHA_*) and the effect registry (EFFECTS): engine.forward.effects


@dataclass(frozen=True)
class Effects:
    """Unmodelled effects injected into the simulated rig (CONTRACT names, SI units).

    sensor_mass: kg added at every accelerometer position on top of the mass the
        rig file declares (``mass_kg``, always simulated and modelled).
    support_stiffness: N/m, a transverse spring at every rig support point.
    temperature: K, specimen temperature minus the temperature its constants
        hold at; moduli scale by (1 + alpha dT), alpha = ALPHA_FIBRE for E1,
        ALPHA_MATRIX for E2, G12, G13, G23, ALPHA_ISOTROPIC for E, G.
    thickness: relative thickness error, h_true = h (1 + thickness) (every ply).
    timing_offset: s, delay added to every wave-sensor channel.
    path_length: m, added to every wave-sensor distance.
    sensor_aperture: m, wave-sensor strain averaged over this length (replaces
        the channel's nominal length_m).
    viscoelastic: loss factor eta: modal damping ratio + eta/2; guided waves
        attenuated by exp(-eta k x / 2), k = omega / c_phase(A0).
    """

    sensor_mass: float = 0.0
    support_stiffness: float = 0.0
    temperature: float = 0.0
    thickness: float = 0.0
    timing_offset: float = 0.0
    path_length: float = 0.0
    sensor_aperture: float = 0.0
    viscoelastic: float = 0.0

    UNITS: ClassVar[dict[str, str]] = {name: spec.unit for name, spec in EFFECTS.items()}

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    def active(self) -> dict[str, float]:
        """The non-zero effects, name -> magnitude."""
        return {k: v for k, v in asdict(self).items() if v != 0.0}

    @classmethod
    def parse(cls, text: str) -> "Effects":
        """From 'name=value,name=value' (ValueError naming the bad item)."""
        kw: dict[str, float] = {}
        for item in filter(None, (s.strip() for s in text.split(","))):
            name, sep, val = item.partition("=")
            name = name.strip()
            if not sep or name not in cls.UNITS:
                raise ValueError(f"effect {item!r}: expected NAME=VALUE with NAME one of {list(cls.names())}")
            try:
                kw[name] = float(val)
            except ValueError:
                raise ValueError(f"effect {name}: value {val!r}: expected a number in "
                                 f"{cls.UNITS[name]}") from None
            if not math.isfinite(kw[name]):
                raise ValueError(f"effect {name}: value {val!r}: expected a finite number")
        e = cls(**kw)
        e.check()
        return e

    def check(self) -> None:
        for k in ("sensor_mass", "support_stiffness", "sensor_aperture", "viscoelastic"):
            if getattr(self, k) < 0:
                raise ValueError(f"effect {k} = {getattr(self, k)!r}: expected >= 0")
        if self.thickness <= -1:
            raise ValueError(f"effect thickness = {self.thickness!r}: expected > -1 (relative error)")


def effective_laminate(lam: Laminate, effects: Effects) -> Laminate:
    """The laminate as the simulated 'real' plate has it (temperature, thickness)."""
    dT = effects.temperature
    if dT:
        for name, mat in lam.materials.items():
            if mat.isotropic:
                f = 1.0 + ALPHA_ISOTROPIC * dT
                p = {"E": mat.E1 * f, "G": mat.G12 * f}
            else:
                fm = 1.0 + ALPHA_MATRIX * dT
                p = {"E1": mat.E1 * (1.0 + ALPHA_FIBRE * dT), "E2": mat.E2 * fm,
                     "G12": mat.G12 * fm, "G13": mat.G13 * fm, "G23": mat.G23 * fm}
            lam = lam.with_params(p, material=name)
    if effects.thickness:
        lam = lam.scaled_thickness(1.0 + effects.thickness)
    return lam


def truth_laminate(lam: Laminate, scale: tuple[tuple[str, float], ...]) -> Laminate:
    """The simulated 'real' plate when it differs from the specimen file (the lab's normal
    case): its moduli times ``scale`` (the rig's ``[simulation] truth_scale``: ('*', f)
    every modulus, or (name, f) pairs; E3 follows E2 when the file leaves it out)."""
    if not scale:
        return lam
    for name, mat in lam.materials.items():
        cur = {"E": mat.E1, "G": mat.G12} if mat.isotropic else \
            {"E1": mat.E1, "E2": mat.E2, "G12": mat.G12, "G13": mat.G13, "G23": mat.G23}
        if not mat.isotropic and mat.E3 is not None:
            cur["E3"] = mat.E3
        new = dict(cur)
        for key, f in scale:                    # factors compose: ('*', 0.5), ('G13', 2) leaves G13
            for k in (cur if key == "*" else [key]):
                if k in new:
                    new[k] = new[k] * f
        lam = lam.with_params(new, material=name)
    return lam


# -- cached engine results ---------------------------------------------------
def _butter_or_bessel(kind: str, order: int, cutoff_hz: float, fs_hz: float):
    # scipy.signal imported where used: ~0.8 s CPU at the start of every command otherwise
    from scipy import signal  # noqa: PLC0415
    if kind == "none":
        return None, 0.0
    if kind == "bessel":
        sos = signal.bessel(order, cutoff_hz, fs=fs_hz, output="sos", norm="mag")
    else:
        sos = signal.butter(order, cutoff_hz, fs=fs_hz, output="sos")
    b, a = signal.sos2tf(sos)
    _, gd = signal.group_delay((b, a), w=[1e-6 * fs_hz], fs=fs_hz)
    return sos, float(gd[0]) / fs_hz


@dataclass
class _Template:
    """Per-configuration unit waveforms (volts per N of peak force) on the fine grid."""

    fine: dict[str, np.ndarray]   # filtered, unit source amplitude
    lead: int                     # fine samples before source onset
    fs_fine: float
    group_delay_s: float
    _env: dict = None

    def running(self, name: str, rising: bool) -> np.ndarray:
        """Running max (rising) or min of a unit waveform, cached."""
        if self._env is None:
            self._env = {}
        key = (name, rising)
        if key not in self._env:
            u = self.fine[name]
            self._env[key] = np.maximum.accumulate(u) if rising else np.minimum.accumulate(u)
        return self._env[key]


class SimulatedDevice:
    """A simulated acquisition device for one role of a rig ('hammer' or 'wave').

    Speaks ``drivers.protocol.Device``: configure(channels, timing, trigger),
    arm(), read(timeout_s) -> Record, close(). ``rig`` and ``specimen`` supply
    what the simulation needs beyond the protocol (source, sensor distances,
    device ADC/noise/filter, ``[simulation]`` settings).
    """

    def __init__(self, rig, specimen, role: str, effects: Effects | None = None, seed: int = 0,
                 double_hit: bool | None = None):
        self.rig, self.specimen, self.role = rig, specimen, role
        self.spec = rig.device(role)
        if self.spec is None:
            raise ValueError(f"rig has no device with role {role!r}")
        self.name = f"sim:{self.spec.name}"
        self.effects = effects or Effects()
        self.effects.check()
        self.seed = int(seed)
        self.force_double_hit = double_hit
        self.shot_index = 0
        self._cfg: tuple | None = None
        self._tpl: _Template | None = None
        self._armed = False

    # -- protocol -----------------------------------------------------------
    def configure(self, channels: tuple[ChannelConfig, ...], timing: Timing,
                  trigger: Trigger | None) -> None:
        names = [c.name for c in channels]
        if trigger is not None and trigger.channel not in names:
            raise ValueError(f"trigger channel {trigger.channel!r} is not configured ({names})")
        if timing.rate_hz <= 0 or timing.samples < 1 or not 0 <= timing.pretrigger < timing.samples:
            raise ValueError(f"impossible timing {timing}")
        cfg = (tuple(channels), timing, trigger)
        if cfg != self._cfg:
            self._cfg, self._tpl = cfg, None
        self._armed = False

    def arm(self) -> None:
        if self._cfg is None:
            raise RuntimeError("configure() before arm()")
        if self._tpl is None:
            self._tpl = self._template()
        self._armed = True

    def read(self, timeout_s: float = 10.0) -> Record:
        if not self._armed:
            raise RuntimeError("arm() before read()")
        self._armed = False
        k = self.shot_index
        self.shot_index += 1
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, ROLE_IDS[self.role], k]))
        src = self.rig.wave_source
        if self.role == "wave" and src is not None and src.burst is not None and src.burst.sweep_hz:
            self._tpl = self._template(k)          # the sweep's turn (cached per frequency)
        return self._synthesise(rng, k)

    def close(self) -> None:
        self._armed = False

    # -- synthesis ------------------------------------------------------------
    @property
    def source(self):
        return self.rig.hammer if self.role == "hammer" else self.rig.wave_source

    def _template(self, shot: int = 0) -> _Template:
        channels, timing, trigger = self._cfg
        return _cached_template(self.shot_rig(shot), self.specimen, self.role, self.effects, channels, timing,
                                waves.model_token())

    def shot_rig(self, shot: int):
        """The rig of wave shot ``shot``: with a tone-burst sweep, the burst at its turn's
        centre frequency (shot k: the (k mod n)-th of the sweep)."""
        src = self.rig.wave_source
        if self.role != "wave" or src is None or src.burst is None or not src.burst.sweep_hz:
            return self.rig
        f = src.burst.sweep_hz[shot % len(src.burst.sweep_hz)]
        return replace(self.rig, wave_source=replace(src, burst=src.burst.at(f)))

    def _synthesise(self, rng: np.random.Generator, k: int) -> Record:
        channels, timing, trigger = self._cfg
        tpl, spec, sim, src = self._tpl, self.spec, self.rig.sim, self.source
        miss = rng.random() < sim.miss_probability
        spread = sim.force_spread if waves.mechanical(src) else 0.0   # a generator repeats itself
        amp = waves.source_peak(src) * max(0.05, 1.0 + spread * rng.standard_normal())
        dbl = rng.random() < sim.double_hit_probability if self.force_double_hit is None \
            else self.force_double_hit
        dbl = dbl and src.kind == "hammer"
        delay = int(round(sim.double_hit_delay_s * (1 + 0.2 * rng.uniform(-1, 1)) * tpl.fs_fine))
        phase = int(rng.integers(OVERSAMPLE))
        jitter = int(round(rng.standard_normal() * spec.trigger_jitter_s * tpl.fs_fine))
        if miss:
            raise NoTrigger(f"{self.name}: no trigger within {spec.trigger_timeout_s:g} s (simulated miss)")

        def take(u: np.ndarray, idx: np.ndarray) -> np.ndarray:
            if idx[0] >= 0 and idx[-1] < u.size:              # common case: a strided view
                step = int(idx[1] - idx[0]) if idx.size > 1 else 1
                return u[idx[0]:idx[-1] + 1:step]
            ok = (idx >= 0) & (idx < u.size)
            return np.where(ok, u[np.clip(idx, 0, u.size - 1)], 0.0)

        def wave(name: str, idx: np.ndarray) -> np.ndarray:
            u = tpl.fine[name]
            v = amp * take(u, idx)
            if dbl:
                v += (amp * sim.double_hit_ratio) * take(u, idx - delay)
            return v

        os_, n, pre = OVERSAMPLE, timing.samples, timing.pretrigger
        if trigger is not None:
            lv, rising = trigger.level_v, trigger.slope == "rising"
            u = tpl.fine[trigger.channel]
            if not dbl and (lv > 0) == rising and lv != 0:
                # signal starts at 0: the first crossing is where the running max (min) passes lv/amp
                env = tpl.running(trigger.channel, rising)
                ic = int(np.searchsorted(env, lv / amp)) if rising else int(np.searchsorted(-env, -lv / amp))
                found = ic < u.size
            else:
                full = wave(trigger.channel, np.arange(u.size))
                hit = (full[:-1] < lv) & (full[1:] >= lv) if rising else (full[:-1] > lv) & (full[1:] <= lv)
                cross = np.flatnonzero(hit)
                found = cross.size > 0
                ic = int(cross[0]) + 1 if found else 0
            if not found:
                raise NoTrigger(f"{self.name}: channel {trigger.channel!r} never crossed "
                                f"{lv:g} V ({trigger.slope}) within the record")
        else:
            ic = tpl.lead
        # first tick of the free-running sample clock at or after the crossing
        it = ic + ((phase - ic) % os_) + jitter
        idx = it + os_ * (np.arange(n) - pre)
        data, over = {}, {}
        for c in channels:
            v = wave(c.name, idx) if c.name in tpl.fine else np.zeros(n)
            if spec.noise_v:
                v += spec.noise_v * rng.standard_normal(n)
            R = c.range_v
            lsb = 2.0 * R / 2.0**spec.adc_bits
            v *= 1.0 / lsb                                   # in ADC steps, in place
            over[c.name] = bool(v.max() >= R / lsb or v.min() <= -R / lsb)
            np.rint(v, out=v)
            np.clip(v, -2.0**(spec.adc_bits - 1), 2.0**(spec.adc_bits - 1) - 1, out=v)
            v *= lsb
            data[c.name] = v
        onset_s = (tpl.lead - it) / tpl.fs_fine  # source onset relative to the trigger sample
        meta: dict[str, Any] = {
            "simulated": True, "device": self.name, "seed": self.seed, "shot_index": k,
            "adc_bits": spec.adc_bits, "noise_v": spec.noise_v,
            "antialias": asdict(spec.antialias), "antialias_group_delay_s": tpl.group_delay_s,
            "source": src.kind, "source_xy_m": [src.x, src.y],
            "sim_force_peak_n": amp, "sim_double_hit": bool(dbl),
            "sim_double_hit_delay_s": delay / tpl.fs_fine if dbl else 0.0,
            "sim_onset_s": onset_s, "effects": self.effects.active(),
        }
        if self.role == "wave" and src.burst is not None and src.burst.sweep_hz:
            meta["burst_frequency_hz"] = src.burst.sweep_hz[k % len(src.burst.sweep_hz)]
        if self.rig.sim.truth_scale:
            meta["sim_truth_scale"] = {k: f for k, f in self.rig.sim.truth_scale}
        if waves.model_token() != "engine.safe":
            meta["sim_wave_model"] = waves.model_token()
        return Record(data=data, channels=tuple(channels), timing=timing, trigger=trigger,
                      overload=over, timestamp=time.time(), backend="mock", meta=meta)


@functools.lru_cache(maxsize=16)
def _cached_template(rig, specimen, role: str, effects: Effects, channels: tuple, timing: Timing,
                     model: str = "engine.safe") -> _Template:
    spec = rig.device(role)
    fs = timing.rate_hz
    fsf = OVERSAMPLE * fs
    lead = OVERSAMPLE * (timing.pretrigger + 16)
    nf = lead + OVERSAMPLE * (2 * timing.samples + 16)
    t = (np.arange(nf) - lead) / fsf
    lam = effective_laminate(truth_laminate(specimen.laminate, rig.sim.truth_scale), effects)
    raw: dict[str, np.ndarray] = {}
    if role == "hammer":
        raw = vibration_signals(rig, specimen, lam, effects, channels, t)
    else:
        raw = waves.wave_channels(rig, (specimen.length, specimen.width), lam, effects, channels, fs,
                                  lead, nf)
        raw = waves.apply_crosstalk(raw, spec.crosstalk_db)
    sos, gd = _butter_or_bessel(spec.antialias.kind, spec.antialias.order,
                                spec.antialias.cutoff_ratio * fs, fsf)
    from scipy import signal  # noqa: PLC0415 - see _butter_or_bessel
    fine = {k: (signal.sosfilt(sos, v) if sos is not None else v) for k, v in raw.items()}
    return _Template(fine, lead, fsf, gd)


