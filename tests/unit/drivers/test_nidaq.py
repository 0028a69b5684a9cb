"""NiDaqDevice against a fake nidaqmx layer (no NI driver on these machines).

The fake records every DAQmx call in order; constants and error classes are
the REAL ones from the installed nidaqmx package, so enum values and error
types are those the driver would meet on a real rig.
"""
from __future__ import annotations

import types

import numpy as np
import pytest

import nidaqmx.constants as C
import nidaqmx.errors as E

from drivers.nidaq import (DaqmxError, DeviceBusy, DeviceConfigError, DeviceNotFound, DriverMissing,
                           NiDaqDevice)
from drivers.protocol import AcquisitionError, ChannelConfig, Device, NoTrigger, Timing, Trigger

G0 = 9.80665  # standard gravity, m/s^2 (definition)


# ------------------------------------------------------------------ the fake
class FakeChan:
    def __init__(self, log, name):
        object.__setattr__(self, "_log", log)
        object.__setattr__(self, "_name", name)

    def __setattr__(self, key, value):
        self._log.append(("set", self._name, key, value))


class FakeAI:
    def __init__(self, log):
        self.log = log

    def _add(self, kind, physical, **kw):
        self.log.append((kind, physical, kw))
        return FakeChan(self.log, kw["name_to_assign_to_channel"])

    def add_ai_accel_chan(self, physical, **kw):
        return self._add("add_ai_accel_chan", physical, **kw)

    def add_ai_force_iepe_chan(self, physical, **kw):
        return self._add("add_ai_force_iepe_chan", physical, **kw)

    def add_ai_voltage_chan(self, physical, **kw):
        return self._add("add_ai_voltage_chan", physical, **kw)


class FakeTiming:
    def __init__(self, task):
        self.task = task
        self.rate = None

    def cfg_samp_clk_timing(self, rate, **kw):
        self.task.log.append(("cfg_samp_clk_timing", rate, kw))
        self.rate = rate * self.task.rig.rate_factor

    @property
    def samp_clk_rate(self):
        return self.rate


class FakeRefTrigger:
    def __init__(self, log):
        self.log = log

    def cfg_anlg_edge_ref_trig(self, source, **kw):
        self.log.append(("cfg_anlg_edge_ref_trig", source, kw))


class FakeInStream:
    def __init__(self, task):
        self.task = task

    @property
    def overloaded_chans_exist(self):
        self.task.log.append(("overloaded_chans_exist",))
        return bool(self.task.rig.overloaded)

    @property
    def overloaded_chans(self):
        self.task.log.append(("overloaded_chans",))
        return list(self.task.rig.overloaded)


class FakeTask:
    def __init__(self, rig, name=""):
        self.rig, self.log = rig, rig.log
        self.log.append(("Task", name))
        if rig.fail.get("Task"):
            raise rig.fail["Task"]
        self.ai_channels = FakeAI(self.log)
        self.timing = FakeTiming(self)
        self.triggers = types.SimpleNamespace(reference_trigger=FakeRefTrigger(self.log))
        self.in_stream = FakeInStream(self)

    def start(self):
        self.log.append(("start",))
        if self.rig.fail.get("start"):
            raise self.rig.fail["start"]

    def stop(self):
        self.log.append(("stop",))

    def close(self):
        self.log.append(("close",))


class FakeReader:
    def __init__(self, rig, in_stream):
        self.rig = rig
        rig.log.append(("AnalogMultiChannelReader", type(in_stream).__name__))

    def read_many_sample(self, data, number_of_samples_per_channel=-1, timeout=10.0):
        self.rig.log.append(("read_many_sample", data.shape, number_of_samples_per_channel, timeout))
        if self.rig.fail.get("read"):
            raise self.rig.fail["read"]
        data[...] = self.rig.physical_rows(data.shape)
        return number_of_samples_per_channel


class FakeRig:
    """A module-like object standing in for ``nidaqmx``."""

    def __init__(self):
        self.log: list = []
        self.fail: dict = {}
        self.overloaded: list[str] = []
        self.rate_factor = 1.0
        self.rows = None
        self.constants, self.errors = C, E
        self.Task = lambda new_task_name="": FakeTask(self, new_task_name)
        self.stream_readers = types.SimpleNamespace(
            AnalogMultiChannelReader=lambda s: FakeReader(self, s))

    def physical_rows(self, shape):
        if self.rows is None:
            return np.zeros(shape)
        return np.asarray(self.rows, float)

    def calls(self):
        return [e[0] for e in self.log]


# ------------------------------------------------------------------ a rig
ACC_MV_PER_G = 10.2     # PCB 352C33-like accelerometer, mV/g
HAMMER_MV_PER_N = 2.25  # PCB 086C03 impact hammer, mV/N
ACC = ChannelConfig("acc1", "accelerometer", "ai0", sensitivity=ACC_MV_PER_G * 1e-3 / G0,
                    range_v=5.0, coupling="IEPE", x=0.1, y=0.1, excitation_current_a=0.004)
HAMMER = ChannelConfig("hammer", "force", "ai3", sensitivity=HAMMER_MV_PER_N * 1e-3,
                       range_v=5.0, coupling="IEPE", excitation_current_a=0.002)
MFC = ChannelConfig("mfc1", "voltage", "PXI1Slot3/ai1", sensitivity=1.0, range_v=2.0,
                    coupling="DC")
TIMING = Timing(rate_hz=10240.0, samples=8, pretrigger=2)
TRIG = Trigger("hammer", level_v=0.45, slope="rising")


@pytest.fixture
def rig():
    return FakeRig()


def configured(rig, channels=(ACC, HAMMER, MFC), timing=TIMING, trigger=TRIG):
    dev = NiDaqDevice("low", device="PXI1Slot2", nidaqmx_module=rig)
    dev.configure(channels, timing, trigger)
    return dev


# ------------------------------------------------------------------ tests
def test_satisfies_protocol(rig):
    assert isinstance(NiDaqDevice("x", nidaqmx_module=rig), Device)


def test_exact_calls_in_order(rig):
    dev = configured(rig)
    dev.arm()
    rec = dev.read(timeout_s=3.0)
    dev.close()
    assert rig.calls() == [
        "Task",
        "add_ai_accel_chan", "set",
        "add_ai_force_iepe_chan", "set",
        "add_ai_voltage_chan",
        "cfg_samp_clk_timing",
        "cfg_anlg_edge_ref_trig",
        "AnalogMultiChannelReader",
        "start",
        "read_many_sample",
        "overloaded_chans_exist",
        "stop",
        "close",
    ]
    log = rig.log
    assert log[0] == ("Task", "labid-low")
    # physical names: bare 'ai0' is prefixed with the device, full names kept
    assert log[1][1] == "PXI1Slot2/ai0" and log[3][1] == "PXI1Slot2/ai3"
    assert log[5][1] == "PXI1Slot3/ai1"
    assert log[1][2]["name_to_assign_to_channel"] == "acc1"
    # IEPE -> AC coupling on the channel objects
    assert log[2] == ("set", "acc1", "ai_coupling", C.Coupling.AC)
    assert log[4] == ("set", "hammer", "ai_coupling", C.Coupling.AC)
    # finite sample clock with the record length
    assert log[6] == ("cfg_samp_clk_timing", 10240.0,
                      {"sample_mode": C.AcquisitionType.FINITE, "samps_per_chan": 8})
    # reference trigger on the hammer's physical channel with the pre-trigger
    src, kw = log[7][1], log[7][2]
    assert src == "PXI1Slot2/ai3"
    assert kw["pretrigger_samples"] == 2 and kw["trigger_slope"] == C.Slope.RISING
    # read: one buffer (channels x samples), whole record, caller's timeout
    assert log[10] == ("read_many_sample", (3, 8), 8, 3.0)
    assert rec.backend == "nidaqmx" and rec.t0_index == 2
    assert list(rec.data) == ["acc1", "hammer", "mfc1"]


def test_accelerometer_units_to_daqmx(rig):
    configured(rig)
    kind, phys, kw = rig.log[1]
    assert kind == "add_ai_accel_chan"
    assert kw["units"] == C.AccelUnits.METERS_PER_SECOND_SQUARED
    assert kw["sensitivity_units"] == C.AccelSensitivityUnits.MILLIVOLTS_PER_G
    assert kw["sensitivity"] == pytest.approx(ACC_MV_PER_G, rel=1e-12)
    # +/-5 V at 10.2 mV/g is +/-490.196 g = +/-4807.18 m/s^2
    assert kw["max_val"] == pytest.approx(5.0 / 10.2e-3 * G0, rel=1e-12)
    assert kw["min_val"] == pytest.approx(-4807.181, rel=1e-6)
    assert kw["current_excit_source"] == C.ExcitationSource.INTERNAL
    assert kw["current_excit_val"] == 0.004


def test_force_units_and_trigger_level_in_newtons(rig):
    configured(rig)
    kind, phys, kw = rig.log[3]
    assert kind == "add_ai_force_iepe_chan"
    assert kw["units"] == C.ForceUnits.NEWTONS
    assert kw["sensitivity_units"] == C.ForceIEPESensorSensitivityUnits.MILLIVOLTS_PER_NEWTON
    assert kw["sensitivity"] == pytest.approx(2.25, rel=1e-12)
    assert kw["max_val"] == pytest.approx(5.0 / 2.25e-3, rel=1e-12)   # 2222.2 N
    assert kw["current_excit_val"] == 0.002
    # DAQmx takes the trigger level in the channel's units: 0.45 V / 2.25 mV/N = 200 N
    assert rig.log[7][2]["trigger_level"] == pytest.approx(200.0, rel=1e-12)


def test_voltage_channel_plain_volts(rig):
    configured(rig)
    kind, phys, kw = rig.log[5]
    assert kind == "add_ai_voltage_chan"
    assert kw["units"] == C.VoltageUnits.VOLTS
    assert (kw["min_val"], kw["max_val"]) == (-2.0, 2.0)
    # DC voltage channel: coupling left at the device default (no 'set' after it)
    assert rig.log[6][0] == "cfg_samp_clk_timing"


def test_falling_slope_and_voltage_trigger(rig):
    configured(rig, trigger=Trigger("mfc1", level_v=-0.1, slope="falling"))
    _, src, kw = rig.log[7]
    assert src == "PXI1Slot3/ai1"
    assert kw["trigger_slope"] == C.Slope.FALLING and kw["trigger_level"] == -0.1


def test_no_trigger_no_reference_trigger_call(rig):
    configured(rig, trigger=None)
    assert "cfg_anlg_edge_ref_trig" not in rig.calls()


def test_iepe_voltage_and_ac_accel(rig):
    mfc_iepe = ChannelConfig("p1", "voltage", "ai5", coupling="IEPE", excitation_current_a=0.002)
    acc_ac = ChannelConfig("a2", "accelerometer", "ai6", sensitivity=1e-3, coupling="AC")
    configured(rig, channels=(mfc_iepe, acc_ac), trigger=None)
    sets = [e[2:] for e in rig.log if e[0] == "set" and e[1] == "p1"]
    assert ("ai_excit_src", C.ExcitationSource.INTERNAL) in sets
    assert ("ai_excit_voltage_or_current", C.ExcitationVoltageOrCurrent.USE_CURRENT) in sets
    assert ("ai_excit_val", 0.002) in sets and ("ai_coupling", C.Coupling.AC) in sets
    acc_kw = next(e[2] for e in rig.log if e[0] == "add_ai_accel_chan")
    assert acc_kw["current_excit_source"] == C.ExcitationSource.NONE


def test_record_is_volts_at_input(rig):
    dev = configured(rig)
    # DAQmx returns physical units: 1 g on acc1, 100 N on the hammer, 0.3 V on the MFC
    rig.rows = np.array([[G0] * 8, [100.0] * 8, [0.3] * 8])
    dev.arm()
    rec = dev.read()
    np.testing.assert_allclose(rec.data["acc1"], 10.2e-3, rtol=1e-12)    # 10.2 mV per g
    np.testing.assert_allclose(rec.data["hammer"], 0.225, rtol=1e-12)    # 2.25 mV/N * 100 N
    np.testing.assert_allclose(rec.data["mfc1"], 0.3)
    np.testing.assert_allclose(rec.scaled("acc1"), G0, rtol=1e-12)       # back to m/s^2
    np.testing.assert_allclose(rec.scaled("hammer"), 100.0, rtol=1e-12)
    assert rec.overload == {"acc1": False, "hammer": False, "mfc1": False}


def test_overload_from_in_stream(rig):
    dev = configured(rig)
    rig.overloaded = ["acc1"]
    dev.arm()
    rec = dev.read()
    assert rec.overload == {"acc1": True, "hammer": False, "mfc1": False}
    calls = rig.calls()
    # overloaded_chans_exist must be read before overloaded_chans, both before stop
    i = calls.index("overloaded_chans_exist")
    assert calls[i + 1] == "overloaded_chans" and calls[i + 2] == "stop"


def test_overload_from_clipping(rig):
    dev = configured(rig)
    rows = np.zeros((3, 8))
    rows[1, 4] = 5.0 / 2.25e-3     # hammer at full scale: 2222 N -> 5 V
    rows[2, 3] = -1.9              # MFC within its 2 V range
    rig.rows = rows
    dev.arm()
    rec = dev.read()
    assert rec.overload == {"acc1": False, "hammer": True, "mfc1": False}


def test_reads_back_coerced_rate(rig):
    rig.rate_factor = 1.024         # device coerces 10 kHz to 10.24 kHz
    dev = configured(rig, timing=Timing(10000.0, 8, 2))
    dev.arm()
    rec = dev.read()
    assert rec.timing.rate_hz == pytest.approx(10240.0)
    assert rec.meta["requested_rate_hz"] == 10000.0


def test_timeout_is_no_trigger_and_task_stopped(rig):
    dev = configured(rig)
    rig.fail["read"] = E.DaqReadError("Wait Until Done did not indicate that the task was "
                                      "done within the specified timeout.\nIncrease the timeout",
                                      -200474, 0)
    dev.arm()
    with pytest.raises(NoTrigger) as ei:
        dev.read(timeout_s=0.5)
    msg = str(ei.value)
    assert "\n" not in msg and "'hammer'" in msg and "0.45 V" in msg and "0.5 s" in msg
    assert rig.calls()[-1] == "stop"
    # the device can be re-armed for the next shot
    rig.fail.clear()
    dev.arm()
    assert dev.read().overload["acc1"] is False


@pytest.mark.parametrize("code, cls, words", [
    (-200220, DeviceNotFound, "not found"),
    (-201003, DeviceNotFound, "cannot be accessed"),
    (-50103, DeviceBusy, "in use"),
    (-200332, DeviceConfigError, "sample rate"),
    (-200077, DeviceConfigError, "value rejected"),
    (-209999, DaqmxError, "-209999"),
    (-200474, DaqmxError, "timed out while starting"),   # a timeout outside read()
])
def test_daqmx_errors_one_line(rig, code, cls, words):
    rig.fail["start"] = E.DaqError("Some DAQmx text.\nProperty: X\nChannel: Y", code, "t")
    dev = configured(rig)
    with pytest.raises(cls) as ei:
        dev.arm()
    msg = str(ei.value)
    assert isinstance(ei.value, AcquisitionError)
    assert "\n" not in msg and words in msg and "low" in msg


@pytest.mark.parametrize("exc, words", [
    (E.DaqNotFoundError("Could not find an installation of NI-DAQmx."), "no NI-DAQmx driver"),
    (E.DaqNotSupportedError("NI-DAQmx not supported on this platform."), "not supported"),
    (E.DaqFunctionNotSupportedError("DAQmxCreateTask not found"), "too old"),
])
def test_driver_missing_from_fake(rig, exc, words):
    rig.fail["Task"] = exc
    dev = NiDaqDevice("low", nidaqmx_module=rig)
    with pytest.raises(DriverMissing) as ei:
        dev.configure((ACC,), TIMING, None)
    msg = str(ei.value)
    assert "\n" not in msg and words in msg and "--backend mock" in msg


def test_failure_while_configuring_closes_task(rig):
    class Boom(FakeAI):
        def add_ai_voltage_chan(self, physical, **kw):
            raise E.DaqError("Physical channel does not exist.", -200170)
    dev = NiDaqDevice("low", nidaqmx_module=rig)
    orig = rig.Task

    def task(name=""):
        t = orig(name)
        t.ai_channels = Boom(rig.log)
        return t
    rig.Task = task
    with pytest.raises(DeviceNotFound):
        dev.configure((ACC, MFC), TIMING, None)
    assert rig.calls()[-1] == "close"


@pytest.mark.parametrize("channels, timing, trigger, words", [
    ((ACC, ACC), TIMING, None, "duplicate"),
    ((ACC,), TIMING, Trigger("nope"), "'nope'"),
    ((ACC,), Timing(-1.0, 8, 0), None, "rate"),
    ((ACC,), Timing(1e4, 8, 8), None, "pre-trigger"),
    ((ChannelConfig("a", "accelerometer", sensitivity=0.0),), TIMING, None, "sensitivity"),
])
def test_bad_configuration_rejected_before_daqmx(rig, channels, timing, trigger, words):
    dev = NiDaqDevice("low", nidaqmx_module=rig)
    with pytest.raises(DeviceConfigError, match=words):
        dev.configure(channels, timing, trigger)
    assert rig.log == []


def test_read_before_arm(rig):
    dev = configured(rig)
    with pytest.raises(AcquisitionError, match="before arm"):
        dev.read()


def _ni_driver_installed() -> bool:
    import nidaqmx
    try:
        nidaqmx.Task().close()
    except E.DaqNotFoundError:
        return False
    except Exception:  # noqa: BLE001 - a driver is there but something else failed
        return True
    return True


@pytest.mark.skipif(_ni_driver_installed(), reason="NI-DAQmx is installed on this machine")
def test_real_nidaqmx_without_driver_says_so():
    """No NI-DAQmx C library here: the real package raises DaqNotFoundError."""
    dev = NiDaqDevice("low", device="PXI1Slot2")   # the real nidaqmx package
    with pytest.raises(DriverMissing) as ei:
        dev.configure((ACC, HAMMER), TIMING, TRIG)
    msg = str(ei.value)
    assert "\n" not in msg
    assert "no NI-DAQmx driver is installed" in msg and "--backend mock" in msg
    assert isinstance(ei.value.__cause__, E.DaqNotFoundError)
