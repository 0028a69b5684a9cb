"""Acquisition tab: live traces and spectra, trigger settings, overload lights, progress, abort.

The work is ``labid.services.acquire`` (the same session as ``labid acquire``)
in a background job; every accepted shot is appended and flushed to the run
file by the session itself. The view only receives each device read
(``on_record``) to show each record as it arrives (accepted or not).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import (QComboBox, QDoubleSpinBox, QFileDialog, QGridLayout,
                               QHBoxLayout, QLabel, QLineEdit, QListWidget, QProgressBar,
                               QPushButton, QSpinBox, QSplitter, QVBoxLayout, QWidget)

from .. import services
from ..base.errors import UserError
from .common import empty_note
from .rigtext import set_device_values

COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"]
MAX_POINTS = 4000


def display_record(kind: str, rec) -> dict:
    """Decimated time traces (physical units) and amplitude spectra (dB) of a record."""
    t = rec.time()
    step = max(1, len(t) // MAX_POINTS)
    out = {"kind": kind, "t": t[::step], "traces": {}, "spectra": {}, "units": {},
           "overload": dict(rec.overload)}
    n = rec.timing.samples
    f = np.fft.rfftfreq(n, 1.0 / rec.timing.rate_hz)
    fstep = max(1, len(f) // MAX_POINTS)
    out["f"] = f[::fstep]
    for c in rec.channels:
        x = rec.scaled(c.name)
        out["traces"][c.name] = x[::step]
        out["units"][c.name] = c.unit
        spec = np.abs(np.fft.rfft(x)) / n
        out["spectra"][c.name] = 20 * np.log10(np.maximum(spec, 1e-300))[::fstep]
    return out


class Light(QLabel):
    """A round indicator: grey (no data), green (ok), red (overload)."""

    def __init__(self, name: str):
        super().__init__(name)
        self.channel = name
        self.state = None
        self.set(None)

    def set(self, overloaded: bool | None) -> None:
        self.state = overloaded
        col = "#bbbbbb" if overloaded is None else ("#e02020" if overloaded else "#20b020")
        self.setTextFormat(Qt.RichText)
        self.setText(f'<span style="color:{col}; font-size:14pt;">●</span> {self.channel}')
        self.setToolTip("no record yet" if overloaded is None else
                        ("OVERLOAD on the last record" if overloaded else "last record within range"))


class AcquisitionView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.job = None
        # run file
        self.run_edit = QLineEdit()
        self.run_edit.setPlaceholderText("run file (RUN.h5)")
        self.run_btn = QPushButton("New/choose…")
        # plan
        self.hits_spin = QSpinBox()
        self.hits_spin.setRange(0, 1_000_000)
        self.hits_spin.setValue(5)
        self.waves_spin = QSpinBox()
        self.waves_spin.setRange(0, 1_000_000)
        self.waves_spin.setValue(3)
        # trigger
        self.device_combo = QComboBox()
        self.level_spin = QDoubleSpinBox()
        self.level_spin.setDecimals(4)
        self.level_spin.setRange(-100.0, 100.0)
        self.level_spin.setSingleStep(0.005)
        self.level_spin.setSuffix(" V")
        self.pre_spin = QSpinBox()
        self.pre_spin.setRange(0, 10_000_000)
        self.pre_spin.setSuffix(" samples")
        self.apply_btn = QPushButton("Apply to rig")
        self.start_btn = QPushButton("Start")
        self.abort_btn = QPushButton("Abort")
        self.abort_btn.setEnabled(False)
        self.progress = QProgressBar()
        self.counter = QLabel("hits 0/0 · waves 0/0")
        self.counter.setStyleSheet("font-weight: bold;")
        self.lights_box = QHBoxLayout()
        self.lights: dict[str, Light] = {}
        self.log = QListWidget()
        self.log.setMaximumHeight(120)

        ctl = QGridLayout()
        ctl.addWidget(QLabel("run file"), 0, 0)
        ctl.addWidget(self.run_edit, 0, 1, 1, 5)
        ctl.addWidget(self.run_btn, 0, 6)
        ctl.addWidget(QLabel("hammer hits"), 1, 0)
        ctl.addWidget(self.hits_spin, 1, 1)
        ctl.addWidget(QLabel("wave shots"), 1, 2)
        ctl.addWidget(self.waves_spin, 1, 3)
        ctl.addWidget(self.start_btn, 1, 5)
        ctl.addWidget(self.abort_btn, 1, 6)
        ctl.addWidget(QLabel("trigger of"), 2, 0)
        ctl.addWidget(self.device_combo, 2, 1)
        ctl.addWidget(QLabel("level"), 2, 2)
        ctl.addWidget(self.level_spin, 2, 3)
        ctl.addWidget(QLabel("pre-trigger"), 2, 4)
        ctl.addWidget(self.pre_spin, 2, 5)
        ctl.addWidget(self.apply_btn, 2, 6)
        ctl.addWidget(self.progress, 3, 0, 1, 4)
        ctl.addWidget(self.counter, 3, 4, 1, 3)
        lights_row = QHBoxLayout()
        lights_row.addWidget(QLabel("overload:"))
        lights_row.addLayout(self.lights_box)
        lights_row.addStretch(1)
        ctl.addLayout(lights_row, 4, 0, 1, 7)

        self.trace_plot = pg.PlotWidget(title="time traces (last record)")
        self.trace_plot.setLabel("bottom", "time", "s")
        self.trace_plot.addLegend(offset=(-5, 5), brush=pg.mkBrush(255, 255, 255, 210))
        self.spec_plot = pg.PlotWidget(title="amplitude spectra (last record)")
        self.spec_plot.setLabel("bottom", "frequency", "Hz")
        self.spec_plot.addLegend(offset=(-5, 5), brush=pg.mkBrush(255, 255, 255, 210))
        self.spec_plot.setLabel("left", "level (dB re 1 unit of the channel: N, m/s², V)")
        for p in (self.trace_plot, self.spec_plot):
            p.setBackground("w")
            p.showGrid(x=True, y=True, alpha=0.3)
        split = QSplitter(Qt.Horizontal)
        split.addWidget(self.trace_plot)
        split.addWidget(self.spec_plot)

        lay = QVBoxLayout(self)
        lay.addLayout(ctl)
        lay.addWidget(split, 1)
        lay.addWidget(self.log)

        self.run_btn.clicked.connect(self._choose_run)
        self.start_btn.clicked.connect(self.start)
        self.abort_btn.clicked.connect(self.abort)
        self.apply_btn.clicked.connect(self.apply_trigger)
        self.device_combo.currentIndexChanged.connect(self._device_changed)
        main.setup.rig_box.validated.connect(self._rig_changed)
        self._rig_changed(main.setup.rig_box.validate())
        self.done = {"hammer": 0, "wave": 0}
        self.planned = {"hammer": 0, "wave": 0}
        self._pending = None
        self._acquired_into: str | None = None
        self.reload()

    # -- rig-dependent controls ------------------------------------------------
    def _rig_changed(self, rig) -> None:
        if rig is None:
            return
        changed = getattr(self, "_rig", None) is None or (self._rig.hits, self._rig.waves) != (rig.hits, rig.waves)
        self._rig = rig
        names = [f"{d.name} ({d.role})" for d in rig.devices]
        cur = self.device_combo.currentIndex()
        self.device_combo.blockSignals(True)
        self.device_combo.clear()
        self.device_combo.addItems(names)
        self.device_combo.setCurrentIndex(min(max(cur, 0), len(names) - 1))
        self.device_combo.blockSignals(False)
        self._device_changed()
        if self.job is None and changed:      # the rig's session defaults, when they change
            self.hits_spin.setValue(rig.hits)
            self.waves_spin.setValue(rig.waves)
        self._set_lights([c.name for d in rig.devices for c in d.channels])

    def _device_changed(self) -> None:
        i = self.device_combo.currentIndex()
        if i < 0 or not hasattr(self, "_rig"):
            return
        d = self._rig.devices[i]
        self.level_spin.setValue(d.trigger.level_v if d.trigger else 0.0)
        self.pre_spin.setValue(d.timing.pretrigger)

    def apply_trigger(self) -> bool:
        """Write the trigger level and pre-trigger into the rig text (Setup tab) and validate."""
        i = self.device_combo.currentIndex()
        if i < 0 or not hasattr(self, "_rig"):
            return False
        dev = self._rig.devices[i].name
        box = self.main.setup.rig_box
        try:
            text = set_device_values(box.text(), dev, level_v=self.level_spin.value(),
                                     pretrigger=self.pre_spin.value())
        except KeyError as e:
            self.main.message(f"rig: cannot set the trigger of device {dev!r}: no inline "
                              f"'trigger = {{...}}' / table {e} in the rig text", error=True)
            return False
        box.editor.setPlainText(text)
        ok = box.validate() is not None
        if ok:
            self.main.message(f"trigger of {dev}: level {self.level_spin.value():g} V, "
                              f"pre-trigger {self.pre_spin.value()} samples")
        else:
            self.main.message(box.status.text(), error=True)
        return ok

    def _set_lights(self, names: list[str]) -> None:
        if list(self.lights) == names:
            return
        for lab in self.lights.values():
            self.lights_box.removeWidget(lab)
            lab.deleteLater()
        self.lights = {n: Light(n) for n in names}
        for lab in self.lights.values():
            self.lights_box.addWidget(lab)

    def _choose_run(self) -> None:
        p, _ = QFileDialog.getSaveFileName(self, "Run file", self.run_edit.text(), "HDF5 run (*.h5)",
                                           options=QFileDialog.DontConfirmOverwrite)
        if p:
            self.run_edit.setText(p)

    # -- the session -------------------------------------------------------------
    def _specimen_for_run(self, path: Path):
        """The validated specimen, backed by a file whose text is the editor's."""
        box = self.main.setup.specimen_box
        spec = box.validate()
        if spec is None:
            return None
        if box.source.startswith("builtin:") and not box.modified():
            return spec
        if box.path and not box.modified() and Path(box.path).is_file():
            return spec
        side = path.with_suffix(".specimen.toml")
        if not box.save(str(side)):
            return None
        self.log.addItem(f"specimen text saved to {side}")
        return box.validate()

    def start(self) -> None:
        if self.main.busy():
            self.main.message("another job is running; wait or cancel it", error=True)
            return
        path = self.run_edit.text().strip()
        if not path:
            self.main.message("choose a run file (RUN.h5) first", error=True)
            return
        path = Path(path)
        setup = self.main.setup
        rig = setup.rig()
        if rig is None:
            self.main.message(setup.rig_box.status.text(), error=True)
            return
        spec = self._specimen_for_run(path)
        if spec is None:
            self.main.message(setup.specimen_box.status.text(), error=True)
            return
        try:
            effects = setup.effects()
        except UserError as e:
            self.main.message(str(e), error=True)
            return
        backend, seed = setup.backend, int(setup.seed_spin.value())
        n_hits, n_waves = self.hits_spin.value(), self.waves_spin.value()
        self.planned = {"hammer": n_hits, "wave": n_waves}
        self.done = {"hammer": 0, "wave": 0}
        self.progress.setRange(0, max(1, n_hits + n_waves))
        self.progress.setValue(0)
        self._update_counter()
        for lab in self.lights.values():
            lab.set(None)
        self.main.set_run_path(str(path), reload=False)
        self._acquired_into = str(path)

        def work(progress, should_stop):
            return services.acquire(path, rig, spec, backend=backend, effects=effects, seed=seed,
                                    hits=n_hits, waves=n_waves, progress=lambda ev: progress(("event", ev)),
                                    should_stop=should_stop,
                                    on_record=lambda k, rec: progress(("record", display_record(k, rec))))

        self.job = self.main.start_job("acquisition", work, self._done, on_progress=self._progress,
                                       on_failed=self._failed)
        if self.job is not None:
            self.start_btn.setEnabled(False)
            self.abort_btn.setEnabled(True)
            self.log.addItem(f"acquisition started: {n_hits} hits, {n_waves} wave shots, "
                             f"backend {backend}, into {path}")

    def abort(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.log.addItem("abort requested: stopping after the shot in progress")
            self.main.message("acquisition: stopping after the shot in progress")

    def _progress(self, item) -> None:
        what, obj = item
        if what == "record":            # draw at most every 100 ms: the latest record wins
            for name, ov in obj["overload"].items():
                if name in self.lights:
                    self.lights[name].set(bool(ov))
            if self._pending is None:
                QTimer.singleShot(100, self._flush_record)
            self._pending = obj
            return
        ev = obj
        self.log.addItem(f"{ev['kind']} {ev['index']}/{ev['total']}: {ev['message']}")
        self.log.scrollToBottom()
        if ev["status"] == "recorded":
            self.done[ev["kind"]] += 1
            self.progress.setValue(sum(self.done.values()))
            self._update_counter()

    def _flush_record(self) -> None:
        d, self._pending = self._pending, None
        if d is not None:
            self.show_record(d)

    def _update_counter(self) -> None:
        self.counter.setText(f"hits {self.done['hammer']}/{self.planned['hammer']} · "
                             f"waves {self.done['wave']}/{self.planned['wave']}")

    def show_record(self, d: dict) -> None:
        self.trace_plot.clear()
        self.spec_plot.clear()
        self.trace_plot.setTitle(f"time traces: last {d['kind']} record")
        self.spec_plot.setTitle(f"amplitude spectra: last {d['kind']} record")
        for i, (name, y) in enumerate(d["traces"].items()):
            col = COLORS[i % len(COLORS)]
            peak = float(np.max(np.abs(y))) or 1.0
            self.trace_plot.plot(d["t"], y / peak, pen=pg.mkPen(col, width=1),
                                 name=f"{name} (÷{peak:.3g} {d['units'][name]})")
            self.spec_plot.plot(d["f"][1:], d["spectra"][name][1:], pen=pg.mkPen(col, width=1),
                                name=f"{name} (dB re 1 {d['units'][name]})")
        self.trace_plot.setLabel("left", "normalised signal")
        for name, ov in d["overload"].items():
            if name in self.lights:
                self.lights[name].set(bool(ov))

    def _finish(self) -> None:
        self.job = None
        self.start_btn.setEnabled(True)
        self.abort_btn.setEnabled(False)

    def _done(self, summary: dict) -> None:
        self._finish()
        self._flush_record()
        rec = summary["recorded"]
        msg = (f"acquisition {'interrupted' if summary['interrupted'] else 'done'}: recorded "
               f"{rec['hammer']} hits and {rec['wave']} wave shots; the file holds "
               f"{summary['in_file']['hammer']} + {summary['in_file']['wave']}")
        if any(summary["gave_up"].values()):
            msg += " · gave up: " + "; ".join(summary["problems"][-1:])
        self.log.addItem(msg)
        self.main.message(msg, error=any(summary["gave_up"].values()))
        self.last_summary = summary
        self.main.run_changed()

    def _failed(self, msg: str) -> None:
        self._finish()
        self.log.addItem("error: " + msg)
        self.log.scrollToBottom()

    # -- an opened run ------------------------------------------------------------------
    def reload(self) -> None:
        """Show what the run file holds when no acquisition is running: shot counts
        and the last stored record (the last wave shot if any, else the last hit)."""
        run = self.main.run_path
        if self.job is not None or (run and run == self._acquired_into):
            return      # acquiring, or just acquired here: the live view already shows it
        counts = {"hammer": 0, "wave": 0}
        snap = self.main.snapshot()         # the run read once (gui.snapshot)
        if snap is not None:
            counts.update(snap.run.counts)
        self.done = {k: int(counts.get(k, 0)) for k in ("hammer", "wave")}
        self.planned = dict(self.done)
        self.counter.setText(f"in the run file: {self.done['hammer']} hits · {self.done['wave']} wave shots")
        kind = "wave" if self.done["wave"] else ("hammer" if self.done["hammer"] else None)
        if kind is None:
            self.trace_plot.clear()
            self.spec_plot.clear()
            empty_note(self.trace_plot, "no data yet: no shot recorded in this run")
            empty_note(self.spec_plot, "no data yet")
            return
        rec = snap.last if snap is not None and snap.last_kind == kind else None
        if rec is None:
            self.main.message(f"cannot read the last {kind} shot of {run}", error=True)
            return
        self.show_record(display_record(kind, rec))
        self.trace_plot.setTitle(f"time traces: last stored {kind} record ({rec.meta.get('shot', '')})")

    # -- session state ----------------------------------------------------------------
    def state(self) -> dict:
        return {"hits": int(self.hits_spin.value()), "waves": int(self.waves_spin.value())}

    def restore(self, st: dict) -> None:
        if "hits" in st:
            self.hits_spin.setValue(int(st["hits"]))
        if "waves" in st:
            self.waves_spin.setValue(int(st["waves"]))
