"""Serial instrument drivers against scripted byte exchanges (PyMeasure's ``expected_protocol``
style: each command the driver writes is checked byte for byte, and the scripted reply is
what the port then reads), plus one pty smoke test of the real transport.

The faults a serial line shows are scripted replies: ``b""`` (no reply: the read times out),
a reply cut short (no ``\\n``), bytes that are not ASCII, a stale line answering an earlier
query, an exception from the port (unplugged)."""
from __future__ import annotations

import errno
import itertools

import pytest
import serial

from drivers.protocol import AcquisitionError
from drivers.serial_instruments import (EnvironmentProbe, HammerUnit, Identity, InstrumentError,
                                        InstrumentRefused)
from mock_hw.serial_sim import PtyServer, SimEnvProbe

FAST = dict(timeout_s=0.15, tries=3, retry_delay_s=0.0)


class Scripted:
    """A pyserial port replaying ``(command, reply)`` pairs: the driver must write exactly
    ``command + b"\\n"``; ``reply`` (bytes, or an exception to raise on reading) is what it
    reads next. Unread bytes are dropped by ``reset_input_buffer`` as on a real port."""

    def __init__(self, pairs):
        self.pairs = iter(pairs)
        self.buf = b""
        self.error: Exception | None = None
        self.closed = False
        self.written: list[bytes] = []

    def reset_input_buffer(self) -> None:
        self.buf = b""

    def write(self, data: bytes) -> int:
        self.written.append(data)
        try:
            cmd, reply = next(self.pairs)
        except StopIteration:
            raise AssertionError(f"unexpected command {data!r}: the script is over") from None
        want = cmd + b"\n"
        assert data == want, f"wrote {data!r}, the script expects {want!r}"
        if isinstance(reply, Exception):
            self.error = reply
        else:
            self.buf += reply
        return len(data)

    def flush(self) -> None:
        pass

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        if self.error is not None:
            err, self.error = self.error, None
            raise err
        i = self.buf.find(expected)
        end = len(self.buf) if i < 0 else i + len(expected)
        if size is not None:
            end = min(end, size)
        out, self.buf = self.buf[:end], self.buf[end:]
        return out

    def close(self) -> None:
        self.closed = True

    def finished(self) -> bool:
        return next(self.pairs, None) is None


def expected_protocol(cls, pairs, **kw):
    """The driver ``cls`` on a scripted port (and the port, to check the script was used up)."""
    port = Scripted(pairs)
    opened = []

    def factory(url, **_):
        if opened:                       # a reopen after a port error: the device is gone
            raise serial.SerialException(errno.ENOENT, f"could not open port {url}: No such file")
        opened.append(url)
        return port
    return cls("/dev/ttyUSB0", serial_factory=factory, **{**FAST, **kw}), port


def one_line(err: BaseException) -> str:
    msg = str(err)
    assert "\n" not in msg
    return msg


# ------------------------------------------------------------ environment probe
def test_probe_identity_and_values():
    p, port = expected_protocol(EnvironmentProbe, [(b"*IDN?", b"LABID,ENVPROBE,EP0042,1.3\n"),
                                                   (b"TEMP?", b"TEMP 23.41\n"), (b"HUM?", b"HUM 45.20\r\n")])
    assert p.identify() == Identity("LABID", "ENVPROBE", "EP0042", "1.3")
    assert (p.temperature(), p.humidity()) == (23.41, 45.2)
    assert port.finished()


@pytest.mark.parametrize("bad", [b"", b"TEMP ", b"T\xc5MP 2\xb3.41\n", b"TEMP 23.41 C\n"],
                         ids=["no reply", "partial", "not ascii", "garbled"])
def test_two_faults_then_success(bad):
    p, port = expected_protocol(EnvironmentProbe, [(b"TEMP?", bad), (b"TEMP?", bad), (b"TEMP?", b"TEMP 23.41\n")])
    assert p.temperature() == 23.41 and port.finished()


@pytest.mark.parametrize("bad, words", [(b"", "no reply to TEMP? after 3 tries"),
                                        (b"T\xc5MP\n", "garbled reply"),
                                        (b"TEMP ", "partial reply b'TEMP '")])
def test_persistent_fault_gives_one_line_error_and_the_probe_still_works(bad, words):
    p, port = expected_protocol(EnvironmentProbe, [(b"TEMP?", bad)] * 3 + [(b"HUM?", b"HUM 45.20\n")])
    with pytest.raises(InstrumentError) as ei:
        p.temperature()
    msg = one_line(ei.value)
    assert words in msg and msg.startswith("environment probe on /dev/ttyUSB0: ") and "3 tries" in msg
    assert isinstance(ei.value, AcquisitionError)
    assert p.humidity() == 45.2 and port.finished()


def test_a_late_reply_to_an_earlier_query_is_skipped():
    """TEMP? times out, its reply arrives while HUM? waits: recognised by its keyword."""
    p, port = expected_protocol(EnvironmentProbe, [(b"TEMP?", b""), (b"TEMP?", b"TEMP 23.41\n"),
                                                   (b"HUM?", b"TEMP 23.41\nHUM 45.20\n")])
    assert p.temperature() == 23.41 and p.humidity() == 45.2 and port.finished()


def test_out_of_range_value_counts_as_garbled():
    p, _ = expected_protocol(EnvironmentProbe, [(b"HUM?", b"HUM 130.00\n")] * 3)
    with pytest.raises(InstrumentError, match="garbled reply b'HUM 130.00"):
        p.humidity()


def test_unknown_command_is_refused_without_retry():
    p, port = expected_protocol(EnvironmentProbe, [(b"PRES?", b"ERR UNKNOWN PRES?\n")])
    with pytest.raises(InstrumentRefused) as ei:
        p.command("PRES?", r"PRES .*")
    assert "ERR UNKNOWN PRES?" in one_line(ei.value) and port.finished()


def test_wrong_instrument_on_port():
    p, _ = expected_protocol(EnvironmentProbe, [(b"*IDN?", b"LABID,HAMMER,HU0007,1.0\n")])
    with pytest.raises(InstrumentError, match="expected a LABID ENVPROBE, found 'LABID,HAMMER"):
        p.identify()


def test_unplugged_mid_session_is_one_line():
    p, _ = expected_protocol(EnvironmentProbe, [(b"TEMP?", b"TEMP 23.00\n"),
                                                (b"TEMP?", serial.SerialException("device reports readiness "
                                                                                  "to read but returned no data"))])
    assert p.temperature() == 23.0
    with pytest.raises(InstrumentError) as ei:
        p.temperature()
    assert one_line(ei.value) == "serial port /dev/ttyUSB0 not found; is the environment probe plugged in?"


def test_missing_port():
    with pytest.raises(InstrumentError) as ei:
        EnvironmentProbe("/dev/ttyUSB_labid_absent", **FAST)
    assert one_line(ei.value) == ("serial port /dev/ttyUSB_labid_absent not found; "
                                  "is the environment probe plugged in?")


def test_loopback_url_is_not_an_instrument():
    p = EnvironmentProbe("loop://", **FAST)
    try:
        with pytest.raises(InstrumentError, match="echo of the command .* to \\*IDN\\? after 3 tries"):
            p.identify()
    finally:
        p.close()


def test_uses_serial_for_url():
    opened = []

    def factory(url, **kw):
        opened.append((url, kw))
        return serial.serial_for_url("loop://", **kw)
    p = EnvironmentProbe("/dev/ttyXYZ", baudrate=19200, timeout_s=0.15, serial_factory=factory)
    p.close()
    assert opened == [("/dev/ttyXYZ", {"baudrate": 19200, "timeout": 0.15, "write_timeout": 0.15})]


# ------------------------------------------------------------ hammer unit
def test_hammer_fire_counts_hits():
    h, port = expected_protocol(HammerUnit, [(b"*IDN?", b"LABID,HAMMER,HU0007,1.0\n"),
                                             (b"COUNT?", b"COUNT 0\n"), (b"ARM?", b"ARM 1\n"), (b"FIRE", b"OK\n"),
                                             (b"COUNT?", b"COUNT 1\n"), (b"ARM?", b"ARM 1\n"), (b"FIRE", b"OK\n")])
    assert h.identify() == Identity("LABID", "HAMMER", "HU0007", "1.0")
    assert h.fire() == 1 and h.fire() == 2 and port.finished()


def test_lost_ok_does_not_double_fire():
    """FIRE was heard (the counter moved) but its OK was lost: no second FIRE."""
    h, port = expected_protocol(HammerUnit, [(b"COUNT?", b"COUNT 4\n"), (b"ARM?", b"ARM 1\n"), (b"FIRE", b""),
                                             (b"COUNT?", b"COUNT 5\n")])
    assert h.fire() == 5 and port.finished()


def test_unheard_fire_is_resent():
    h, port = expected_protocol(HammerUnit, [(b"COUNT?", b"COUNT 0\n")]
                                + [(b"ARM?", b"ARM 1\n"), (b"FIRE", b""), (b"COUNT?", b"COUNT 0\n")] * 2
                                + [(b"ARM?", b"ARM 1\n"), (b"FIRE", b"OK\n")])
    assert h.fire() == 1 and port.finished()


def test_fire_never_heard_gives_clear_error():
    h, _ = expected_protocol(HammerUnit, [(b"COUNT?", b"COUNT 0\n")]
                             + [(b"ARM?", b"ARM 1\n"), (b"FIRE", b""), (b"COUNT?", b"COUNT 0\n")] * 3)
    with pytest.raises(InstrumentError) as ei:
        h.fire()
    assert one_line(ei.value).endswith("no reply to FIRE after 3 tries; no hit fired")


def test_fire_waits_for_recharge():
    h, port = expected_protocol(HammerUnit, [(b"COUNT?", b"COUNT 1\n"), (b"ARM?", b"ARM 0\n"), (b"ARM?", b"ARM 0\n"),
                                             (b"ARM?", b"ARM 1\n"), (b"FIRE", b"OK\n")])
    assert h.fire() == 2 and port.finished()       # waited for ARM 1 instead of getting ERR BUSY


def test_fire_gives_up_if_never_ready():
    h, _ = expected_protocol(HammerUnit, itertools.chain([(b"COUNT?", b"COUNT 1\n")],
                                                         itertools.repeat((b"ARM?", b"ARM 0\n"))))
    with pytest.raises(InstrumentError, match="not ready to fire after 0.1 s"):
        h.fire(ready_timeout_s=0.1)


def test_hammer_level():
    h, port = expected_protocol(HammerUnit, [(b"LEVEL 80", b"OK\n"), (b"LEVEL?", b"LEVEL 80\n"),
                                             (b"LEVEL 150", b"ERR RANGE 0..100\n")])
    h.set_level(80)
    assert h.level() == 80
    with pytest.raises(InstrumentRefused, match="LEVEL 150 refused: ERR RANGE 0..100"):
        h.set_level(150)
    assert port.finished()


# ------------------------------------------------------------ the real transport, once
def test_probe_over_a_pty():
    sim = SimEnvProbe(temperature_c=23.41, humidity_pct=45.2, serial="EP0042", firmware="1.3")
    with PtyServer(sim) as srv, EnvironmentProbe(srv.port, **FAST) as p:
        assert p.port.startswith("/dev/")
        assert p.identify() == Identity("LABID", "ENVPROBE", "EP0042", "1.3")
        assert (p.temperature(), p.humidity()) == (23.41, 45.2)
    assert sim.received == ["*IDN?", "TEMP?", "HUM?"]
