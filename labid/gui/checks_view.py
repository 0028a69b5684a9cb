"""Hammer checks tab: what a technician looks at before trusting the hits of a run (issue 26).

Left: the force of every hit in N against time after the trigger (ms), and a table of the
hits with their peak force and flags (double hit, overloaded channels). Right: per response
channel |H1| over the hits in dB re 1 (channel unit)/N, and the ordinary coherence (0-1)
under it; a coherence well below 1 at a resonance means the hits disagree there. The data
come from ``services.hammer_checks`` on the run's hammer shots, computed in a worker thread
when the run changes.
"""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHBoxLayout, QSplitter, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget

from .. import services
from .common import Banner, empty_note, plot

COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"]
UNITS = {"m/s^2": "m/s²"}


class ChecksView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.job = None
        self.checks = None
        self.banner = Banner()
        self.force_plot = plot("hammer force of each hit", ("time after trigger", "ms"), ("force", "N"))
        self.frf_plot = plot("|H1| per channel over the hits", ("frequency", "Hz"), ("|H1|", "dB re 1 (m/s²)/N"))
        self.frf_plot.addLegend(offset=(-5, 5), brush=pg.mkBrush(255, 255, 255, 210))
        self.coh_plot = plot("coherence γ² per channel", ("frequency", "Hz"), ("coherence γ²", ""))
        self.coh_plot.setXLink(self.frf_plot)
        self.coh_plot.setYRange(0, 1.05, padding=0)
        self.table = QTableWidget(0, 4)
        self.table.setHorizontalHeaderLabels(["hit", "peak force (N)", "double hit", "overloaded channels"])
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.setMaximumHeight(180)
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.setContentsMargins(0, 0, 0, 0)
        ll.addWidget(self.force_plot, 1)
        ll.addWidget(self.table)
        right = QSplitter(Qt.Vertical)
        right.addWidget(self.frf_plot)
        right.addWidget(self.coh_plot)
        right.setSizes([500, 250])
        body = QSplitter(Qt.Horizontal)
        body.addWidget(left)
        body.addWidget(right)
        lay = QVBoxLayout(self)
        lay.addWidget(self.banner)
        row = QHBoxLayout()
        row.addWidget(body)
        lay.addLayout(row, 1)
        self.show_checks(None)

    def reload(self) -> None:
        """Recompute the checks of the run's hammer hits in a worker thread."""
        snap = self.main.snapshot()
        run = self.main.run_path
        if snap is None or not snap.run.counts.get("hammer"):
            self.show_checks(None)
            return
        if self.job is not None:
            return

        def work(progress, should_stop):
            return services.hammer_checks(services.shots(run, "hammer"))

        def done(checks) -> None:
            self.job = None
            self.show_checks(checks)

        def failed(msg: str) -> None:
            self.job = None

        self.job = self.main.start_job("hammer checks", work, done, on_failed=failed, exclusive=False)

    def show_checks(self, c) -> None:
        self.checks = c
        for p in (self.force_plot, self.frf_plot, self.coh_plot):
            p.clear()
        self.table.setRowCount(0)
        if c is None:
            self.banner.info("no hammer hits with a force channel in this run")
            for p in (self.force_plot, self.frf_plot, self.coh_plot):
                empty_note(p, "no data yet: no hammer hit")
            return
        bad = [h for h, d, o in zip(c.hits, c.double_hit, c.overload) if d or o]
        if bad:
            self.banner.warn(f"{len(bad)} of {len(c.hits)} hits flagged (double hit or overload): "
                             + ", ".join(bad) + "; consider discarding them")
        else:
            self.banner.info(f"{len(c.hits)} hits: no double hit, no overload")
        t_ms = c.times_s * 1e3
        mask = (t_ms >= -0.5) & (t_ms <= 8.0)       # the pulse (~0.3-1 ms) and a double hit within 8 ms
        for i, (h, f, dh, ov) in enumerate(zip(c.hits, c.force_n, c.double_hit, c.overload)):
            col = "#d62728" if (dh or ov) else COLORS[i % len(COLORS)]
            self.force_plot.plot(t_ms[mask], np.asarray(f)[mask], pen=pg.mkPen(col, width=1.5 if dh or ov else 1))
        for i, (h, pk, dh, ov) in enumerate(zip(c.hits, c.peak_n, c.double_hit, c.overload)):
            self.table.insertRow(i)
            for j, text in enumerate((h, f"{pk:.3g}", "YES" if dh else "no", ", ".join(ov) or "none")):
                item = QTableWidgetItem(text)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                if (j == 2 and dh) or (j == 3 and ov):
                    item.setForeground(pg.mkColor("#b00000"))
                self.table.setItem(i, j, item)
        units = {UNITS.get(u, u) for u in c.units.values()}
        ref = f"dB re 1 ({units.pop()})/N" if len(units) == 1 else "dB re 1 (channel unit)/N"
        self.frf_plot.setLabel("left", "|H1|", ref)
        for i, (name, db) in enumerate(c.frf_db.items()):
            col = COLORS[i % len(COLORS)]
            self.frf_plot.plot(c.frequencies_hz, db, pen=pg.mkPen(col, width=1), name=name)
            if c.coherence is not None:
                self.coh_plot.plot(c.frequencies_hz, c.coherence[name], pen=pg.mkPen(col, width=1))
        lo = min(float(np.min(v)) for v in c.frf_db.values())
        hi = max(float(np.max(v)) for v in c.frf_db.values())
        if hi - lo < 20.0:           # a flat |H1| (a gauge, a check with a known gain): keep 20 dB in view
            mid = 0.5 * (lo + hi)
            self.frf_plot.setYRange(mid - 10.0, mid + 10.0, padding=0)
        self.frf_plot.setXRange(0.0, float(c.frequencies_hz[-1]), padding=0.02)
        if c.coherence is None:
            empty_note(self.coh_plot, "coherence needs two hits or more")
        self.coh_plot.setYRange(0, 1.05, padding=0)

    def state(self) -> dict:
        return {}

    def restore(self, st: dict) -> None:
        pass
