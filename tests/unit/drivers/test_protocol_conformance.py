"""One conformance test per protocol (ophyd-style): every real and simulated device speaks it.

* ``drivers.protocol.Device``: the NI-DAQmx driver (on a fake nidaqmx layer) and the
  simulated rig's device run configure -> arm -> read -> close and return a ``Record`` that
  holds what was configured.
* ``drivers.protocol.Instrument``: each serial driver talks to its simulated instrument
  (``mock_hw.serial_sim``) over an in-memory wire: every command of the "LABID serial v1"
  table is answered in the form the driver accepts, and an injected fault is recovered.
"""
from __future__ import annotations

import inspect

import numpy as np
import pytest

from drivers.nidaq import NiDaqDevice
from drivers.protocol import Device, Instrument, Record
from drivers.serial_instruments import EnvironmentProbe, HammerUnit
from labid.inputs.rig import read_rig_text, rig_from_text
from labid.inputs.specimen import load_specimen
from mock_hw.rig import SimulatedDevice
from mock_hw.serial_sim import SimEnvProbe, SimHammer
from tests.unit.drivers.test_nidaq import ACC, HAMMER, TIMING, TRIG, FakeRig


def _fast_rig():
    text, _ = read_rig_text("default")
    return rig_from_text(text.replace("n_modes = 40", "n_modes = 8").replace("samples = 20000", "samples = 2048"),
                         "fast rig")


def nidaq():
    return NiDaqDevice("low", nidaqmx_module=FakeRig()), (ACC, HAMMER), TIMING, TRIG


def simulated():
    rig = _fast_rig()
    d = rig.device("hammer")
    return SimulatedDevice(rig, load_specimen("cfrp"), "hammer"), d.channels, d.timing, d.trigger


def _signature(obj, name):
    return [p.name for p in inspect.signature(getattr(obj, name)).parameters.values() if p.name != "self"]


@pytest.mark.parametrize("make", [nidaq, simulated], ids=["nidaq", "simulated"])
def test_acquisition_devices_speak_the_device_protocol(make):
    dev, channels, timing, trigger = make()
    assert isinstance(dev, Device) and isinstance(dev.name, str)
    for method in ("configure", "arm", "read", "close"):
        assert _signature(dev, method) == _signature(Device, method), method
    dev.configure(tuple(channels), timing, trigger)
    dev.arm()
    rec = dev.read(timeout_s=5.0)
    dev.close()
    assert isinstance(rec, Record)
    assert [c.name for c in rec.channels] == [c.name for c in channels]
    assert rec.timing == timing and rec.trigger == trigger
    assert set(rec.data) == set(rec.overload) == {c.name for c in channels}
    assert all(np.asarray(x).shape == (timing.samples,) for x in rec.data.values())
    assert rec.t0_index == timing.pretrigger and rec.time()[timing.pretrigger] == 0.0


class Wire:
    """A pyserial stand-in connecting a driver to a simulated instrument in memory."""

    def __init__(self, sim):
        self.sim, self.buf = sim, b""

    def reset_input_buffer(self):
        self.buf = b""

    def write(self, data: bytes) -> int:
        for line in data.split(b"\n")[:-1]:
            reply, _delay = self.sim.handle(line.decode("ascii"))
            self.buf += reply
        return len(data)

    def flush(self):
        pass

    def read_until(self, expected=b"\n", size=None):
        i = self.buf.find(expected)
        end = len(self.buf) if i < 0 else i + 1
        end = end if size is None else min(end, size)
        out, self.buf = self.buf[:end], self.buf[end:]
        return out

    def close(self):
        pass


def _on_wire(cls, sim):
    return cls("sim://", serial_factory=lambda *a, **k: Wire(sim), timeout_s=0.1, tries=3, retry_delay_s=0.0)


def test_environment_probe_and_its_simulation_agree():
    sim = SimEnvProbe(temperature_c=21.5, humidity_pct=38.25)
    with _on_wire(EnvironmentProbe, sim) as p:
        assert isinstance(p, Instrument)
        assert p.identify().model == "ENVPROBE"
        assert (p.temperature(), p.humidity()) == (21.5, 38.25)
        sim.inject("garbled")
        assert p.temperature() == 21.5
    assert sim.received == ["*IDN?", "TEMP?", "HUM?", "TEMP?", "TEMP?"] and sim.pending_faults() == 0


def test_hammer_unit_and_its_simulation_agree():
    sim = SimHammer(level_pct=40)
    with _on_wire(HammerUnit, sim) as h:
        assert isinstance(h, Instrument)
        assert h.identify().model == "HAMMER"
        assert h.ready() and h.count() == 0 and h.level() == 40
        h.set_level(70)
        assert h.level() == 70
        sim.inject("lost_reply", command="FIRE")
        assert h.fire() == 1 and sim.hits == 1            # the lost OK did not fire twice
    assert sim.received.count("FIRE") == 1
