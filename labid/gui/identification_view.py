"""Identification tab: parameters and data (modal / waves / combined), estimate ± std,
the GUM uncertainty budget, convergence history, multi-start scatter and the
identifiability view.

The work is ``labid.services.run_identification`` (the one flow of ``labid identify``, with
a multi-start study) in a background job: it reports each model evaluation and stops at the
next one when cancelled; then the GUM budget (``budget=True``, as ``labid identify`` prints
it) in the same job. Results are read and shown as the typed
``labid.services.Identification`` the command line stores too (data kinds, "identified"
by its one definition); a stored result shows the ``uncertainty_budget`` it holds: per
constant u_c and U (k = 2) and the standard uncertainty each input contributes (its share
of u_c² in the tooltip).
"""
from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QButtonGroup, QCheckBox, QComboBox, QFileDialog, QGridLayout,
                               QGroupBox, QHBoxLayout, QHeaderView, QLabel, QPushButton, QRadioButton,
                               QLineEdit, QSpinBox, QTableWidget, QTabWidget, QTableWidgetItem, QVBoxLayout, QWidget)

from pathlib import Path

from .. import services
from ..base.errors import Cancelled, UserError
from ..base.summary import display_unit
from .budget_view import BudgetView
from .common import Banner, empty_note, plot

DATA = ("modal", "waves", "combined")
SYMBOLS = ("o", "s", "t", "d", "+", "x")
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")


def _num(v, default: float = math.nan) -> float:
    """A stored number as float; None, text or a missing entry as ``default`` (NaN)."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return default
    return x


class IdentificationView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.result: dict | None = None
        self.features_file_doc: dict | None = None
        self.features_dir = "."
        self.banner = Banner()
        # controls
        self.data_radios = {d: QRadioButton(d) for d in DATA}
        grp = QButtonGroup(self)
        for r in self.data_radios.values():
            grp.addButton(r)
        self.data_radios["combined"].setChecked(True)
        self.param_box = QGroupBox("parameters")
        self.param_layout = QGridLayout(self.param_box)
        self.param_checks: dict[str, QCheckBox] = {}
        self.method_combo = QComboBox()
        self.method_combo.addItems(["lm", "bayes", "nelder-mead"])
        self.starts_spin = QSpinBox()
        self.starts_spin.setRange(0, 200)
        self.starts_spin.setValue(0)
        self.start_edit = QLineEdit()
        self.start_edit.setPlaceholderText("start P=V,.. (SI; default: nominal)")
        self.load_btn = QPushButton("Load features…")
        self.run_btn = QPushButton("Identify")
        self.cancel_btn = QPushButton("Cancel")
        self.cancel_btn.setEnabled(False)
        self.progress_label = QLabel("")
        ctl = QGroupBox("data and method")
        cl = QGridLayout(ctl)
        row = QHBoxLayout()
        for r in self.data_radios.values():
            row.addWidget(r)
        cl.addWidget(QLabel("data"), 0, 0)
        cl.addLayout(row, 0, 1)
        cl.addWidget(QLabel("method"), 1, 0)
        cl.addWidget(self.method_combo, 1, 1)
        cl.addWidget(QLabel("multi-start runs"), 2, 0)
        cl.addWidget(self.starts_spin, 2, 1)
        cl.addWidget(QLabel("start"), 3, 0)
        cl.addWidget(self.start_edit, 3, 1)
        btns = QHBoxLayout()
        btns.addWidget(self.load_btn)
        btns.addWidget(self.run_btn)
        btns.addWidget(self.cancel_btn)
        cl.addLayout(btns, 4, 0, 1, 2)
        cl.addWidget(self.progress_label, 5, 0, 1, 2)
        self.source_label = QLabel("")
        self.source_label.setWordWrap(True)
        cl.addWidget(self.source_label, 6, 0, 1, 2)
        # results
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["parameter", "value ± std", "rel. std", "nominal", "identified"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.verticalHeader().setVisible(False)
        # measured peaks against FE modes with their (m,n) family, when the result has a pairing
        self.pairing_table = QTableWidget(0, 6)
        self.pairing_table.setHorizontalHeaderLabels(["peak", "measured (Hz)", "FE mode", "family",
                                                      "predicted (Hz)", "difference"])
        self.pairing_table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.pairing_table.horizontalHeader().setStretchLastSection(True)
        self.pairing_table.verticalHeader().setVisible(False)
        self.pairing_table.setVisible(False)
        # the GUM budget: one row per source (type A, each type-B input), u_c and U, one column per constant
        self.budget_box = BudgetView()
        self.budget_label, self.budget_table = self.budget_box.label, self.budget_box.table
        self.summary = QLabel("")
        self.summary.setWordWrap(True)
        self.summary.setMinimumHeight(3 * self.summary.fontMetrics().height())
        self.history_plot = plot("convergence history", ("iteration", ""), ("cost (χ²)", ""))
        self.history_plot.setLogMode(y=True)
        self.multi_plot = plot("multi-start: identified / nominal", ("start number", ""), ("ratio", ""))
        self.multi_plot.addLegend(offset=(5, 5))
        self.ident_plot = plot("identifiability: posterior rel. std per data set", ("parameter", ""),
                               ("rel. std", ""))
        self.ident_plot.setLogMode(y=True)
        self.ident_plot.getAxis("left").enableAutoSIPrefix(False)
        self.history_plot.getAxis("left").enableAutoSIPrefix(False)
        self.ident_plot.addLegend(offset=(5, 5))

        left = QVBoxLayout()
        left.addWidget(ctl)
        left.addWidget(self.param_box)
        left.addWidget(self.table, 1)
        left.addWidget(self.pairing_table, 1)
        left.addWidget(self.summary)
        lw = QWidget()
        lw.setLayout(left)
        lw.setMinimumWidth(500)
        lw.setMaximumWidth(560)
        plots = QGridLayout()
        plots.addWidget(self.history_plot, 0, 0)
        plots.addWidget(self.ident_plot, 0, 1)
        # the GUM budget and the multi-start study share the lower half: one tab each
        self.lower_tabs = QTabWidget()
        self.lower_tabs.addTab(self.budget_box, "GUM uncertainty budget")
        self.lower_tabs.addTab(self.multi_plot, "multi-start")
        plots.addWidget(self.lower_tabs, 1, 0, 1, 2)
        plots.setRowStretch(0, 1)
        plots.setRowStretch(1, 1)
        body = QHBoxLayout()
        body.addWidget(lw)
        body.addLayout(plots, 1)
        lay = QVBoxLayout(self)
        lay.addWidget(self.banner)
        lay.addLayout(body, 1)

        self.run_btn.clicked.connect(self.identify)
        self.cancel_btn.clicked.connect(self.cancel)
        self.load_btn.clicked.connect(self._load_dialog)
        self.job = None
        self.reload()

    # -- inputs ---------------------------------------------------------------------
    def features(self) -> dict | None:
        """The features to identify from: a loaded file, else what the run's analysis holds."""
        if self.features_file_doc is not None:
            return self.features_file_doc
        return self.main.features()

    def load_features_file(self, path: str) -> bool:
        try:
            doc = services.load_features_file(path)
        except UserError as e:
            self.main.message(str(e), error=True)
            return False
        self.features_file_doc = doc
        self.features_dir = str(Path(path).parent)
        self.source_label.setText(f"features: {path}")
        self.reload()
        return True

    def _load_dialog(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, "Features", "", "JSON (*.json)")
        if p:
            self.load_features_file(p)

    def _set_params(self, names: tuple[str, ...], default: tuple[str, ...]) -> None:
        if tuple(self.param_checks) == names:
            return
        default = tuple(getattr(self, "_pending_params", None) or default)
        for cb in self.param_checks.values():
            self.param_layout.removeWidget(cb)
            cb.deleteLater()
        self.param_checks = {}
        for i, n in enumerate(names):
            cb = QCheckBox(n)
            cb.setChecked(n in default)
            self.param_checks[n] = cb
            self.param_layout.addWidget(cb, i // 4, i % 4)

    def chosen_params(self) -> tuple[str, ...]:
        return tuple(n for n, cb in self.param_checks.items() if cb.isChecked())

    def data_choice(self) -> str:
        return next(d for d, r in self.data_radios.items() if r.isChecked())

    def reload(self) -> None:
        try:
            st = self.main.read_results("identification")
        except Exception:  # noqa: BLE001 - an unreadable group just is not shown
            st = None
        doc = self.features()
        if not doc:
            self.banner.info("no measured features yet: acquire and analyse (Modes, Waves tabs), "
                             "or load a features file")
            self.run_btn.setEnabled(False)
        else:
            has = {"modal": bool(doc.get("modal")), "waves": bool(doc.get("waves"))}
            self.data_radios["modal"].setEnabled(has["modal"])
            self.data_radios["waves"].setEnabled(has["waves"])
            self.data_radios["combined"].setEnabled(has["modal"] and has["waves"])
            if not self.data_radios[self.data_choice()].isEnabled():
                self.data_radios["modal" if has["modal"] else "waves"].setChecked(True)
            self.banner.info(f"features: {'modal' if has['modal'] else ''}"
                             f"{' + ' if all(has.values()) else ''}{'waves' if has['waves'] else ''}"
                             f" · specimen {self._specimen_name(doc)}")
            self.run_btn.setEnabled(self.job is None)
            try:
                spec = self.main.specimen_for_features(doc)
                mat = next(iter(spec.laminate.materials.values()))
                names = tuple(mat.param_names)
                # the constants of the stored identification (CLI or panel), else the CLI's default
                stored = tuple((st or {}).get("parameters") or ()) if isinstance(st, dict) else ()
                self._set_params(names, stored or services.default_params_for(doc, mat.isotropic))
            except (UserError, StopIteration, AttributeError):
                pass
        if st and self.job is None:
            self.show_result(st)
        elif self.job is None and self.result is None:
            self.show_empty()

    def show_empty(self) -> None:
        """Plots with a 'no data yet' note instead of bare 0-1 axes."""
        self.budget_box.show_budget(None, [])
        for w, text in ((self.history_plot, "no data yet: press Identify"),
                        (self.ident_plot, "no data yet"), (self.multi_plot, "no data yet")):
            w.clear()
            w.setXRange(0, 1)
            w.setYRange(0, 1)
            empty_note(w, text)

    def _specimen_name(self, doc: dict) -> str:
        s = doc.get("specimen")
        return s if isinstance(s, str) else (s or {}).get("name", "inline")

    # -- the job -------------------------------------------------------------------------
    def identify(self) -> None:
        doc = self.features()
        if not doc:
            self.main.message("identification: no features to identify from", error=True)
            return
        data = self.data_choice()
        names = self.chosen_params()
        try:
            spec = self.main.specimen_for_features(doc)
        except UserError as e:
            self.main.message(str(e), error=True)
            return
        if not names:
            self.main.message("identification: choose at least one parameter", error=True)
            return
        method = self.method_combo.currentText()
        try:
            start = services.parse_start(self.start_edit.text(), "start")
        except UserError as e:
            self.main.message(str(e), error=True)
            return
        n_starts = self.starts_spin.value()
        doc = services.select_data(doc, data)
        base_dir = self.features_dir if self.features_file_doc is not None else "."

        def work(progress, should_stop):
            res = services.run_identification(doc, specimen=spec, base_dir=base_dir, names=names, start=start,
                                              method=method, n_starts=n_starts, progress=progress,
                                              should_stop=should_stop, budget=True)
            if should_stop():
                raise Cancelled()
            return res.to_dict()

        self.job = self.main.start_job("identification", work, self._done, on_progress=self._progress,
                                       on_failed=self._failed)
        if self.job is not None:
            self.run_btn.setEnabled(False)
            self.cancel_btn.setEnabled(True)
            self.progress_label.setText("running…")

    def cancel(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.progress_label.setText("cancelling…")

    def _progress(self, item) -> None:
        if item[0] == "eval":
            self.progress_label.setText(f"running: {item[1]} model evaluations")
        elif item[0] == "start":
            self.progress_label.setText(f"multi-start {item[1]}/{item[2]}")
        elif item[0] == "budget":
            self.progress_label.setText("GUM uncertainty budget: sensitivities to the type-B inputs…")

    def _finish(self) -> None:
        self.job = None
        self.run_btn.setEnabled(True)
        self.cancel_btn.setEnabled(False)

    def _failed(self, msg: str) -> None:
        self._finish()
        self.progress_label.setText(msg)

    def _done(self, out: dict) -> None:
        self._finish()
        self.progress_label.setText(f"done in {out.get('seconds', 0):.2f} s "
                                    f"({out.get('iterations')} iterations)")
        self.main.store_results("identification", out)
        self.show_result(out)
        self.main.message("identification done" + ("" if out.get("converged") else " (NOT converged)"),
                          error=not out.get("converged"))
        self.main.modes.reload()
        self.main.waves.reload()

    # -- display -----------------------------------------------------------------------------
    def show_result(self, out: dict) -> None:
        """Show a stored or fresh identification (its dict; read as ``services.Identification``)."""
        self.result = out
        ident = services.identification_of(out) or services.Identification({})
        out = ident.estimate
        params = ident.parameters
        nominal = dict(ident.nominal) or self._specimen_nominal()
        for w in (self.history_plot, self.ident_plot):
            w.enableAutoRange()
        idp = (out.get("identifiability") or {}).get("parameters") or {}
        self.table.setRowCount(len(params))
        for i, (n, p) in enumerate(params.items()):
            unit, sc = display_unit(n)
            v, s = _num(p.get("value")), _num(p.get("std"))
            ok, why = ident.status(n)
            cells = [n, f"{v * sc:.4g} ± {s * sc:.2g} {unit}", f"{100 * s / abs(v):.2g} %" if v and math.isfinite(v) else "—",
                     f"{_num(nominal[n]) * sc:.4g}" if n in nominal else "—", "yes" if ok else "no"]
            for j, c in enumerate(cells):
                item = QTableWidgetItem(c)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                if j == 4 and not ok:
                    item.setToolTip(why)
                self.table.setItem(i, j, item)
        self.show_pairing(ident.pairing)
        self.budget_box.show_budget(ident.budget, list(params), ident.budget_error)
        has_budget = self.budget_table.rowCount() > 0
        self.lower_tabs.setCurrentWidget(self.budget_box if has_budget or not ident.multi_start
                                         else self.multi_plot)
        res = out.get("residual") or {}
        rs = ", ".join(f"{k} {v:.2e}" for k, v in res.items() if isinstance(v, (int, float)))
        self.summary.setText(f"data {ident.data_set} · method {out.get('method', '?')} · "
                             f"converged {ident.converged} · residual {rs or '—'}")
        # convergence history
        self.history_plot.clear()
        hist = out.get("history") or []
        it = [h.get("iteration", i) for i, h in enumerate(hist) if isinstance(h.get("cost"), (int, float))]
        cost = [max(float(h["cost"]), 1e-30) for h in hist if isinstance(h.get("cost"), (int, float))]
        if not cost:
            empty_note(self.history_plot, "no convergence history in this result")
        if cost:
            # a staged fit restarts its iteration count: one line per stage, not a jump back
            conn = np.r_[np.diff(np.asarray(it, float)) > 0, False]
            self.history_plot.plot(it, cost, pen=pg.mkPen("#1f77b4", width=2), symbol="o", symbolSize=6,
                                   symbolBrush="#1f77b4", connect=conn)
        # multi-start scatter
        self.multi_plot.clear()
        runs = list(ident.multi_start)
        names = list(params)
        if not runs:
            self.multi_plot.setXRange(0, 1)
            self.multi_plot.setYRange(0, 2)
            empty_note(self.multi_plot, "no multi-start study in this result (set 'multi-start runs' > 0)")
        if runs:
            self.multi_plot.enableAutoRange()
            idx = np.arange(1, len(runs) + 1)
            for k, n in enumerate(names):
                nom = _num(nominal.get(n, params[n].get("value")))
                vals = np.array([_num((r.get("values") or {}).get(n)) for r in runs]) / nom
                starts = np.array([_num((r.get("start") or {}).get(n)) for r in runs]) / nom
                c = COLORS[k % len(COLORS)]
                self.multi_plot.plot(idx, starts, pen=None, symbol="x", symbolSize=7, symbolPen=pg.mkPen(c),
                                     symbolBrush=None, name="starts (×, same colours)" if k == 0 else None)
                self.multi_plot.plot(idx, vals, pen=None, symbol=SYMBOLS[k % len(SYMBOLS)], symbolSize=9,
                                     symbolBrush=c, symbolPen=None, name=f"{n} identified")
        # identifiability
        self.ident_plot.clear()
        blocks = (out.get("identifiability") or {}).get("blocks") or {}
        ax = self.ident_plot.getAxis("bottom")
        ax.enableAutoSIPrefix(False)      # category ticks: no "(x0.001)" scale on a narrow range
        ax.setTicks([[(i, n) for i, n in enumerate(names)]])
        thr = (out.get("identifiability") or {}).get("rel_threshold")
        for k, (bname, b) in enumerate(blocks.items()):
            rs_ = b.get("rel_std") or {}
            y = np.array([max(_num(rs_.get(n)), 1e-12) for n in names])
            x = np.arange(len(names)) + 0.12 * (k - (len(blocks) - 1) / 2)
            c = COLORS[k % len(COLORS)]
            ok = np.isfinite(y)    # a constant without a rel_std is left out, not drawn as NaN
            if ok.any():
                self.ident_plot.plot(x[ok], y[ok], pen=None, symbol=SYMBOLS[k % len(SYMBOLS)], symbolSize=9,
                                     symbolBrush=c, symbolPen=None, name=f"{bname} alone")
        comb = np.array([max(_num((idp.get(n) or {}).get("rel_std")), 1e-12) for n in names])
        ok = np.isfinite(comb)
        if ok.any():
            self.ident_plot.plot(np.arange(len(names))[ok], comb[ok], pen=None, symbol="star", symbolSize=12,
                                 symbolBrush="k", name="all data")
        if isinstance(thr, (int, float)) and names:
            self.ident_plot.addItem(pg.InfiniteLine(math.log10(thr), angle=0,
                                                    pen=pg.mkPen("#d62728", style=Qt.DashLine)))

    def show_pairing(self, pairs) -> None:
        """The pairing table of a result (hidden when it has none)."""
        pairs = [p for p in pairs if isinstance(p, dict)] if isinstance(pairs, list) else []
        self.pairing_table.setVisible(bool(pairs))
        self.pairing_table.setRowCount(len(pairs))
        for i, p in enumerate(pairs):
            meas, pred = _num(p.get("measured_hz")), _num(p.get("predicted_hz"))
            diff = ("predicted mode without a peak" if not math.isfinite(meas) else
                    "peak without a mode" if not math.isfinite(pred) else f"{100 * (pred - meas) / meas:+.2f} %")
            cells = ["—" if p.get("peak") is None else str(p.get("peak")),
                     "—" if not math.isfinite(meas) else f"{meas:.3f}",
                     "—" if p.get("mode_index") is None else str(p.get("mode_index")),
                     str(p.get("family") or "—"), "—" if not math.isfinite(pred) else f"{pred:.3f}", diff]
            for j, c in enumerate(cells):
                item = QTableWidgetItem(c)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                self.pairing_table.setItem(i, j, item)

    def _specimen_nominal(self) -> dict:
        """Nominal constants of the specimen of the features (a CLI result stores none)."""
        doc = self.features()
        if not doc:
            return {}
        try:
            spec = self.main.specimen_for_features(doc)
            return dict(next(iter(spec.laminate.materials.values())).params())
        except (UserError, StopIteration, AttributeError, TypeError):
            return {}

    # -- session state ----------------------------------------------------------------------
    def state(self) -> dict:
        return {"data": self.data_choice(), "params": list(self.chosen_params()),
                "method": self.method_combo.currentText(), "starts": int(self.starts_spin.value()),
                "start_values": self.start_edit.text()}

    def restore(self, st: dict) -> None:
        if st.get("data") in self.data_radios:
            self.data_radios[st["data"]].setChecked(True)
        if "params" in st:
            self._pending_params = list(st["params"])
            for n, cb in self.param_checks.items():
                cb.setChecked(n in st["params"])
        if st.get("method"):
            self.method_combo.setCurrentText(st["method"])
        self.start_edit.setText(st.get("start_values", ""))
        if "starts" in st:
            self.starts_spin.setValue(int(st["starts"]))
