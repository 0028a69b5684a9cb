"""Simulated serial instruments speaking the "LABID serial v1" line protocol.

The protocol is documented in :mod:`drivers.serial_instruments`. Two
instruments, transport-independent (``handle(line) -> reply``):

* :class:`SimEnvProbe`: ``TEMP?``/``HUM?`` answer the attributes
  ``temperature_c`` and ``humidity_pct`` (set them at any time).
* :class:`SimHammer`: counts ``FIRE`` commands in ``hits``; after a hit it is
  not ready (``ARM 0``, ``FIRE`` -> ``ERR BUSY``) for ``recharge_s`` seconds;
  ``on_fire(level_pct)`` is called for every hit (a simulated rig can start
  its impact response from it).

Transports: :class:`PtyServer` serves an instrument on a pseudo-terminal
(``os.openpty()``, raw mode, a thread serving the master side; ``.port`` is
the slave path to open with pyserial), :class:`TcpServer` on
``socket://127.0.0.1:<port>``.

Fault injection, ``inst.inject(fault, times=1, command=None)`` (``command``:
only lines starting with it; faults are used first-in first-out):

* ``"noreply"``: the command is not heard (not executed, no reply);
* ``"lost_reply"``: the command is executed, its reply is lost;
* ``"garbled"``: executed, the reply has corrupted (non-ASCII) bytes;
* ``"partial"``: executed, only the first half of the reply, no ``\\n``;
* ``"late"``: executed, the reply is sent ``delay_s`` (default ``late_s``) s later.
"""
from __future__ import annotations

import os
import select
import socket
import threading
import time
import tty
from collections import deque
from typing import Callable

FAULTS = ("noreply", "lost_reply", "garbled", "partial", "late")


class SimInstrument:
    """Protocol core shared by the simulated instruments."""

    model = ""

    def __init__(self, serial: str = "SIM0001", firmware: str = "1.0", late_s: float = 0.2):
        self.serial, self.firmware, self.late_s = serial, firmware, late_s
        self.received: list[str] = []          # every line heard on the wire
        self._faults: deque[tuple[str, str | None, float]] = deque()
        self._lock = threading.Lock()

    def inject(self, fault: str, times: int = 1, command: str | None = None,
               delay_s: float | None = None) -> None:
        """Queue ``times`` faults of one kind (see the module docstring).

        delay_s: delay of a ``"late"`` reply (default ``late_s``).
        """
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; expected one of {', '.join(FAULTS)}")
        delay = self.late_s if delay_s is None else delay_s
        with self._lock:
            self._faults.extend([(fault, command, delay)] * times)

    def pending_faults(self) -> int:
        with self._lock:
            return len(self._faults)

    def _take_fault(self, line: str) -> tuple[str | None, float]:
        with self._lock:
            for i, (fault, cmd, delay) in enumerate(self._faults):
                if cmd is None or line.startswith(cmd):
                    del self._faults[i]
                    return fault, delay
        return None, 0.0

    def handle(self, line: str) -> tuple[bytes, float]:
        """One received line -> (bytes to send, delay in s). Empty bytes: silence."""
        line = line.rstrip("\r")
        with self._lock:
            self.received.append(line)
        fault, delay = self._take_fault(line)
        if fault == "noreply":
            return b"", 0.0
        reply = (self.answer(line) + "\n").encode("ascii")
        if fault == "lost_reply":
            return b"", 0.0
        if fault == "garbled":
            return bytes(b ^ 0x80 if i % 2 else b for i, b in enumerate(reply[:-1])) + b"\n", 0.0
        if fault == "partial":
            return reply[: max(1, (len(reply) - 1) // 2)], 0.0
        if fault == "late":
            return reply, delay
        return reply, 0.0

    def answer(self, line: str) -> str:
        if line == "*IDN?":
            return f"LABID,{self.model},{self.serial},{self.firmware}"
        return self.answer_specific(line)

    def answer_specific(self, line: str) -> str:
        return f"ERR UNKNOWN {line}"


class SimEnvProbe(SimInstrument):
    """Environment probe: temperature (deg C) and relative humidity (%)."""

    model = "ENVPROBE"

    def __init__(self, temperature_c: float = 23.0, humidity_pct: float = 45.0, **kw):
        super().__init__(**{"serial": "EP0001", **kw})
        self.temperature_c, self.humidity_pct = temperature_c, humidity_pct

    def answer_specific(self, line: str) -> str:
        if line == "TEMP?":
            return f"TEMP {self.temperature_c:.2f}"
        if line == "HUM?":
            return f"HUM {self.humidity_pct:.2f}"
        return super().answer_specific(line)


class SimHammer(SimInstrument):
    """Automatic impulse hammer: FIRE counts a hit, then recharges."""

    model = "HAMMER"

    def __init__(self, recharge_s: float = 0.0, level_pct: int = 50,
                 on_fire: Callable[[int], None] | None = None,
                 clock: Callable[[], float] | None = None, **kw):
        super().__init__(**{"serial": "HU0001", **kw})
        self.recharge_s, self.level_pct, self.on_fire = recharge_s, level_pct, on_fire
        self.hits = 0
        self._clock = clock or time.monotonic
        self._ready_at = -float("inf")

    def ready(self) -> bool:
        return self._clock() >= self._ready_at

    def answer_specific(self, line: str) -> str:
        if line == "ARM?":
            return f"ARM {int(self.ready())}"
        if line == "COUNT?":
            return f"COUNT {self.hits}"
        if line == "LEVEL?":
            return f"LEVEL {self.level_pct}"
        if line == "FIRE":
            if not self.ready():
                return "ERR BUSY"
            self.hits += 1
            self._ready_at = self._clock() + self.recharge_s
            if self.on_fire is not None:
                self.on_fire(self.level_pct)
            return "OK"
        if line.startswith("LEVEL "):
            arg = line[6:]
            if not arg.isdigit() or not 0 <= int(arg) <= 100:
                return "ERR RANGE 0..100"
            self.level_pct = int(arg)
            return "OK"
        return super().answer_specific(line)


class _Server:
    """Line splitting and (possibly delayed) replies over a byte stream."""

    def __init__(self, instrument: SimInstrument):
        self.instrument = instrument
        self._stop = threading.Event()
        self._buf = b""
        self._timers: list[threading.Timer] = []

    def _feed(self, data: bytes, send: Callable[[bytes], None]) -> None:
        self._buf += data
        while b"\n" in self._buf:
            raw, self._buf = self._buf.split(b"\n", 1)
            line = raw.decode("ascii", errors="replace")
            reply, delay = self.instrument.handle(line)
            if not reply:
                continue
            if delay > 0:
                t = threading.Timer(delay, self._safe_send, (send, reply))
                t.daemon = True
                self._timers.append(t)
                t.start()
            else:
                self._safe_send(send, reply)

    @staticmethod
    def _safe_send(send: Callable[[bytes], None], reply: bytes) -> None:
        try:
            send(reply)
        except OSError:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop serving and release the port (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._stop_timers()
        self._thread.join(timeout=1.0)
        self._release()

    def _release(self) -> None:
        raise NotImplementedError

    def _stop_timers(self) -> None:
        for t in self._timers:
            t.cancel()


class PtyServer(_Server):
    """Serve ``instrument`` on a new pseudo-terminal; ``port`` is its slave path."""

    def __init__(self, instrument: SimInstrument):
        super().__init__(instrument)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)                 # no echo, no line discipline
        self.port = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._run, name=f"pty-{self.port}", daemon=True)
        self._thread.start()

    def _send(self, data: bytes) -> None:
        os.write(self._master, data)

    def _run(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.02)
            if not ready:
                continue
            try:
                data = os.read(self._master, 1024)
            except OSError:
                break
            if data:
                self._feed(data, self._send)

    def _release(self) -> None:
        """Remove the pty (the port disappears, like an unplugged USB)."""
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass


class TcpServer(_Server):
    """Serve ``instrument`` on 127.0.0.1; ``port`` is a ``socket://`` URL for pyserial."""

    def __init__(self, instrument: SimInstrument):
        super().__init__(instrument)
        self._sock = socket.create_server(("127.0.0.1", 0))
        self._sock.settimeout(0.05)
        self.port = f"socket://127.0.0.1:{self._sock.getsockname()[1]}"
        self._thread = threading.Thread(target=self._run, name=self.port, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except (socket.timeout, OSError):
                continue
            with conn:
                conn.settimeout(0.02)
                self._buf = b""
                while not self._stop.is_set():
                    try:
                        data = conn.recv(1024)
                    except socket.timeout:
                        continue
                    except OSError:
                        break
                    if not data:
                        break
                    self._feed(data, conn.sendall)

    def _release(self) -> None:
        self._sock.close()
