"""The acquisition workflow shared by ``labid acquire`` and the lab panel.

``AcquisitionSession(rig, specimen, store, backend)`` records N hammer hits on
the rig's 'hammer' device and M wave shots on its 'wave' device into a
``RunStore``. Each accepted shot is appended (and flushed) at once. A shot that
did not trigger (``NoTrigger``), overloaded a channel or was a double hit is
reported through ``progress`` and redone, at most ``rig.max_retries`` times.
``should_stop()`` is polled between shots: stopping keeps everything recorded.
The devices are ``mock_hw.rig.SimulatedDevice`` (backend 'mock') or
``drivers.nidaq.NiDaqDevice`` (backend 'nidaqmx'; it loads the ``nidaqmx``
package only when a device is configured, so a missing NI driver is one
clear line then); the workflow only uses the ``drivers.protocol.Device``
methods. ``LiveSession`` also hands every device read (accepted or not) to
``on_record`` (the panel's live traces).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from drivers.nidaq import NiDaqDevice
from drivers.protocol import AcquisitionError, NoTrigger, Record
from mock_hw.rig import SimulatedDevice

from ..base.errors import UserError
from ..inputs.calibration import calibrate, nidaq_teds, status as calibration_status
from ..inputs.rig import Rig, load_rig
from ..store import RunStore
from ..inputs.specimen import Specimen, load_specimen, specimen_text

BACKENDS = ("mock", "nidaqmx")
KINDS = ("hammer", "wave")

Progress = Callable[[dict], None]


def double_hit(force: np.ndarray, rate_hz: float, min_gap_s: float = 5e-4,
               fraction: float = 0.1) -> bool:
    """True if the force record holds two pulses above ``fraction`` of its peak,
    separated by more than ``min_gap_s`` below that level."""
    x = np.asarray(force, float)
    peak = x.max()
    if not peak > 0:
        return False
    above = np.flatnonzero(x > fraction * peak)
    if above.size < 2:
        return False
    return bool(np.any(np.diff(above) > min_gap_s * rate_hz))


def sample_dtype(spec) -> str:
    """Sample dtype of a device's shot tables: float32 for the (long, MHz) wave records of
    an ADC of up to 23 bits, float64 otherwise. A float32 value v differs from the float64
    one by at most |v| 2^-24 <= range 2^-24, less than half the ADC step range 2^(1 - bits)
    for bits <= 23: the code a sample came from is recovered exactly (``round(v / step)``)."""
    return "f4" if spec.role == "wave" and spec.adc_bits <= 23 else "f8"


def merge_acquisitions(records: list[Record], groups: tuple[tuple[str, ...], ...], spec) -> Record:
    """One shot from the records of separate acquisitions on a common trigger: each
    channel from the acquisition that records it, in the device's channel order; the
    meta of the first, plus per acquisition its channels and the device's own meta
    (shot index, simulated onset)."""
    data, over = {}, {}
    for rec, g in zip(records, groups):
        for name in g:
            data[name] = rec.data[name]
            over[name] = rec.overload.get(name, False)
    keep = ("shot_index", "sim_onset_s", "sim_force_peak_n")
    meta = dict(records[0].meta)
    if "shot_index" in records[-1].meta:          # the last device read (a resumed run continues after it)
        meta["shot_index"] = records[-1].meta["shot_index"]
    meta["acquisitions"] = [{"channels": list(g), "timestamp": r.timestamp,
                             **{k: r.meta[k] for k in keep if k in r.meta}} for r, g in zip(records, groups)]
    return Record(data=data, channels=tuple(spec.channels), timing=spec.timing, trigger=spec.trigger,
                  overload=over, timestamp=records[0].timestamp, backend=records[0].backend, meta=meta)


class AcquisitionSession:
    """One acquisition session on ``rig`` for ``specimen``, stored in ``store``.

    rig: a Rig or a rig path ('default' or None: the built-in simulated rig);
    specimen: a Specimen or a path/builtin name ('cfrp'); store: an open RunStore;
    backend: 'mock' or 'nidaqmx'; effects: mock_hw.rig.Effects for the mock;
    seed: the mock's random seed (shot k of a run is reproducible from it);
    device_factory: DeviceSpec -> Device, replaces the backend's devices (tests,
    other hardware).
    """

    def __init__(self, rig: Rig | str | None, specimen: Specimen | str, store: RunStore,
                 backend: str = "mock", effects=None, seed: int = 0,
                 device_factory: Callable[[Any], Any] | None = None):
        self.rig = rig if isinstance(rig, Rig) else load_rig(rig)
        self.specimen = specimen if isinstance(specimen, Specimen) else load_specimen(specimen)
        if backend not in BACKENDS:
            raise UserError(f"value {backend!r}: expected one of {list(BACKENDS)}", key="--backend")
        teds = nidaq_teds() if backend == "nidaqmx" and device_factory is None else None
        self.rig, self.calibration = calibrate(self.rig, teds)     # sheet and TEDS sensitivities
        self.store, self.backend, self.effects, self.seed = store, backend, effects, int(seed)
        self.device_factory = device_factory
        self.rig.check_specimen(self.specimen.length, self.specimen.width)
        self._devices: dict[str, Any] = {}

    # -- devices ------------------------------------------------------------
    def device(self, kind: str):
        """The configured device recording ``kind`` shots (created on first use)."""
        if kind in self._devices:
            return self._devices[kind]
        spec = self.rig.device(kind)
        if spec is None:
            raise UserError(f"no device with role {kind!r}; expected a [devices.NAME] table with "
                            f"role = {kind!r} to record {kind} shots", file=self.rig.source, key="devices")
        if self.device_factory is not None:
            dev = self.device_factory(spec)
        elif self.backend == "mock":
            dev = SimulatedDevice(self.rig, self.specimen, kind, self.effects, self.seed)
            last = [m.get("shot_index") for m in self.store.metas(kind)[-1:]]
            if last and isinstance(last[0], int):
                dev.shot_index = last[0] + 1          # resume: continue the random sequence
        else:
            daq = spec.daq_device or next((c.physical.split("/")[0] for c in spec.channels
                                           if "/" in c.physical), "Dev1")
        try:
            if self.backend == "nidaqmx" and self.device_factory is None:
                dev = NiDaqDevice(spec.name, daq)
            dev.configure(spec.channels, spec.timing, spec.trigger)
        except AcquisitionError as e:
            raise UserError(str(e), file=self.rig.source, key=f"devices.{spec.name}") from None
        except ValueError as e:
            raise UserError(f"rejected by the device: {e}", file=self.rig.source,
                            key=f"devices.{spec.name}") from None
        self._devices[kind] = dev
        return dev

    def close(self) -> None:
        for dev in self._devices.values():
            try:
                dev.close()
            except Exception:  # noqa: BLE001 - closing must not lose the summary
                pass
        self._devices.clear()

    # -- one shot --------------------------------------------------------------
    def _problem(self, rec: Record, kind: str) -> str | None:
        over = [n for n, v in rec.overload.items() if v]
        if over:
            return f"overload on {', '.join(over)}"
        if kind == "hammer":
            for c in rec.channels:
                if c.kind == "force" and double_hit(rec.scaled(c.name), rec.timing.rate_hz):
                    return f"double hit on {c.name}"
        return None

    def _read(self, dev, spec) -> Record:
        """One record of the device; a device whose channels are split into separate
        acquisitions (rig ``acquisition`` keys) records each on the common trigger and
        the records are merged (``merge_acquisitions``)."""
        groups = spec.acquisitions
        if len(groups) <= 1:
            dev.arm()
            return dev.read(spec.trigger_timeout_s)
        recs = []
        try:
            for g in groups:
                chans = tuple(c for c in spec.channels if c.name in g or c.name == spec.trigger.channel)
                dev.configure(chans, spec.timing, spec.trigger)
                dev.arm()
                recs.append(dev.read(spec.trigger_timeout_s))
        finally:
            dev.configure(spec.channels, spec.timing, spec.trigger)
        return merge_acquisitions(recs, groups, spec)

    def shoot(self, kind: str, progress: Progress | None = None, index: int = 0,
              total: int = 0) -> str | None:
        """Record one accepted shot of ``kind``; returns its name, None after giving up."""
        dev, spec = self.device(kind), self.rig.device(kind)
        report = progress or (lambda ev: None)
        for attempt in range(self.rig.max_retries + 1):
            try:
                rec = self._read(dev, spec)
            except NoTrigger as e:
                report(dict(kind=kind, index=index, total=total, status="no trigger",
                            attempt=attempt, message=str(e)))
                continue
            except AcquisitionError as e:
                raise UserError(str(e), file=self.rig.source, key=f"devices.{spec.name}") from None
            problem = self._problem(rec, kind)
            if problem:
                report(dict(kind=kind, index=index, total=total, status="rejected",
                            attempt=attempt, message=f"{problem}; redoing the shot"))
                continue
            if self.calibration is not None:
                rec.meta.update(self.calibration.meta(c.name for c in rec.channels))
            name = self.store.append_shot(rec, kind)
            report(dict(kind=kind, index=index, total=total, status="recorded", attempt=attempt,
                        shot=name, message=f"recorded {name}"))
            return name
        report(dict(kind=kind, index=index, total=total, status="gave up", attempt=attempt,
                    message=f"no acceptable {kind} shot after {self.rig.max_retries + 1} attempts"))
        return None

    # -- the session ----------------------------------------------------------------
    def run(self, n_hits: int | None = None, n_waves: int | None = None,
            progress: Progress | None = None, should_stop: Callable[[], bool] | None = None,
            total: bool = False) -> dict:
        """Record ``n_hits`` hammer hits then ``n_waves`` wave shots (rig defaults if None).

        total=True: the counts include the shots already in the store (resume a
        session to its planned size). Returns the summary (the ``--json`` result).
        """
        stop = should_stop or (lambda: False)
        # rig defaults apply only to the kinds the rig has a device for
        want = {"hammer": (self.rig.hits if self.rig.device("hammer") else 0) if n_hits is None
                else int(n_hits),
                "wave": (self.rig.waves if self.rig.device("wave") else 0) if n_waves is None
                else int(n_waves)}
        for k, n in want.items():
            if n < 0:
                raise UserError(f"value {n}: expected a non-negative count", key=f"--{k}s")
        before = {k: self.store.n_shots(k) for k in KINDS}
        if total:
            want = {k: max(0, want[k] - before[k]) for k in KINDS}
        self.store.write_config(specimen_text(self.specimen), self.rig.text)
        if self.calibration is not None and self.calibration.text:
            self.store.write_config_text("calibration_csv", self.calibration.text)
        events: list[dict] = []

        def report(ev: dict) -> None:
            events.append(ev)
            if progress:
                progress(ev)

        recorded: dict[str, list[str]] = {k: [] for k in KINDS}
        gave_up: dict[str, int] = {k: 0 for k in KINDS}
        interrupted = False
        try:
            for kind in KINDS:
                if want[kind] == 0:
                    continue
                spec = self.rig.device(kind)
                self.device(kind)
                self.store.declare(kind, spec.channels, spec.timing, spec.trigger, sample_dtype(spec))
                for i in range(want[kind]):
                    if stop():
                        interrupted = True
                        break
                    name = self.shoot(kind, report, i + 1, want[kind])
                    if name is None:
                        gave_up[kind] += 1
                        break       # the rig needs attention: do not hammer on
                    recorded[kind].append(name)
                if interrupted:
                    break
        finally:
            self.close()
        return {
            "out": str(self.store.path), "backend": self.backend, "seed": self.seed,
            "rig": self.rig.name, "rig_file": self.rig.source, "specimen": self.specimen.name,
            "effects": self.effects.active() if self.effects is not None else {},
            "requested": want,
            "recorded": {k: len(v) for k, v in recorded.items()},
            "shots": recorded["hammer"] + recorded["wave"],
            "in_file": {k: self.store.n_shots(k) for k in KINDS},
            "redone": sum(1 for e in events if e["status"] in ("no trigger", "rejected")),
            "problems": [f"{e['kind']} {e['index']}: {e['message']}" for e in events
                         if e["status"] != "recorded"],
            "gave_up": gave_up,
            "interrupted": interrupted,
            "complete": not interrupted and all(len(recorded[k]) == want[k] for k in KINDS),
            "calibration": calibration_status(self.calibration),
        }


class TappedDevice:
    """A device whose reads are also handed to ``on_record(kind, record)`` (delegates the protocol)."""

    def __init__(self, dev, kind: str, on_record):
        self._dev, self._kind, self._on_record = dev, kind, on_record
        self.name = getattr(dev, "name", kind)

    def configure(self, *a, **kw):
        return self._dev.configure(*a, **kw)

    def arm(self):
        return self._dev.arm()

    def read(self, timeout_s: float = 10.0):
        rec = self._dev.read(timeout_s)
        self._on_record(self._kind, rec)
        return rec

    def close(self):
        return self._dev.close()


class LiveSession(AcquisitionSession):
    """AcquisitionSession whose device reads are reported to ``on_record(kind, record)``."""

    def __init__(self, *a, on_record=None, **kw):
        super().__init__(*a, **kw)
        self._on_record = on_record or (lambda kind, rec: None)

    def device(self, kind: str):
        return TappedDevice(super().device(kind), kind, self._on_record)
