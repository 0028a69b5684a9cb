"""Serial instrument drivers against the simulated instruments over a pty / socket."""
from __future__ import annotations

import pytest
import serial

from drivers.protocol import AcquisitionError
from drivers.serial_instruments import (EnvironmentProbe, HammerUnit, Identity, InstrumentError,
                                        InstrumentRefused)
from mock_hw.serial_sim import PtyServer, SimEnvProbe, SimHammer, TcpServer

FAST = dict(timeout_s=0.15, tries=3, retry_delay_s=0.0)  # generous: shared CPUs


@pytest.fixture
def probe_sim():
    sim = SimEnvProbe(temperature_c=23.41, humidity_pct=45.2, serial="EP0042", firmware="1.3")
    with PtyServer(sim) as srv:
        yield sim, srv


@pytest.fixture
def probe(probe_sim):
    sim, srv = probe_sim
    with EnvironmentProbe(srv.port, **FAST) as p:
        yield sim, p


@pytest.fixture
def hammer():
    sim = SimHammer(recharge_s=0.0, level_pct=50, serial="HU0007")
    with PtyServer(sim) as srv, HammerUnit(srv.port, **FAST) as h:
        yield sim, h


def one_line(err: BaseException) -> str:
    msg = str(err)
    assert "\n" not in msg
    return msg


# ------------------------------------------------------------ environment probe
def test_probe_identity_and_values_over_pty(probe):
    sim, p = probe
    assert p.port.startswith("/dev/")
    assert p.identify() == Identity("LABID", "ENVPROBE", "EP0042", "1.3")
    assert p.temperature() == 23.41
    assert p.humidity() == 45.2
    sim.temperature_c, sim.humidity_pct = -5.5, 80.0
    assert (p.temperature(), p.humidity()) == (-5.5, 80.0)
    assert sim.received == ["*IDN?", "TEMP?", "HUM?", "TEMP?", "HUM?"]


@pytest.mark.parametrize("fault", ["noreply", "lost_reply", "garbled", "partial"])
def test_two_faults_then_success(probe, fault):
    sim, p = probe
    sim.inject(fault, times=2)
    assert p.temperature() == 23.41
    assert sim.received == ["TEMP?"] * 3
    assert sim.pending_faults() == 0


@pytest.mark.parametrize("fault, words", [
    ("noreply", "no reply to TEMP? after 3 tries"),
    ("lost_reply", "no reply to TEMP? after 3 tries"),
    ("garbled", "garbled reply"),
    ("partial", "partial reply b'TEMP '"),
])
def test_persistent_fault_gives_one_line_error(probe, fault, words):
    sim, p = probe
    sim.inject(fault, times=3)
    with pytest.raises(InstrumentError) as ei:
        p.temperature()
    msg = one_line(ei.value)
    assert words in msg and msg.startswith(f"environment probe on {p.port}: ")
    assert "TEMP?" in msg and "3 tries" in msg
    assert isinstance(ei.value, AcquisitionError)
    assert len(sim.received) == 3
    # the instrument is usable again afterwards
    assert p.humidity() == 45.2


def test_mixed_faults_recovered(probe):
    sim, p = probe
    sim.inject("garbled")
    sim.inject("partial")
    assert p.humidity() == 45.2
    assert len(sim.received) == 3


def test_late_reply_is_not_taken_for_the_next_query(probe_sim):
    """A reply to TEMP? arriving while HUM? waits is recognised and skipped.

    Time line (T = 0.4 s timeout): TEMP? try 1 at 0, its reply is sent at
    0.55 s; try 2 at ~0.4 s is answered at once; HUM? at ~0.41 s is answered at
    ~0.76 s, so the stale 'TEMP 23.41' reaches the driver first, inside HUM?'s window.
    """
    sim, srv = probe_sim
    with EnvironmentProbe(srv.port, timeout_s=0.4, tries=3, retry_delay_s=0.0) as p:
        sim.inject("late", command="TEMP?", delay_s=0.55)
        sim.inject("late", command="HUM?", delay_s=0.35)
        assert p.temperature() == 23.41
        assert p.humidity() == 45.2
        assert sim.received == ["TEMP?", "TEMP?", "HUM?"]   # HUM? answered on the first try


def test_out_of_range_value_counts_as_garbled(probe):
    sim, p = probe
    sim.humidity_pct = 130.0                # impossible relative humidity
    with pytest.raises(InstrumentError, match="garbled reply b'HUM 130.00"):
        p.humidity()


def test_unknown_command_is_refused_without_retry(probe):
    sim, p = probe
    with pytest.raises(InstrumentRefused) as ei:
        p.command("PRES?", r"PRES .*")
    assert "ERR UNKNOWN PRES?" in one_line(ei.value)
    assert sim.received == ["PRES?"]


def test_wrong_instrument_on_port(hammer):
    sim, h = hammer
    probe = EnvironmentProbe(h.port, **FAST)
    try:
        with pytest.raises(InstrumentError, match="expected a LABID ENVPROBE, found 'LABID,HAMMER"):
            probe.identify()
    finally:
        probe.close()


def test_missing_port():
    with pytest.raises(InstrumentError) as ei:
        EnvironmentProbe("/dev/ttyUSB_labid_absent", **FAST)
    assert one_line(ei.value) == ("serial port /dev/ttyUSB_labid_absent not found; "
                                  "is the environment probe plugged in?")


def test_unplugged_mid_session():
    sim = SimEnvProbe()
    srv = PtyServer(sim)
    p = EnvironmentProbe(srv.port, **FAST)
    try:
        assert p.temperature() == 23.0
        srv.close()                         # the pty disappears
        with pytest.raises(InstrumentError) as ei:
            p.temperature()
        msg = one_line(ei.value)
        assert srv.port in msg and ("not found" in msg or "port error" in msg or "no reply" in msg)
    finally:
        p.close()
        srv.close()


def test_loopback_url_is_not_an_instrument():
    p = EnvironmentProbe("loop://", **FAST)
    try:
        with pytest.raises(InstrumentError, match="echo of the command .* to \\*IDN\\? after 3 tries"):
            p.identify()
    finally:
        p.close()


def test_socket_url():
    sim = SimEnvProbe(temperature_c=19.75, humidity_pct=60.0)
    with TcpServer(sim) as srv:
        assert srv.port.startswith("socket://")
        with EnvironmentProbe(srv.port, timeout_s=0.2, tries=3, retry_delay_s=0.0) as p:
            assert p.identify().model == "ENVPROBE"
            assert p.temperature() == 19.75
            sim.inject("garbled")
            assert p.humidity() == 60.0


def test_uses_serial_for_url():
    opened = []

    def factory(url, **kw):
        opened.append((url, kw))
        return serial.serial_for_url("loop://", **kw)
    p = EnvironmentProbe("/dev/ttyXYZ", baudrate=19200, timeout_s=0.15, serial_factory=factory)
    p.close()
    assert opened == [("/dev/ttyXYZ", {"baudrate": 19200, "timeout": 0.15, "write_timeout": 0.15})]


# ------------------------------------------------------------ hammer unit
def test_hammer_fire_counts_hits(hammer):
    sim, h = hammer
    fired = []
    sim.on_fire = fired.append
    assert h.identify() == Identity("LABID", "HAMMER", "HU0007", "1.0")
    assert h.fire() == 1 and h.fire() == 2
    assert sim.hits == 2 and fired == [50, 50]


def test_lost_ok_does_not_double_fire(hammer):
    sim, h = hammer
    sim.inject("lost_reply", command="FIRE")
    assert h.fire() == 1
    assert sim.hits == 1
    assert sim.received.count("FIRE") == 1


def test_unheard_fire_is_resent(hammer):
    sim, h = hammer
    sim.inject("noreply", times=2, command="FIRE")
    assert h.fire() == 1
    assert sim.hits == 1 and sim.received.count("FIRE") == 3


def test_fire_never_heard_gives_clear_error(hammer):
    sim, h = hammer
    sim.inject("noreply", times=3, command="FIRE")
    with pytest.raises(InstrumentError) as ei:
        h.fire()
    assert one_line(ei.value).endswith("no reply to FIRE after 3 tries; no hit fired")
    assert sim.hits == 0


def test_fire_waits_for_recharge(hammer):
    sim, h = hammer
    sim.recharge_s = 0.3
    h.fire()
    assert not h.ready()
    assert h.fire() == 2                    # waited for ARM 1 instead of getting ERR BUSY
    assert sim.hits == 2
    assert "ARM 0" not in sim.received and sim.received.count("ARM?") >= 3


def test_fire_gives_up_if_never_ready(hammer):
    sim, h = hammer
    sim.recharge_s = 10.0
    h.fire()
    with pytest.raises(InstrumentError, match="not ready to fire after 0.1 s"):
        h.fire(ready_timeout_s=0.1)
    assert sim.hits == 1


def test_hammer_level(hammer):
    sim, h = hammer
    h.set_level(80)
    assert h.level() == 80 and sim.level_pct == 80
    with pytest.raises(InstrumentRefused, match="LEVEL 150 refused: ERR RANGE 0..100"):
        h.set_level(150)
    assert sim.level_pct == 80
