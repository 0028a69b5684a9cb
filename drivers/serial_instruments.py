"""Serial instruments of the rig (pyserial): environment probe and hammer unit.

Line protocol "LABID serial v1"
-------------------------------
Transport: any ``serial.serial_for_url`` URL: a device path (``/dev/ttyUSB0``,
a pty such as ``/dev/pts/5``, ``COM3``), ``socket://host:port`` or ``loop://``.
Real ports run at 9600 baud, 8N1, no flow control.

* ASCII only. The host sends one command per line, terminated by ``\\n``
  (a ``\\r`` before it is ignored). The instrument answers EVERY command with
  exactly one ``\\n``-terminated line, within 100 ms (except as noted).
* Replies are ``OK`` (action done), ``ERR <reason>`` (refused; never retried),
  or, for a query ``KEY?``, ``KEY <value>``: the reply repeats the keyword so a
  late reply to an earlier query can be recognised and discarded.

======================  ==============================  ===============================
command                 reply                           meaning
======================  ==============================  ===============================
``*IDN?``               ``LABID,<MODEL>,<SN>,<FW>``     identity; MODEL is ``ENVPROBE``
                                                        or ``HAMMER``
``TEMP?``  (ENVPROBE)   ``TEMP 23.41``                  air temperature, deg C
``HUM?``   (ENVPROBE)   ``HUM 45.20``                   relative humidity, %
``ARM?``   (HAMMER)     ``ARM 1`` / ``ARM 0``           1: charged, ready to fire;
                                                        0: recharging after a hit
``FIRE``   (HAMMER)     ``OK`` / ``ERR BUSY``           fire one automatic hammer hit
                                                        (``ERR BUSY`` while ``ARM 0``)
``COUNT?`` (HAMMER)     ``COUNT 17``                    hits fired since power-up
``LEVEL <p>`` (HAMMER)  ``OK`` / ``ERR RANGE 0..100``   impact strength, % of maximum
``LEVEL?`` (HAMMER)     ``LEVEL 60``                    current impact strength, %
anything else           ``ERR UNKNOWN <command>``
======================  ==============================  ===============================

Host side (this module): before each command the input buffer is flushed;
a reply is accepted only if it is complete (``\\n``-terminated), printable
ASCII and of the expected form (queries: keyword and a plausible value);
lines of another query's form are stale and skipped. No reply, a partial
reply, a garbled reply or a port error (the port is reopened) cost one try;
after ``tries`` tries (default 3) :class:`InstrumentError` says what happened
in one line, e.g. ``environment probe on /dev/ttyUSB0: no reply to TEMP?
after 3 tries``. ``FIRE`` is not blindly repeated: after a failed exchange the
hit counter is read to learn whether the hit happened, so a lost ``OK`` never
gives a double hit.
"""
from __future__ import annotations

import errno
import re
import time
from dataclasses import dataclass
from typing import Any, Callable

import serial

from drivers.protocol import AcquisitionError

MAX_LINE = 128  # bytes; longer replies are garbage

try:  # POSIX ports raise termios.error (not an OSError) when the tty vanishes
    import termios
    _PORT_ERRORS: tuple = (serial.SerialException, OSError, termios.error)
except ImportError:  # pragma: no cover - Windows
    _PORT_ERRORS = (serial.SerialException, OSError)


class InstrumentError(AcquisitionError):
    """A serial instrument failed; the message is one line naming port and cause.

    ``reason``: the last failed exchange ('no reply', 'partial reply ...', ...).
    """

    def __init__(self, message: str, reason: str = ""):
        super().__init__(message)
        self.reason = reason


class InstrumentRefused(InstrumentError):
    """The instrument answered ``ERR ...`` (a definite answer: not retried)."""


class _BadReply(Exception):
    """One failed exchange (retryable); ``kind`` is 'no reply', 'partial reply', ..."""

    def __init__(self, kind: str, raw: bytes = b"", message: str = ""):
        super().__init__(kind)
        self.kind, self.raw, self.message = kind, raw, message

    def describe(self) -> str:
        if self.raw:
            return f"{self.kind} {self.raw[:40]!r}"
        return self.kind


@dataclass(frozen=True)
class Identity:
    """Answer to ``*IDN?``."""

    maker: str
    model: str
    serial: str
    firmware: str


_IDN = re.compile(r"([A-Z0-9_]+),([A-Z0-9_]+),([^,\s]+),([^,\s]+)")
_NUMBER = r"[-+]?\d+(?:\.\d+)?"
_QUERY_FORM = re.compile(r"[A-Z]+ \S+")  # any 'KEY value' line (possibly stale)


class SerialInstrument:
    """Base class: open the port, exchange lines with retries, identify.

    port: a ``serial_for_url`` URL. timeout_s: per-reply timeout in s; tries:
    attempts per command (and per port opening); retry_delay_s: pause between
    attempts. ``serial_factory`` replaces ``serial.serial_for_url`` (tests).
    """

    model = ""
    label = "instrument"

    def __init__(self, port: str, *, baudrate: int = 9600, timeout_s: float = 0.5,
                 tries: int = 3, retry_delay_s: float = 0.05,
                 serial_factory: Callable[..., Any] = serial.serial_for_url):
        if tries < 1:
            raise ValueError(f"tries must be >= 1, got {tries}")
        self.port, self.baudrate = port, baudrate
        self.timeout_s, self.tries, self.retry_delay_s = timeout_s, tries, retry_delay_s
        self._factory = serial_factory
        self._ser: Any = None
        self._open()

    # ------------------------------------------------------------- port
    def _where(self) -> str:
        return f"{self.label} on {self.port}"

    def _connect(self) -> None:
        """Open the port once; raise _BadReply('open', message=...) on failure."""
        try:
            self._ser = self._factory(self.port, baudrate=self.baudrate,
                                      timeout=self.timeout_s, write_timeout=self.timeout_s)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise _BadReply("open", message=self._open_message(exc)) from exc

    def _open(self) -> None:
        for attempt in range(self.tries):
            try:
                self._connect()
                return
            except _BadReply as bad:
                if attempt + 1 == self.tries:
                    raise InstrumentError(bad.message, "open") from bad.__cause__
                time.sleep(self.retry_delay_s)

    def _open_message(self, exc: Exception) -> str:
        code = getattr(exc, "errno", None)
        text = str(exc)
        if code == errno.ENOENT or "No such file" in text:
            return f"serial port {self.port} not found; is the {self.label} plugged in?"
        if code == errno.EACCES or "Permission denied" in text:
            return (f"permission denied on serial port {self.port}; "
                    "add your user to the 'dialout' group")
        if code == errno.EBUSY or "busy" in text.lower():
            return f"serial port {self.port} is busy (open in another program?)"
        return f"cannot open serial port {self.port} for the {self.label}: {_first_line(exc)}"

    def _close_port(self) -> None:
        ser, self._ser = self._ser, None
        if ser is not None:
            try:
                ser.close()
            except Exception:  # noqa: BLE001 - the port may already be gone
                pass

    def close(self) -> None:
        self._close_port()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # --------------------------------------------------------- exchange
    def _exchange_once(self, command: str, accept: Callable[[str], bool]) -> str:
        """Send ``command`` once and return its reply line, or raise _BadReply."""
        if self._ser is None:
            self._connect()     # reopen after a port error
        ser = self._ser
        key = command.split()[0].rstrip("?")
        try:
            ser.reset_input_buffer()
            ser.write(command.encode("ascii") + b"\n")
            ser.flush()
            deadline = time.monotonic() + self.timeout_s
            while True:
                raw = ser.read_until(b"\n", MAX_LINE)
                if not raw:
                    raise _BadReply("no reply")
                if not raw.endswith(b"\n"):
                    raise _BadReply("partial reply" if len(raw) < MAX_LINE else "garbled reply", raw)
                try:
                    line = raw.decode("ascii").rstrip("\r\n")
                except UnicodeDecodeError:
                    raise _BadReply("garbled reply", raw) from None
                if not line.isprintable():
                    raise _BadReply("garbled reply", raw)
                if line == command:
                    raise _BadReply("echo of the command (looped-back port, not an instrument?)")
                if line.startswith("ERR") or accept(line):
                    return line
                if (_QUERY_FORM.fullmatch(line) and line.split()[0] != key
                        and time.monotonic() < deadline):
                    continue  # a late reply to an earlier, different query: skip it
                raise _BadReply("garbled reply", raw)
        except _PORT_ERRORS as exc:
            self._close_port()  # reopened on the next try
            raise _BadReply(f"port error ({_first_line(exc)})") from exc

    def command(self, command: str, accept: Callable[[str], bool] | str,
                tries: int | None = None) -> str:
        """Send ``command`` with up to ``tries`` tries; return the accepted reply line.

        accept: predicate on the reply line, or a regular expression that must
        match it fully. ``ERR ...`` replies raise InstrumentRefused at once.
        """
        if isinstance(accept, str):
            pattern = re.compile(accept)
            accept = lambda line: pattern.fullmatch(line) is not None  # noqa: E731
        n = self.tries if tries is None else tries
        last = _BadReply("no reply")
        for attempt in range(n):
            try:
                line = self._exchange_once(command, accept)
            except _BadReply as bad:
                last = bad
                if attempt + 1 < n:
                    time.sleep(self.retry_delay_s)
                continue
            if line.startswith("ERR"):
                raise InstrumentRefused(f"{self._where()}: {command} refused: {line}", line)
            return line
        if last.kind == "open":
            raise InstrumentError(last.message, "open")
        raise InstrumentError(f"{self._where()}: {last.describe()} to {command} after "
                              f"{n} {'try' if n == 1 else 'tries'}", last.describe())

    def query_number(self, key: str, lo: float, hi: float) -> float:
        """``KEY?`` -> float value of a ``KEY <value>`` reply within [lo, hi]."""
        pat = re.compile(rf"{key} ({_NUMBER})")

        def ok(line: str) -> bool:
            m = pat.fullmatch(line)
            return bool(m) and lo <= float(m.group(1)) <= hi
        return float(pat.fullmatch(self.command(f"{key}?", ok)).group(1))

    def identify(self) -> Identity:
        """``*IDN?``; raises InstrumentError if the port holds another model."""
        line = self.command("*IDN?", lambda s: _IDN.fullmatch(s) is not None)
        ident = Identity(*_IDN.fullmatch(line).groups())
        if self.model and (ident.maker, ident.model) != ("LABID", self.model):
            raise InstrumentError(f"{self._where()}: expected a LABID {self.model}, "
                                  f"found {line!r}; check which port is which")
        return ident


class EnvironmentProbe(SerialInstrument):
    """Temperature/humidity probe (model ``ENVPROBE``)."""

    model = "ENVPROBE"
    label = "environment probe"

    def temperature(self) -> float:
        """Air temperature in deg C (replies outside -40..125 count as garbled)."""
        return self.query_number("TEMP", -40.0, 125.0)

    def humidity(self) -> float:
        """Relative humidity in % (replies outside 0..100 count as garbled)."""
        return self.query_number("HUM", 0.0, 100.0)


class HammerUnit(SerialInstrument):
    """Automatic impulse hammer / trigger unit (model ``HAMMER``)."""

    model = "HAMMER"
    label = "hammer unit"

    def ready(self) -> bool:
        """True if charged and ready to fire (``ARM?``)."""
        return self.command("ARM?", r"ARM [01]") == "ARM 1"

    def count(self) -> int:
        """Hits fired since power-up (``COUNT?``)."""
        return int(self.command("COUNT?", r"COUNT \d+").split()[1])

    def level(self) -> int:
        """Impact strength in % of maximum (``LEVEL?``)."""
        return int(self.command("LEVEL?", r"LEVEL \d+").split()[1])

    def set_level(self, percent: int) -> None:
        """Set the impact strength, 0..100 % (the unit refuses other values)."""
        self.command(f"LEVEL {int(percent)}", r"OK")

    def wait_ready(self, timeout_s: float = 2.0, poll_s: float = 0.02) -> None:
        deadline = time.monotonic() + timeout_s
        while not self.ready():
            if time.monotonic() > deadline:
                raise InstrumentError(f"{self._where()}: not ready to fire after {timeout_s:g} s "
                                      "(solenoid not recharging?)")
            time.sleep(poll_s)

    def fire(self, ready_timeout_s: float = 2.0) -> int:
        """Fire exactly one hit; return the unit's hit count after it.

        Waits until the unit is charged, sends ``FIRE`` once per try, and after
        a failed exchange reads ``COUNT?`` to learn whether the hit happened,
        so one call never gives two hits.
        """
        before = self.count()
        reason = "no reply"
        for attempt in range(self.tries):
            self.wait_ready(ready_timeout_s)
            try:
                self.command("FIRE", r"OK", tries=1)
                return before + 1
            except InstrumentRefused as exc:
                if exc.reason != "ERR BUSY":
                    raise
                reason = "busy"
            except InstrumentError as exc:
                reason = exc.reason
            now = self.count()
            if now == before + 1:
                return now          # it fired; only the OK was lost
            if now != before:
                raise InstrumentError(f"{self._where()}: hit counter went from {before} to {now} "
                                      "during one FIRE; is another program driving the unit?")
            if attempt + 1 < self.tries:
                time.sleep(self.retry_delay_s)
        raise InstrumentError(f"{self._where()}: {reason} to FIRE after {self.tries} tries; "
                              "no hit fired", reason)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
