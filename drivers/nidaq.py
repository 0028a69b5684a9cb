"""NI-DAQmx acquisition device (the real ``nidaqmx`` Python API behind the protocol).

One :class:`NiDaqDevice` owns one DAQmx task on one device (e.g. a PXIe-4497
at ~10 kHz for the hammer and accelerometers, or a PXIe-6124 at 1-5 MHz for
MFC/piezo sensors). Life cycle and the DAQmx calls it makes, in this order::

    configure()  nidaqmx.Task(name)
                 task.ai_channels.add_ai_accel_chan / add_ai_force_iepe_chan /
                     add_ai_voltage_chan                      (one per channel)
                 chan.ai_coupling = AC / DC   (see Coupling below)
                 task.timing.cfg_samp_clk_timing(rate, FINITE, samples)
                 task.timing.samp_clk_rate    (read back: rate actually used)
                 task.triggers.reference_trigger.cfg_anlg_edge_ref_trig(
                     physical, pretrigger, slope, level)      (if a trigger)
    arm()        task.start()
    read()       AnalogMultiChannelReader(task.in_stream).read_many_sample(
                     buf, samples, timeout)
                 task.in_stream.overloaded_chans_exist   (clears the flags)
                 task.in_stream.overloaded_chans         (only if any exist)
                 task.stop()                (ready for the next arm())
    close()      task.close()

Units. ``ChannelConfig.sensitivity`` is in V per SI unit (V/(m/s^2), V/N);
DAQmx wants mV/g and mV/N::

    accelerometer  units=METERS_PER_SECOND_SQUARED, sensitivity_units=MILLIVOLTS_PER_G,
                   sensitivity[mV/g] = 1000 * g0 * sensitivity[V/(m/s^2)],
                   g0 = 9.80665 m/s^2 (standard gravity, exact)
    force (IEPE)   units=NEWTONS, sensitivity_units=MILLIVOLTS_PER_NEWTON,
                   sensitivity[mV/N] = 1000 * sensitivity[V/N]
    voltage        units=VOLTS (sensitivity only used by Record.scaled)

``min_val``/``max_val`` are ``+/-range_v / sensitivity`` in those units, and the
trigger level (``Trigger.level_v``, volts at the input) is divided by the
trigger channel's sensitivity, because DAQmx takes it in the channel's units.
DAQmx returns samples in physical units; :class:`~drivers.protocol.Record`
stores VOLTS at the input, so each row is multiplied back by its sensitivity
(exact: the DAQmx scale is linear through zero).

Coupling. ``IEPE``: internal current excitation (``excitation_current_a``)
and AC coupling; ``AC``: no excitation, AC coupling; ``DC``: no excitation,
DC coupling on accelerometer/force channels (DSA boards), while a DC voltage
channel keeps the device default (multifunction boards such as the 6124 are
DC-only and reject the coupling property). A voltage channel with
``IEPE`` coupling sets ``ai_excit_src``/``ai_excit_val`` on the channel.

Overload. A channel is flagged if DAQmx lists it in ``overloaded_chans`` or
if any sample reaches 99.9 % of its range (clipping at the ADC limit).

TEDS. ``read_teds(physical, kind)`` reads a TEDS sensor's identity and sensitivity
(``labid.inputs.calibration`` uses it on the NI backend; the calibration sheet wins).

Errors. Every DAQmx failure becomes one line, an
:class:`~drivers.protocol.AcquisitionError` subclass: :class:`DriverMissing`
(no NI-DAQmx installed: suggests ``--backend mock``), :class:`NoTrigger`
(read timeout, -200474), :class:`DeviceNotFound`, :class:`DeviceBusy`,
:class:`DeviceConfigError` (rejected rate/range/trigger, bad channel list) and
:class:`DaqmxError` (anything else, with its status code).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from types import ModuleType
from typing import Any

import numpy as np

from drivers.protocol import AcquisitionError, ChannelConfig, NoTrigger, Record, Timing, Trigger

#: standard acceleration of gravity, m/s^2 (exact by definition, CGPM 1901)
G0 = 9.80665
#: pound-force in N (exact by definition)
LBF = 4.4482216152605
#: fraction of the range from which a sample counts as clipped
CLIP_FRACTION = 0.999

MOCK_HINT = "use --backend mock to run on the simulated rig"


class DriverMissing(AcquisitionError):
    """No usable NI-DAQmx driver (or nidaqmx package) on this machine."""


class DeviceNotFound(AcquisitionError):
    """The DAQ device or a physical channel does not exist."""


class DeviceBusy(AcquisitionError):
    """The device is reserved by another task or process."""


class DeviceConfigError(AcquisitionError, ValueError):
    """The device rejected (or we reject) the channels, timing or trigger."""


class DaqmxError(AcquisitionError):
    """Any other DAQmx status error; ``code`` holds the status code."""

    def __init__(self, message: str, code: int | None = None):
        super().__init__(message)
        self.code = code


# DAQmx status codes with their own one-line explanation (nidaqmx.error_codes.DAQmxErrors)
_TIMEOUT = -200474                       # OPERATION_TIMED_OUT
_NOT_FOUND = {-200220, -200170}          # INVALID_DEVICE_ID, PHYSICAL_CHAN_DOES_NOT_EXIST
_NOT_ACCESSIBLE = {-201003, -200045}      # DEV_CANNOT_BE_ACCESSED, DEVICE_REMOVED
_BUSY = {-50103, -200022}                # PAL_RESOURCE_RESERVED, RESOURCE_ALREADY_RESERVED
_BAD_RATE = {-200332, -200331, -201093, -200660}  # SAMP_RATE_TOO_HIGH/LOW, *_INVALID, *_UNAVAILABLE
_BAD_VALUE = {-200077}                   # INVALID_ATTRIBUTE_VALUE
_OVERFLOW = {-200279, -200010}           # SAMPLES_NO_LONGER_AVAILABLE, INPUT_FIFO_OVERFLOW


def _load_nidaqmx() -> ModuleType:
    try:
        import nidaqmx
        import nidaqmx.constants  # noqa: F401
        import nidaqmx.errors  # noqa: F401
        import nidaqmx.stream_readers  # noqa: F401
    except ImportError as exc:  # pragma: no cover - the package is a dependency
        raise DriverMissing(f"python package nidaqmx is not installed ({exc}); {MOCK_HINT}") from exc
    return nidaqmx


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0].strip() if text else type(exc).__name__


class NiDaqDevice:
    """An NI-DAQmx device speaking :class:`drivers.protocol.Device`.

    name: label used in messages and records; device: DAQmx device name
    (``ChannelConfig.physical`` 'ai0' becomes 'PXI1Slot2/ai0'; an empty
    ``physical`` takes 'ai<i>' in channel order). ``nidaqmx_module`` replaces the
    real ``nidaqmx`` package (tests inject a fake with ``Task``, ``constants``,
    ``errors`` and ``stream_readers``).
    """

    backend = "nidaqmx"

    def __init__(self, name: str, device: str = "PXI1Slot2", *,
                 nidaqmx_module: Any | None = None):
        self.name = name
        self.device = device
        self._nx = nidaqmx_module if nidaqmx_module is not None else _load_nidaqmx()
        self._task: Any = None
        self._reader: Any = None
        self._channels: tuple[ChannelConfig, ...] = ()
        self._physical: tuple[str, ...] = ()
        self._timing: Timing | None = None
        self._trigger: Trigger | None = None
        self._armed = False

    # ----------------------------------------------------------------- protocol
    def configure(self, channels: tuple[ChannelConfig, ...], timing: Timing,
                  trigger: Trigger | None) -> None:
        """Create the DAQmx task: channels, finite sample clock, reference trigger."""
        channels = tuple(channels)
        self._check(channels, timing, trigger)
        self.close()
        C = self._nx.constants
        physical = tuple(self._physical_name(c, i) for i, c in enumerate(channels))
        with self._mapped("creating the task"):
            self._task = self._nx.Task(f"labid-{self.name}")
        try:
            with self._mapped("adding channels"):
                for c, phys in zip(channels, physical):
                    self._add_channel(c, phys)
            with self._mapped(f"setting the sample clock to {timing.rate_hz:g} Hz"):
                self._task.timing.cfg_samp_clk_timing(
                    timing.rate_hz, sample_mode=C.AcquisitionType.FINITE,
                    samps_per_chan=int(timing.samples))
                actual = float(self._task.timing.samp_clk_rate)
            if trigger is not None:
                tc = next(c for c in channels if c.name == trigger.channel)
                slope = C.Slope.RISING if trigger.slope == "rising" else C.Slope.FALLING
                with self._mapped(f"configuring the trigger on {trigger.channel!r}"):
                    self._task.triggers.reference_trigger.cfg_anlg_edge_ref_trig(
                        physical[channels.index(tc)],
                        pretrigger_samples=int(timing.pretrigger),
                        trigger_slope=slope,
                        trigger_level=self._to_channel_units(tc, trigger.level_v))
            with self._mapped("creating the stream reader"):
                self._reader = self._nx.stream_readers.AnalogMultiChannelReader(self._task.in_stream)
        except BaseException:
            self.close()
            raise
        self._channels, self._physical, self._trigger = channels, physical, trigger
        self._timing = timing if actual == timing.rate_hz else replace(timing, rate_hz=actual)
        self._requested_rate = timing.rate_hz

    def arm(self) -> None:
        """Start the task: it fills the pre-trigger buffer and waits for the trigger."""
        if self._task is None:
            raise AcquisitionError(f"{self.name}: arm() before configure()")
        with self._mapped("starting the acquisition"):
            self._task.start()
        self._armed = True

    def read(self, timeout_s: float = 10.0) -> Record:
        """Wait for the trigger and the whole record; return it in volts at the input."""
        if not self._armed:
            raise AcquisitionError(f"{self.name}: read() before arm()")
        timing = self._timing
        n = int(timing.samples)
        buf = np.zeros((len(self._channels), n), dtype=np.float64)
        try:
            with self._mapped("reading", timeout_s=timeout_s):
                got = self._reader.read_many_sample(buf, number_of_samples_per_channel=n,
                                                    timeout=timeout_s)
                stamp = time.time()
                flagged = self._overloaded()
        finally:
            self._stop()
        if got is not None and int(got) != n:
            raise DaqmxError(f"{self.name}: DAQmx returned {int(got)} of {n} samples per channel")
        data, overload = {}, {}
        for row, c in zip(buf, self._channels):
            volts = row * c.sensitivity if c.kind != "voltage" else row.copy()
            data[c.name] = volts
            overload[c.name] = bool(c.name in flagged or c.physical in flagged
                                    or np.any(np.abs(volts) >= CLIP_FRACTION * c.range_v))
        meta = {"device": self.device, "physical": list(self._physical),
                "requested_rate_hz": self._requested_rate, "daqmx_overloaded": sorted(flagged)}
        return Record(data=data, channels=self._channels, timing=timing, trigger=self._trigger,
                      overload=overload, timestamp=stamp, backend=self.backend, meta=meta)

    def close(self) -> None:
        """Release the task (idempotent; errors while closing are ignored)."""
        task, self._task, self._reader, self._armed = self._task, None, None, False
        if task is not None:
            try:
                task.close()
            except Exception:  # noqa: BLE001 - nothing useful to do while releasing
                pass

    def __enter__(self) -> "NiDaqDevice":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- internals
    def _check(self, channels, timing, trigger) -> None:
        names = [c.name for c in channels]
        where = f"{self.name}"
        if not channels:
            raise DeviceConfigError(f"{where}: no channels to configure")
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise DeviceConfigError(f"{where}: duplicate channel name(s) {', '.join(dup)}")
        for c in channels:
            if c.kind not in ("accelerometer", "force", "voltage"):
                raise DeviceConfigError(f"{where}: channel {c.name!r} has kind {c.kind!r}; "
                                        "expected accelerometer, force or voltage")
            if not (c.sensitivity > 0 and np.isfinite(c.sensitivity)):
                raise DeviceConfigError(f"{where}: channel {c.name!r} sensitivity {c.sensitivity!r} "
                                        "V/unit; expected > 0")
            if not (c.range_v > 0 and np.isfinite(c.range_v)):
                raise DeviceConfigError(f"{where}: channel {c.name!r} range {c.range_v!r} V; expected > 0")
        if not (timing.rate_hz > 0 and np.isfinite(timing.rate_hz)):
            raise DeviceConfigError(f"{where}: sample rate {timing.rate_hz!r} Hz; expected > 0")
        if timing.samples < 2 or not 0 <= timing.pretrigger < timing.samples:
            raise DeviceConfigError(f"{where}: {timing.samples} samples with {timing.pretrigger} "
                                    "pre-trigger; expected samples >= 2 and 0 <= pretrigger < samples")
        if trigger is not None and trigger.channel not in names:
            raise DeviceConfigError(f"{where}: trigger channel {trigger.channel!r} is not one of "
                                    f"{', '.join(names)}")
        if trigger is not None and trigger.slope not in ("rising", "falling"):
            raise DeviceConfigError(f"{where}: trigger slope {trigger.slope!r}; expected rising or falling")

    def _physical_name(self, c: ChannelConfig, index: int) -> str:
        return physical_name(self.device, c, index)

    @staticmethod
    def _to_channel_units(c: ChannelConfig, volts: float) -> float:
        """Volts at the input -> the DAQmx channel's units (m/s^2, N or V)."""
        return volts if c.kind == "voltage" else volts / c.sensitivity

    def _add_channel(self, c: ChannelConfig, physical: str) -> None:
        C = self._nx.constants
        ai = self._task.ai_channels
        top = self._to_channel_units(c, c.range_v)
        iepe = c.coupling == "IEPE"
        excit = C.ExcitationSource.INTERNAL if iepe else C.ExcitationSource.NONE
        if c.kind == "accelerometer":
            chan = ai.add_ai_accel_chan(
                physical, name_to_assign_to_channel=c.name, min_val=-top, max_val=top,
                units=C.AccelUnits.METERS_PER_SECOND_SQUARED,
                sensitivity=c.sensitivity * G0 * 1e3,
                sensitivity_units=C.AccelSensitivityUnits.MILLIVOLTS_PER_G,
                current_excit_source=excit, current_excit_val=c.excitation_current_a)
        elif c.kind == "force":
            chan = ai.add_ai_force_iepe_chan(
                physical, name_to_assign_to_channel=c.name, min_val=-top, max_val=top,
                units=C.ForceUnits.NEWTONS, sensitivity=c.sensitivity * 1e3,
                sensitivity_units=C.ForceIEPESensorSensitivityUnits.MILLIVOLTS_PER_NEWTON,
                current_excit_source=excit, current_excit_val=c.excitation_current_a)
        else:
            chan = ai.add_ai_voltage_chan(
                physical, name_to_assign_to_channel=c.name, min_val=-top, max_val=top,
                units=C.VoltageUnits.VOLTS)
            if iepe:
                chan.ai_excit_src = C.ExcitationSource.INTERNAL
                chan.ai_excit_voltage_or_current = C.ExcitationVoltageOrCurrent.USE_CURRENT
                chan.ai_excit_val = c.excitation_current_a
        if c.coupling in ("IEPE", "AC"):
            chan.ai_coupling = C.Coupling.AC
        elif c.kind != "voltage":
            chan.ai_coupling = C.Coupling.DC

    def _overloaded(self) -> set[str]:
        stream = self._task.in_stream
        if not stream.overloaded_chans_exist:   # must be read first: it latches/clears
            return set()
        return {str(n) for n in stream.overloaded_chans}

    def _stop(self) -> None:
        self._armed = False
        try:
            self._task.stop()
        except Exception:  # noqa: BLE001 - the read error (if any) is the one to report
            pass

    def _mapped(self, doing: str, timeout_s: float | None = None) -> "_ErrorMap":
        return _ErrorMap(self, doing, timeout_s)

    def translate(self, exc: BaseException, doing: str, timeout_s: float | None = None) -> AcquisitionError:
        """One-line :class:`AcquisitionError` for a nidaqmx exception."""
        errors = self._nx.errors
        who = f"{self.name} ({self.device})"
        if isinstance(exc, errors.DaqNotFoundError):
            return DriverMissing(f"{who}: no NI-DAQmx driver is installed on this machine; "
                                 f"install NI-DAQmx or {MOCK_HINT}")
        if isinstance(exc, errors.DaqNotSupportedError):
            return DriverMissing(f"{who}: NI-DAQmx is not supported on this platform; {MOCK_HINT}")
        if isinstance(exc, errors.DaqFunctionNotSupportedError):
            return DriverMissing(f"{who}: the installed NI-DAQmx is too old for {doing} "
                                 f"({_first_line(exc)}); update NI-DAQmx or {MOCK_HINT}")
        code = getattr(exc, "error_code", None)
        if code == _TIMEOUT and timeout_s is None:
            return DaqmxError(f"{who}: DAQmx timed out while {doing} (DAQmx {code})", code)
        if code == _TIMEOUT:
            trig = self._trigger
            what = (f"no trigger on {trig.channel!r} ({trig.slope} through {trig.level_v:g} V)"
                    if trig is not None else "record not complete")
            rec = self._timing.samples / self._timing.rate_hz if self._timing else 0.0
            return NoTrigger(f"{who}: {what} within {timeout_s:g} s "
                             f"(record length {rec:g} s); hit harder or lower the trigger level")
        if code in _NOT_FOUND:
            return DeviceNotFound(f"{who}: device or channel not found while {doing}; "
                                  f"check the device name in NI MAX and the rig file "
                                  f"(DAQmx {code})")
        if code in _NOT_ACCESSIBLE:
            return DeviceNotFound(f"{who}: device cannot be accessed (unplugged, powered off "
                                  f"or chassis not detected) (DAQmx {code})")
        if code in _BUSY:
            return DeviceBusy(f"{who}: device is in use by another task or program; close it "
                              f"and retry (DAQmx {code})")
        if code in _BAD_RATE:
            return DeviceConfigError(f"{who}: sample rate rejected while {doing}: "
                                     f"{_first_line(exc)} (DAQmx {code})")
        if code in _OVERFLOW:
            return DaqmxError(f"{who}: buffer overflow while {doing}: the computer did not read the "
                              f"samples before the device overwrote them; lower the sample rate or the "
                              f"number of channels, or close other programs, and retry (DAQmx {code})", code)
        if code in _BAD_VALUE:
            return DeviceConfigError(f"{who}: value rejected while {doing}: "
                                     f"{_first_line(exc)} (DAQmx {code})")
        if code is not None:
            return DaqmxError(f"{who}: DAQmx error {code} while {doing}: {_first_line(exc)}", code)
        return DaqmxError(f"{who}: {type(exc).__name__} while {doing}: {_first_line(exc)}")


def physical_name(device: str, c: ChannelConfig, index: int) -> str:
    """The DAQmx physical channel of ``c`` (the ``index``-th channel) on ``device``."""
    if not c.physical:
        return f"{device}/ai{index}"
    return c.physical if "/" in c.physical else f"{device}/{c.physical}"


@dataclass(frozen=True)
class TedsInfo:
    """What a TEDS sensor (IEEE 1451.4) tells through DAQmx: manufacturer id, model,
    serial and version numbers, and the sensitivity in V per SI unit (V/(m/s^2), V/N;
    None for a voltage channel). The calibration date sits in the template bit stream,
    which DAQmx does not decode: it is not read."""

    physical: str
    manufacturer_id: int
    model: int
    serial: int
    version: str
    sensitivity: float | None


def read_teds(physical: str, kind: str, *, nidaqmx_module: Any | None = None) -> TedsInfo | None:
    """The TEDS of the sensor on ``physical`` (None when there is none, or no NI-DAQmx).

    Calls ``nidaqmx.system.PhysicalChannel(physical).configure_teds()`` (find the sensor),
    reads ``teds_mfg_id``, ``teds_model_num``, ``teds_serial_num``, ``teds_version_num``/
    ``teds_version_letter``, then the sensitivity DAQmx took from TEDS through a
    temporary task: ``add_teds_ai_accel_chan`` -> ``ai_accel_sensitivity`` (mV/g or V/g),
    ``add_teds_ai_force_iepe_chan`` -> ``ai_force_iepe_sensor_sensitivity`` (mV/N or
    mV/lb)."""
    try:
        nx = nidaqmx_module if nidaqmx_module is not None else _load_nidaqmx()
    except DriverMissing:
        return None
    C = nx.constants
    try:
        pc = nx.system.PhysicalChannel(physical)
        pc.configure_teds()
        info = dict(manufacturer_id=int(pc.teds_mfg_id), model=int(pc.teds_model_num),
                    serial=int(pc.teds_serial_num),
                    version=f"{pc.teds_version_num}{pc.teds_version_letter}")
        sens = None
        if kind in ("accelerometer", "force"):
            with nx.Task("labid-teds") as task:
                if kind == "accelerometer":
                    ch = task.ai_channels.add_teds_ai_accel_chan(
                        physical, units=C.AccelUnits.METERS_PER_SECOND_SQUARED)
                    per_g = 1e-3 if ch.ai_accel_sensitivity_units == C.AccelSensitivityUnits.MILLIVOLTS_PER_G else 1.0
                    sens = float(ch.ai_accel_sensitivity) * per_g / G0
                else:
                    ch = task.ai_channels.add_teds_ai_force_iepe_chan(physical, units=C.ForceUnits.NEWTONS)
                    mv_lb = C.ForceIEPESensorSensitivityUnits.MILLIVOLTS_PER_POUND
                    per_n = 1e-3 / LBF if ch.ai_force_iepe_sensor_sensitivity_units == mv_lb else 1e-3
                    sens = float(ch.ai_force_iepe_sensor_sensitivity) * per_n
    except nx.errors.Error:
        return None
    return TedsInfo(physical=physical, sensitivity=sens, **info)


class _ErrorMap:
    """Context manager turning nidaqmx errors into one-line AcquisitionErrors."""

    def __init__(self, dev: NiDaqDevice, doing: str, timeout_s: float | None):
        self.dev, self.doing, self.timeout_s = dev, doing, timeout_s

    def __enter__(self) -> None:
        return None

    def __exit__(self, etype, exc, tb) -> bool:
        if exc is None or isinstance(exc, AcquisitionError):
            return False
        if isinstance(exc, self.dev._nx.errors.Error):
            raise self.dev.translate(exc, self.doing, self.timeout_s) from exc
        return False
