"""Waves tab: the scalogram of a wave shot with the picked arrival ridge, and the
group velocity (with error bars) against the SAFE curve (nominal and identified).

Arrivals and velocities are those of the analysis workflow (``labid.workflows.analysis``,
stored under ``/results/analysis``); the scalogram is ``services.scalogram``
(the analysis' wavelet and band), the curves ``services.model_group_velocity``.
"""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from .. import services
from .common import Banner, empty_note, plot

COLORS = {"A0": "#1f77b4", "S0": "#d62728", "SH0": "#2ca02c"}


class WavesView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.banner = Banner()
        self.shot_combo = QComboBox()
        self.shot_combo.setSizeAdjustPolicy(QComboBox.AdjustToContents)
        self.shot_combo.setMinimumContentsLength(18)
        self.info = QLabel("")
        self.scalogram = plot("scalogram |W(f, t)|", ("time after trigger", "s"), ("frequency", "Hz"))
        self.scalogram.getAxis("left").enableAutoSIPrefix(True)
        self.image = pg.ImageItem()
        self.image.setColorMap(pg.colormap.get("viridis"))
        self.scalogram.addItem(self.image)
        # the colour scale of |W| (issue 26), in the unit of the record's channel
        self.colorbar = pg.ColorBarItem(colorMap=pg.colormap.get("viridis"), interactive=False, width=12)
        self.colorbar.setImageItem(self.image, insert_in=self.scalogram.getPlotItem())
        self.ridge = pg.PlotDataItem(pen=pg.mkPen("w", width=2), symbol="o", symbolSize=4, symbolBrush="w")
        self.scalogram.addItem(self.ridge)
        self.velocity = plot("group velocity", ("frequency", "Hz"), ("group velocity", "m/s"))
        self.velocity.addLegend(offset=(-5, -5))
        self.velocity.getAxis("left").enableAutoSIPrefix(True)
        top = QHBoxLayout()
        top.addWidget(QLabel("record"))
        top.addWidget(self.shot_combo)
        top.addWidget(self.info, 1)
        body = QHBoxLayout()
        body.addWidget(self.scalogram, 1)
        body.addWidget(self.velocity, 1)
        lay = QVBoxLayout(self)
        lay.addWidget(self.banner)
        lay.addLayout(top)
        lay.addLayout(body, 1)
        self.shot_combo.currentIndexChanged.connect(self._draw_scalogram)
        self._records: list = []
        self._res: dict | None = None
        self._safe_job = None
        self.safe_curves: dict = {}
        self.reload()

    # -- data ---------------------------------------------------------------------------
    def reload(self) -> None:
        res = self.main.read_results("analysis")
        self._res = res
        if not res:
            self.banner.info("no group velocities yet: record wave shots and press 'Analyze run' (Modes tab)"
                             if self.main.run_path else "no run file yet: acquire first")
        elif not res.get("waves"):
            notes = [n for n in np.atleast_1d(res.get("notes", [])) if "A0" in str(n) or "S0" in str(n)
                     or "wave" in str(n)]
            self.banner.warn("the analysis found no usable group velocities in this run"
                             + (": " + "; ".join(map(str, notes)) if notes else ""))
        else:
            self.banner.info("arrival ridge and group velocities of the analysis; SAFE curves of the "
                             "nominal and the identified constants")
        self._load_records()
        self._draw_scalogram()
        self._draw_velocity()
        self._compute_safe()

    def set_analysis(self, an) -> None:
        self.reload()

    def _load_records(self) -> None:
        self._records = []
        self.shot_combo.blockSignals(True)
        self.shot_combo.clear()
        snap = self.main.snapshot()         # the run read once (gui.snapshot): up to 10 wave shots
        if snap is not None:
            for r in snap.waves:
                for c in r.channels:
                    self._records.append((r, c.name))
                    self.shot_combo.addItem(f"{r.meta.get('shot', '?')} · {c.name}")
        if self._records:   # default: the farthest sensor of the first shot
            n = len(self._records[0][0].channels)
            self.shot_combo.setCurrentIndex(n - 1)
        self.shot_combo.blockSignals(False)

    def _specimen(self):
        doc = self.main.features() or {}
        try:
            return self.main.specimen_for_features(doc)
        except Exception:  # noqa: BLE001
            return None

    # -- drawing -------------------------------------------------------------------------------
    def _draw_scalogram(self) -> None:
        i = self.shot_combo.currentIndex()
        note = getattr(self, "_scalo_note", None)
        if note is None:            # one note item, shown while there is no record
            note = self._scalo_note = pg.TextItem("no data yet: no wave shot in this run", color="#777777",
                                                  anchor=(0.5, 0.5))
            self.scalogram.addItem(note)
        if i < 0 or i >= len(self._records):
            self.image.clear()
            self.ridge.setData([], [])
            self.scalogram.setXRange(0, 1, padding=0)
            self.scalogram.setYRange(0, 1, padding=0)
            note.setPos(0.5, 0.5)
            note.setVisible(True)
            return
        note.setVisible(False)
        rec, name = self._records[i]
        fs = rec.timing.rate_hz
        arr = (self._res or {}).get("arrivals") or {}
        sc = services.scalogram(rec, name, self._res, n_freqs=100)
        t, fmin, fmax = sc.times_s, float(sc.frequencies_hz[0]), float(sc.frequencies_hz[-1])
        self.image.setImage(sc.magnitude.T, autoLevels=True)
        self.colorbar.setLevels((float(sc.magnitude.min()), float(sc.magnitude.max())))
        unit = {"accelerometer": "m/s²", "force": "N"}.get(rec.channel(name).kind, "V")
        self.colorbar.axis.setLabel("|W|", units=unit)     # SI prefix added by the axis: mV
        self.image.setRect(pg.QtCore.QRectF(t[0], fmin, t[-1] - t[0], fmax - fmin))
        self.info.setText(f"{sc.wavelet} · {fs / 1e6:g} MHz · {len(t)} samples")
        self.ridge.setData([], [])
        if arr and "times_s" in arr and i == len(self._records[0][0].channels) - 1:
            self.ridge.setData(np.asarray(arr["times_s"], float), np.asarray(arr["frequencies_hz"], float))
        self.scalogram.setXRange(t[0], t[-1], padding=0)
        self.scalogram.setYRange(fmin, fmax, padding=0)

    def _draw_velocity(self) -> None:
        p = self.velocity
        p.clear()
        curves = (self._res or {}).get("waves") or {}
        if not curves:
            p.setXRange(0, 1)
            p.setYRange(0, 1)
            empty_note(p, "no group velocities in this run")
        else:
            p.enableAutoRange()
        for key, c in curves.items():
            mode = key.split("_")[0]
            ok = np.asarray(c.get("valid", np.ones(len(c["frequency_hz"]))), bool)
            f = np.asarray(c["frequency_hz"], float)[ok]
            v = np.asarray(c["group_velocity_m_s"], float)[ok]
            s = np.asarray(c["sigma_m_s"], float)[ok]
            col = COLORS.get(mode, "#9467bd")
            p.addItem(pg.ErrorBarItem(x=f, y=v, top=s, bottom=s, beam=0.0, pen=pg.mkPen(col)))
            p.plot(f, v, pen=None, symbol="o", symbolSize=5, symbolBrush=col, name=f"measured {mode}, {key.partition('_')[2]}°")
        for (mode, which), (f, v) in self.safe_curves.items():
            col = COLORS.get(mode, "#9467bd")
            style = Qt.DashLine if which == "nominal" else Qt.SolidLine
            p.plot(f, v, pen=pg.mkPen(col, width=2, style=style), name=f"SAFE {mode}, {which}")

    def _compute_safe(self) -> None:
        curves = (self._res or {}).get("waves") or {}
        spec = self._specimen()
        if not curves or spec is None or self._safe_job is not None:
            return
        params = services.parameters_of(self.main.read_results("identification"))
        lam = spec.laminate
        todo = []
        for key, c in curves.items():
            mode, direction = key.split("_")[0], float(key.split("_")[1])
            f = np.asarray(c["frequency_hz"], float)
            grid = np.linspace(f.min(), f.max(), 40)
            todo.append((mode, direction, grid))

        def work(progress, should_stop):
            out = {}
            for mode, direction, grid in todo:
                out[(mode, "nominal")] = (grid, services.model_group_velocity(lam, grid, mode, direction))
                if params:
                    out[(mode, "identified")] = (grid, services.model_group_velocity(lam, grid, mode, direction,
                                                                                     params))
            return out

        def done(out):
            self._safe_job = None
            self.safe_curves = out
            self._draw_velocity()

        def failed(msg):
            self._safe_job = None

        self._safe_job = self.main.start_job("SAFE curves", work, done, on_failed=failed, exclusive=False)

    def state(self) -> dict:
        return {"record": int(self.shot_combo.currentIndex())}

    def restore(self, st: dict) -> None:
        pass
