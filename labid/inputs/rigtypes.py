"""The rig as labid holds it once its file is read (``labid.inputs.rig`` reads and validates it):
devices, channels, wave sensors, sources, simulator settings. Frozen dataclasses; units SI
(m, s, Hz, V, N, kg), angles in degrees. The file format is ``docs/rig-file.md``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from drivers.protocol import ChannelConfig, Timing, Trigger

from ..base.errors import UserError

BUILTIN = {"default": "rig_default.toml", "pzt-aluminium": "rig_pzt_aluminium.toml"}
ROLES = ("hammer", "wave")
KINDS = ("accelerometer", "force", "voltage")
COUPLINGS = ("IEPE", "AC", "DC")
FILTERS = ("butterworth", "bessel", "none")
DEFAULT_MAX_RATE_HZ = 10.0e6


@dataclass(frozen=True)
class AntiAlias:
    """Anti-alias low-pass of a device: kind, order, cutoff as a fraction of the rate."""

    kind: str = "butterworth"
    order: int = 6
    cutoff_ratio: float = 0.45


@dataclass(frozen=True)
class DeviceSpec:
    """One acquisition device and the shots it records (role 'hammer' or 'wave')."""

    name: str
    role: str
    channels: tuple[ChannelConfig, ...]
    timing: Timing
    trigger: Trigger | None
    product: str = ""
    daq_device: str = ""
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ
    adc_bits: int = 16
    noise_v: float = 0.0
    crosstalk_db: float | None = None
    acquisitions: tuple[tuple[str, ...], ...] = ()
    trigger_jitter_s: float = 0.0
    antialias: AntiAlias = AntiAlias()
    trigger_timeout_s: float = 10.0

    def channel(self, name: str) -> ChannelConfig:
        for c in self.channels:
            if c.name == name:
                return c
        raise KeyError(name)


FACES = ("top", "bottom")
SOURCE_KINDS = ("pencil", "hammer", "tone_burst", "pzt")
WINDOWS = ("hann", "hamming", "rect")
PAIRS = ("symmetric", "antisymmetric")
BREAK_ON = ("face", "edge")


@dataclass(frozen=True)
class WaveSensor:
    """A guided-wave sensor: distance (m) and direction (deg) from the wave source.

    face: the plate face it is bonded to ('top', 'bottom'). highpass_hz: corner of its
    first-order high-pass (AC/IEPE coupling), None: none. resonance_hz, resonance_q: a
    resonant sensor, a damped second-order response w0^2 / (w0^2 - w^2 + i w w0 / Q)
    (None: flat). acquisition: which acquisition of a shot records it (0, 1, ...).
    """

    channel: str
    distance_m: float
    direction_deg: float = 0.0
    volts_per_strain: float = 1.0e4
    length_m: float = 0.0
    face: str = "top"
    highpass_hz: float | None = None
    resonance_hz: float | None = None
    resonance_q: float = 5.0
    acquisition: int = 0


@dataclass(frozen=True)
class Burst:
    """A windowed sine burst: centre frequency (Hz), cycles, window ('hann', 'hamming',
    'rect') and amplitude (N for a force tone burst, V for a piezo's excitation); with
    ``sweep_hz`` a sweep of centre frequencies (the lab's usual practice: the wave shots
    cycle through them, each shot's meta says which)."""

    frequency_hz: float
    cycles: float = 5.0
    window: str = "hann"
    amplitude: float = 1.0
    sweep_hz: tuple[float, ...] = ()     # a sweep: the centre frequencies shot in turn (frequency_hz the first)

    def at(self, frequency_hz: float) -> "Burst":
        """The same burst at one centre frequency (no sweep)."""
        return Burst(float(frequency_hz), self.cycles, self.window, self.amplitude)

    @property
    def duration_s(self) -> float:
        return self.cycles / self.frequency_hz


@dataclass(frozen=True)
class Source:
    """An excitation of the plate.

    kind: 'hammer' (half-sine of contact_s), 'pencil' (lead break, rise_s), 'tone_burst'
    (a normal point force following ``burst``, N) or 'pzt' (a bonded piezo disc of
    ``diameter_m`` on ``face``, driven by the voltage ``burst``, V; ``pair``: a collocated
    top/bottom pair driven 'symmetric' (in phase: S modes only) or 'antisymmetric').
    channel: the channel recording the source (force or excitation voltage), if any.
    newton_per_volt: the piezo's pin force per volt (simulator).
    break_on: a pencil lead broken on the top 'face' (a normal force: A0 strong, S0 ~40 dB
    under it on a thin laminate) or on the plate's 'edge' at mid-thickness (an in-plane force
    along ``force_deg``, deg from x, default the inward normal of the nearest edge: S modes,
    S0 strongest along the force; docs/waves.md).
    """

    kind: str
    x: float
    y: float
    force_n: float = 1.0
    contact_s: float = 2.0e-4
    rise_s: float = 1.0e-6
    burst: Burst | None = None
    channel: str | None = None
    diameter_m: float = 0.01
    face: str = "top"
    pair: str | None = None
    newton_per_volt: float = 1.0
    break_on: str = "face"
    force_deg: float | None = None


@dataclass(frozen=True)
class SimSettings:
    """Settings read only by the simulated backend (mock_hw)."""

    modal_damping: float = 0.005
    n_modes: int = 40
    force_spread: float = 0.10
    double_hit_probability: float = 0.0
    double_hit_delay_s: float = 3.0e-3
    double_hit_ratio: float = 0.3
    miss_probability: float = 0.0
    wave_fmax_hz: float = 400.0e3
    reflections: int = 1          # edge reflections of the wave shots: image-source order 0, 1 or 2
    # the simulated plate's moduli are the specimen file's times these factors: (('*', f),) scales
    # every modulus (E1, E2, E3, G12, G13, G23; E, G), (('G13', f), ...) named ones; () none
    truth_scale: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Rig:
    """A parsed, validated rig file."""

    name: str
    devices: tuple[DeviceSpec, ...]
    hammer: Source | None
    wave_source: Source | None
    wave_sensors: tuple[WaveSensor, ...] = ()
    supports: tuple[tuple[float, float], ...] = ()
    sim: SimSettings = SimSettings()
    hits: int = 5
    waves: int = 3
    max_retries: int = 5
    text: str = field(default="", repr=False, compare=False)
    source: str = "<inline>"
    calibration: str | None = None   # the calibration sheet (CSV) as the file names it (labid.inputs.calibration)

    def device(self, role: str) -> DeviceSpec | None:
        """The device recording shots of ``role`` ('hammer' or 'wave'), if any."""
        for d in self.devices:
            if d.role == role:
                return d
        return None

    def wave_sensor(self, channel: str) -> WaveSensor | None:
        for w in self.wave_sensors:
            if w.channel == channel:
                return w
        return None

    @property
    def accelerometers(self) -> tuple[ChannelConfig, ...]:
        return tuple(c for d in self.devices for c in d.channels if c.kind == "accelerometer")

    def features(self) -> dict:
        """The rig block of the measured-features file (CONTRACT section 2).

        ``wave_path_m``: the spacing of the two outermost wave sensors (arrival
        time differences, as with a pencil-lead break), or the distance of the
        only one from the source. ``temperature_c`` is not known to the rig.
        """
        d = sorted(w.distance_m for w in self.wave_sensors)
        out: dict = {
            "accelerometers": [{"x": c.x, "y": c.y, "mass_kg": c.mass_kg} for c in self.accelerometers],
            "supports": [{"x": x, "y": y} for x, y in self.supports],
        }
        if d:
            out["wave_path_m"] = d[-1] - d[0] if len(d) > 1 else d[0]
            out["sensor_length_m"] = max(w.length_m for w in self.wave_sensors)
            out["wave_sensors"] = [{"channel": w.channel, "distance_m": w.distance_m,
                                    "direction_deg": w.direction_deg} for w in self.wave_sensors]
        return out

    def check_specimen(self, length: float, width: float) -> None:
        """Every position on the plate must lie within it (UserError otherwise)."""
        pts = [(key, src.x, src.y) for key, src in (("hammer", self.hammer), ("wave_source", self.wave_source))
               if src is not None]
        pts += [(f"supports[{i}]", x, y) for i, (x, y) in enumerate(self.supports)]
        for d in self.devices:
            pts += [(f"devices.{d.name}.channels.{c.name}", c.x, c.y)
                    for c in d.channels if c.x is not None]
        for key, x, y in pts:
            if not (-1e-12 <= x <= length + 1e-12 and -1e-12 <= y <= width + 1e-12):
                raise UserError(f"position ({x:g}, {y:g}) m lies outside the {length:g} x {width:g} m "
                                "plate; expected 0 <= x <= length, 0 <= y <= width",
                                file=self.source, key=key)


# -- parsing -------------------------------------------------------------
