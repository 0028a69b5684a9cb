"""Gap tab: the sim-to-real diagnosis (``labid.services.run_diagnosis``, as ``labid
diagnose``): verdict, where the gap lies, ranked effects, residuals before/after."""
from __future__ import annotations

import tomllib

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QHBoxLayout, QHeaderView, QLabel, QPushButton, QTableWidget,
                               QTableWidgetItem, QVBoxLayout, QWidget)

from .. import services
from ..base.summary import eng
from .common import Banner, empty_note, plot


def _f(v, fmt=".3g") -> str:
    return "—" if not isinstance(v, (int, float)) or not np.isfinite(v) else format(v, fmt)


def _magnitude(e: dict) -> str:
    """An effect's magnitude in engineering notation with its unit ('561 µm'; '0.004 (ratio)' when
    unitless, as the report says)."""
    unit = str(e.get("unit") or "")
    if unit in ("", "1"):
        return f"{_f(e.get('magnitude'))} (ratio)"
    if unit.isalpha() and len(unit) <= 2:          # m, s, kg, K: an SI prefix reads well
        return eng(e.get("magnitude"), unit, 3)
    return f"{_f(e.get('magnitude'))} {unit}"


class GapView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.result: dict | None = None
        self.job = None
        self.banner = Banner()
        self.run_btn = QPushButton("Diagnose")
        self.verdict = QLabel("no diagnosis yet")
        self.verdict.setStyleSheet("font-size: 14pt; font-weight: bold;")
        self.where = QLabel("")
        self.where.setWordWrap(True)
        self.where.setMinimumHeight(4 * self.where.fontMetrics().height())
        self.where.setAlignment(Qt.AlignTop | Qt.AlignLeft)
        self.table = QTableWidget(0, 6)
        self.table.setHorizontalHeaderLabels(["rank", "effect", "magnitude (unit)", "gap after (rms residual/σ)",
                                              "score (0-1)", "detectable"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.verticalHeader().setVisible(False)
        self.resid_plot = plot("residuals before / after (model − measured) / σ", ("feature", ""), ("", ""))
        self.resid_plot.addLegend(offset=(-5, 5), brush=pg.mkBrush(255, 255, 255, 210))
        self.group_plot = plot("χ² per feature by group (1 = noise)", ("χ²/n", ""), ("", ""))
        top = QHBoxLayout()
        top.addWidget(self.run_btn)
        top.addWidget(self.verdict, 1)
        left = QVBoxLayout()
        left.addWidget(self.where)
        left.addWidget(self.table, 1)
        lw = QWidget()
        lw.setLayout(left)
        lw.setMinimumWidth(470)
        lw.setMaximumWidth(560)
        right = QVBoxLayout()
        right.addWidget(self.resid_plot, 3)
        right.addWidget(self.group_plot, 2)
        body = QHBoxLayout()
        body.addWidget(lw)
        body.addLayout(right, 1)
        lay = QVBoxLayout(self)
        lay.addWidget(self.banner)
        lay.addLayout(top)
        lay.addLayout(body, 1)
        self.run_btn.clicked.connect(self.diagnose)
        self.reload()

    def features(self) -> dict | None:
        f = self.main.identification.features_file_doc
        return f if f is not None else self.main.features()

    def reload(self) -> None:
        doc = self.features()
        if not doc:
            self.banner.info("no measured features yet: acquire and analyse first (or load a features "
                             "file on the Identification tab)")
            self.run_btn.setEnabled(False)
        else:
            self.banner.info("diagnosis of the measured features against the nominal model and rig")
            self.run_btn.setEnabled(self.job is None)
        res = self.main.read_results("diagnosis")
        if res and self.job is None:
            self.show_result(res)
        elif self.job is None and self.result is None:
            for w in (self.resid_plot, self.group_plot):
                w.clear()
                w.setXRange(0, 1)
                w.setYRange(0, 1)
                empty_note(w, "no data yet: " + ("press Diagnose" if doc else "no measured features"))

    def diagnose(self) -> None:
        doc = self.features()
        if not doc:
            self.main.message("diagnosis: no features", error=True)
            return
        doc = dict(doc)
        if not doc.get("specimen"):
            spec_text = self.main.setup.specimen_box.text()
            try:
                doc["specimen"] = tomllib.loads(spec_text)
            except tomllib.TOMLDecodeError:
                self.main.message("diagnosis: the specimen on the Setup tab is malformed", error=True)
                return

        # the same parameter selection as the identification shown in the panel (issue 13:
        # the diagnosis starts from the estimate identify reports)
        ident = self.main.read_results("identification")
        names = list(ident["parameters"]) if isinstance(ident, dict) and isinstance(
            ident.get("parameters"), dict) and ident["parameters"] else None

        def work(progress, should_stop):
            return services.run_diagnosis(doc, ".", "<features>", names=names)

        self.job = self.main.start_job("diagnosis", work, self._done, on_failed=self._failed)
        if self.job is not None:
            self.run_btn.setEnabled(False)
            self.verdict.setText("diagnosing…")

    def _failed(self, msg: str) -> None:
        self.job = None
        self.run_btn.setEnabled(True)
        self.verdict.setText("diagnosis failed")

    def _done(self, res: dict) -> None:
        self.job = None
        self.run_btn.setEnabled(True)
        self.main.store_results("diagnosis", res)
        self.show_result(res)
        self.main.message(f"diagnosis done: verdict {res.get('verdict')}")

    def show_result(self, res: dict) -> None:
        self.result = res
        g = res.get("gap") or {}
        self.verdict.setText(f"verdict: {res.get('verdict', '—')} · gap {_f(g.get('before'))} → "
                             f"{_f(g.get('after'))} (rms residual/σ; held out {_f(g.get('held_out_before'))}"
                             f" → {_f(g.get('held_out_after'))})")
        where = res.get("where") or []
        self.where.setText("where the gap lies: " + (", ".join(map(str, where)) if where else
                                                     "nowhere significant"))
        effects = [e for e in (res.get("effects") or []) if isinstance(e, dict)]
        self.table.setRowCount(len(effects))
        for i, e in enumerate(effects):
            cells = [str(i + 1), str(e.get("name")), _magnitude(e),
                     _f(e.get("gap_after")), _f(e.get("score")), "yes" if e.get("detectable", True) else "no"]
            for j, c in enumerate(cells):
                item = QTableWidgetItem(c)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                self.table.setItem(i, j, item)
        # residuals before/after per feature
        self.resid_plot.clear()
        self.resid_plot.enableAutoRange()
        self.group_plot.enableAutoRange()
        ft = res.get("features") or {}
        r0 = np.asarray(ft.get("residual_before", []), float)
        r1 = np.asarray(ft.get("residual_after", []), float)
        if r0.size:
            x = np.arange(r0.size)
            self.resid_plot.addItem(pg.BarGraphItem(x=x - 0.2, height=r0, width=0.4, brush="#1f77b4",
                                                    name="before (constants only)"))
            if r1.size == r0.size:
                self.resid_plot.addItem(pg.BarGraphItem(x=x + 0.2, height=r1, width=0.4, brush="#aaaaaa",
                                                        name=f"after ({res.get('verdict')})"))
            labels = [str(lb) for lb in ft.get("labels", [])]
            width = max(200, self.resid_plot.width())
            longest = max((len(lb) for lb in labels), default=1)
            fit = max(1, int(width / (7 * longest + 12)))
            step = max(1, -(-len(labels) // fit))
            self.resid_plot.getAxis("bottom").setTicks([[(i, labels[i]) for i in range(0, len(labels), step)],
                                                        [(i, "") for i in range(len(labels))]])
            for y in (-2, 2):
                self.resid_plot.addItem(pg.InfiniteLine(y, angle=0, pen=pg.mkPen("#888", style=Qt.DashLine)))
        # chi2 per group
        self.group_plot.clear()
        groups = [d for d in (res.get("groups") or []) if isinstance(d, dict) and d.get("n", 0) > 0][:12]
        if groups:
            y = np.arange(len(groups))[::-1]
            val = np.array([float(d["chi2"]) / max(int(d["n"]), 1) for d in groups])
            brushes = ["#d62728" if d.get("significant") else "#1f77b4" for d in groups]
            self.group_plot.addItem(pg.BarGraphItem(x0=0, y=y, height=0.7, width=val, brushes=brushes))
            ax = self.group_plot.getAxis("left")
            ax.setTicks([[(yy, str(d["group"])) for yy, d in zip(y, groups)]])
            ax.setWidth(int(7 * max(len(str(d["group"])) for d in groups) + 12))
            self.group_plot.addItem(pg.InfiniteLine(1.0, angle=90, pen=pg.mkPen("k")))

    def state(self) -> dict:
        return {}

    def restore(self, st: dict) -> None:
        pass
