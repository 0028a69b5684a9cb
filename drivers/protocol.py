"""The small protocols every device speaks, real or simulated (ophyd-style: one interface,
checked by one conformance test, ``tests/unit/drivers/test_protocol_conformance.py``).

Acquisition devices (``Device``: ``drivers.nidaq.NiDaqDevice``, ``mock_hw.rig.SimulatedDevice``):
configure(channels, timing, trigger) -> arm() -> read(timeout_s) -> Record ... -> close()

Serial instruments (``Instrument``: ``drivers.serial_instruments.EnvironmentProbe``,
``HammerUnit``; simulated on the wire by ``mock_hw.serial_sim``): identify() -> close(),
a context manager; their commands are the "LABID serial v1" line protocol.

Units: rates in Hz, sensitivities in V per physical unit (V/(m/s^2) for an
accelerometer, V/N for a force channel, V/V for a plain voltage channel),
ranges in V (symmetric, +/-), positions in m on the plate.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

ChannelKind = Literal["accelerometer", "force", "voltage"]
Coupling = Literal["IEPE", "AC", "DC"]

#: physical unit of each channel kind once divided by its sensitivity
UNITS: dict[str, str] = {"accelerometer": "m/s^2", "force": "N", "voltage": "V"}


@dataclass(frozen=True)
class ChannelConfig:
    """One analog input channel.

    name: unique label (e.g. 'acc1'); physical: device channel ('PXI1Slot2/ai0').
    sensitivity: V per physical unit; range_v: +/- input range in V.
    x, y: position on the plate in m (None if not on the plate, e.g. the hammer).
    mass_kg: sensor mass (for the model), 0 if unknown.
    """

    name: str
    kind: ChannelKind = "voltage"
    physical: str = ""
    sensitivity: float = 1.0
    range_v: float = 5.0
    coupling: Coupling = "DC"
    x: float | None = None
    y: float | None = None
    mass_kg: float = 0.0
    length_m: float = 0.0
    excitation_current_a: float = 0.004  # IEPE only

    @property
    def unit(self) -> str:
        return UNITS[self.kind]


@dataclass(frozen=True)
class Timing:
    """Finite acquisition: sample rate (Hz), samples per record, pre-trigger samples."""

    rate_hz: float
    samples: int
    pretrigger: int = 0


@dataclass(frozen=True)
class Trigger:
    """Analog edge reference trigger on one channel; level in V at the input."""

    channel: str
    level_v: float = 0.5
    slope: Literal["rising", "falling"] = "rising"


@dataclass
class Record:
    """One triggered record, with every setting needed to interpret it.

    data: channel name -> samples in volts at the ADC input (float64).
    The physical value is ``data[name] / channel.sensitivity`` (see ``scaled``).
    overload: channel name -> True if the channel clipped/overloaded.
    t0_index: index of the trigger sample (== timing.pretrigger).
    """

    data: dict[str, np.ndarray]
    channels: tuple[ChannelConfig, ...]
    timing: Timing
    trigger: Trigger | None
    overload: dict[str, bool]
    timestamp: float = field(default_factory=time.time)
    backend: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def t0_index(self) -> int:
        return self.timing.pretrigger

    def channel(self, name: str) -> ChannelConfig:
        for c in self.channels:
            if c.name == name:
                return c
        raise KeyError(name)

    def scaled(self, name: str) -> np.ndarray:
        """Samples of ``name`` in physical units (volts / sensitivity)."""
        return self.data[name] / self.channel(name).sensitivity

    def time(self) -> np.ndarray:
        """Time axis in s, zero at the trigger sample."""
        n = self.timing.samples
        return (np.arange(n) - self.timing.pretrigger) / self.timing.rate_hz


class AcquisitionError(RuntimeError):
    """A device-side failure, already phrased as one line for the user."""


class NoTrigger(AcquisitionError):
    """The trigger condition was not met before the timeout."""


@runtime_checkable
class Device(Protocol):
    """What the workflow needs from an acquisition device."""

    name: str

    def configure(self, channels: tuple[ChannelConfig, ...], timing: Timing,
                  trigger: Trigger | None) -> None: ...

    def arm(self) -> None: ...

    def read(self, timeout_s: float = 10.0) -> Record: ...

    def close(self) -> None: ...


@runtime_checkable
class Instrument(Protocol):
    """What the workflow needs from a serial instrument (its queries are its own)."""

    port: str

    def identify(self) -> Any: ...

    def close(self) -> None: ...

    def __enter__(self) -> Any: ...

    def __exit__(self, *exc: Any) -> None: ...
