"""Modes tab: the averaged spectrum (summed normalised indicator) with the automatic
picks; click to add (or, on a pick, remove) a peak; model frequencies overlaid
after identification.

Picking is the analysis workflow's (``labid analyze``); editing is
``labid.services.toggle_peak`` on the same spectra; the edited picks go back
into the run's features (``services.save_picks``), which identification and
diagnosis read.
"""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QHBoxLayout, QHeaderView, QLabel, QPushButton, QTableWidget,
                               QTableWidgetItem, QVBoxLayout, QWidget)

from .. import services
from .common import Banner, empty_note, plot


class ModesView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.spec = None            # engine.modal.Spectra
        self.freqs = None           # (nf,) Hz
        self.indicator = None       # (nf,) curve shown
        self.peaks: tuple = ()      # engine.modal.Peak
        self._features: dict = {}   # the run's features: the sigma identification uses
        self.edited = False
        self.banner = Banner()
        self.analyze_btn = QPushButton("Analyze run")
        self.save_btn = QPushButton("Save picks")
        self.save_btn.setEnabled(False)
        self.hint = QLabel("click on the spectrum: add a peak there; click on a pick: remove it")
        self.plot = plot("averaged spectrum", ("frequency", "Hz"), ("indicator", ""))
        self.plot.setLogMode(y=True)
        self.plot.addLegend(offset=(-5, 5))
        self.plot.scene().sigMouseClicked.connect(self._clicked)
        self.table = QTableWidget(0, 6)
        self.table.setHorizontalHeaderLabels(["f (Hz)", "σ (Hz)", "ζ (%)", "conf. (M: manual)", "model (Hz)",
                                              "mode family"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.verticalHeader().setVisible(True)
        self.table.setMinimumWidth(470)
        self.table.setMaximumWidth(520)
        top = QHBoxLayout()
        top.addWidget(self.analyze_btn)
        top.addWidget(self.save_btn)
        top.addWidget(self.hint, 1)
        body = QHBoxLayout()
        body.addWidget(self.plot, 1)
        body.addWidget(self.table)
        lay = QVBoxLayout(self)
        lay.addWidget(self.banner)
        lay.addLayout(top)
        lay.addLayout(body, 1)
        self.analyze_btn.clicked.connect(self.main.analyze)
        self.save_btn.clicked.connect(self.save_picks)
        self.reload()

    # -- data ------------------------------------------------------------------------
    def reload(self) -> None:
        self.analyze_btn.setEnabled(self.main.run_path is not None)
        self._features = self.main.features() or {}
        if self.spec is None:
            res = self.main.read_results("analysis")
            sp = (res or {}).get("spectrum")
            if isinstance(sp, dict) and "frequencies_hz" in sp:
                self.freqs = np.asarray(sp["frequencies_hz"], float)
                self.indicator = np.asarray(sp["indicator"], float)
                self.peaks = services.stored_peaks(res)
                self.banner.info(f"stored analysis of this run: {len(self.peaks)} peaks "
                                 "(click to edit: the spectra are recomputed from the shots)")
            else:
                self.freqs = self.indicator = None
                self.peaks = ()
                self.banner.info("press 'Analyze run' to compute the spectra and pick the resonances"
                                 if self.main.run_path else "no run file yet: acquire first")
        self._draw()

    def set_modal(self, spec, peaks, indicator=None, edited: bool = False) -> None:
        """Show spectra ``spec`` (engine.modal.Spectra) and ``peaks``."""
        self.spec = spec
        self._features = self.main.features() or {}
        self.freqs = spec.frequencies_hz
        self.indicator = services.spectrum_indicator(spec) if indicator is None else np.asarray(indicator)
        self.peaks = tuple(peaks)
        self.edited = edited
        self.save_btn.setEnabled(edited)
        self.banner.info(f"{spec.n_hits} hits, {len(spec.channels)} channels "
                         f"({'H1' if spec.kind == 'frf' else 'auto-spectra'}), Δf = {spec.df:.3g} Hz · "
                         f"{len(self.peaks)} peaks")
        self._draw()

    def sigma_of(self, f_hz: float, fit_sigma: float) -> tuple[float, bool]:
        """The sigma (Hz) identification uses for the pick at ``f_hz``: the run's features
        file value (one source of truth), else the peak fit's own (unsaved pick), flagged."""
        m = self._features.get("modal") or {}
        fr = np.asarray(m.get("frequencies_hz") or [], float)
        sg = np.asarray(m.get("sigma_hz") or [], float)
        if fr.size and sg.size == fr.size:
            i = int(np.argmin(abs(fr - f_hz)))
            if abs(fr[i] - f_hz) <= 1e-9 * max(abs(f_hz), 1.0):
                return float(sg[i]), True
        return float(fit_sigma), False

    def families(self) -> dict[float, str]:
        """{measured Hz: 'FE mode k (m,n)'} from the identification's pairing, if it has one."""
        ident = self.main.read_results("identification")
        out = {}
        pairs = ident.get("pairing") if isinstance(ident, dict) else None
        for p in pairs if isinstance(pairs, list) else []:
            if isinstance(p, dict) and p.get("measured_hz") is not None:
                try:
                    out[float(p["measured_hz"])] = (f"{p.get('mode_index', '?')} {p.get('family') or ''}").strip()
                except (TypeError, ValueError):
                    continue
        return out

    def model_frequencies(self) -> np.ndarray:
        return services.model_frequencies(self.main.read_results("identification"))

    # -- editing ----------------------------------------------------------------------------
    def _clicked(self, ev) -> None:
        if self.freqs is None or ev.button() != Qt.LeftButton:
            return
        vb = self.plot.getPlotItem().vb
        if not vb.sceneBoundingRect().contains(ev.scenePos()):
            return
        f = float(vb.mapSceneToView(ev.scenePos()).x())
        # a click within 8 px of a pick removes it
        px = abs(vb.mapSceneToView(ev.scenePos() + pg.Point(8, 0)).x() - f)
        self.toggle_peak(f, tol_hz=max(px, 2 * (self.freqs[1] - self.freqs[0])))

    def toggle_peak(self, f_hz: float, tol_hz: float | None = None) -> str:
        """Remove the pick within ``tol_hz`` of ``f_hz``, else add one fitted there.
        Returns 'removed', 'added' or an error message."""
        if self.spec is None:
            if not self.main.run_path:
                return "no spectra"
            try:
                self.spec = services.spectra_of_run(self.main.run_path)
            except Exception as e:  # noqa: BLE001 - shown, not raised
                self.main.message(f"cannot recompute the spectra: {e}", error=True)
                return str(e)
            if self.spec is None:
                return "no spectra"
        try:
            self.peaks, what = services.toggle_peak(self.peaks, self.spec, f_hz, tol_hz)
        except ValueError as e:
            self.main.message(f"add peak: {e}", error=True)
            return str(e)
        self.edited = True
        self.save_btn.setEnabled(True)
        self.main.message(f"peak {what} near {f_hz:.2f} Hz; {len(self.peaks)} peaks (not saved yet)")
        self._draw()
        return what

    def save_picks(self) -> bool:
        ok = self.main.save_modal_picks(self.peaks)
        if ok:
            self.edited = False
            self.save_btn.setEnabled(False)
            self._features = self.main.features() or {}
            self._draw()
        return ok

    # -- drawing ----------------------------------------------------------------------------
    def _draw(self) -> None:
        self.plot.clear()
        if self.freqs is None:
            self.table.setRowCount(0)
            self.plot.setLogMode(y=False)
            self.plot.setXRange(0, 1)
            self.plot.setYRange(0, 1)
            empty_note(self.plot, "no data yet: " + ("press 'Analyze run'" if self.main.run_path
                                                     else "acquire hammer hits first"))
            return
        self.plot.setLogMode(y=True)
        f = self.freqs
        y = np.maximum(self.indicator, 1e-30)
        self.plot.plot(f[1:], y[1:], pen=pg.mkPen("#1f77b4", width=1), name="summed normalised spectrum")
        top = float(np.max(y[1:]))
        fp = np.array([p.frequency_hz for p in self.peaks])
        if fp.size:
            yp = np.interp(fp, f, y)
            manual = np.array([p.manual for p in self.peaks])
            if (~manual).any():
                self.plot.plot(fp[~manual], yp[~manual] * 1.6, pen=None, symbol="t", symbolSize=11,
                               symbolBrush="#d62728", name="automatic picks")
            if manual.any():
                self.plot.plot(fp[manual], yp[manual] * 1.6, pen=None, symbol="d", symbolSize=13,
                               symbolBrush="#ff9900", name="manual picks")
        model = self.model_frequencies()
        if model.size:
            self.plot.plot(model, np.full(model.size, top * 6), pen=None, symbol="t1", symbolSize=11,
                           symbolBrush="#2ca02c", name="model, identified constants")
            for fm in model:
                self.plot.addItem(pg.InfiniteLine(fm, angle=90, pen=pg.mkPen("#2ca02c", style=Qt.DotLine)))
        fmax = 1.25 * max(fp.max() if fp.size else f[-1] / 1.25, model.max() if model.size else 0)
        self.plot.setXRange(0, min(f[-1], fmax), padding=0.01)
        self.table.setRowCount(len(self.peaks))
        fam = self.families()
        for i, p in enumerate(self.peaks):
            m = model[np.argmin(abs(model - p.frequency_hz))] if model.size else None
            sig, stored = self.sigma_of(p.frequency_hz, p.sigma_hz)
            label = next((v for k, v in fam.items() if abs(k - p.frequency_hz) <= 1e-6 * p.frequency_hz), "—")
            cells = [f"{p.frequency_hz:.3f}", f"{sig:.3g}" + ("" if stored else " (fit, unsaved)"),
                     f"{100 * p.damping_ratio:.3g}",
                     f"{p.confidence:.2f}" + (" M" if p.manual else ""),
                     "—" if m is None else f"{m:.3f}", label]
            for j, c in enumerate(cells):
                item = QTableWidgetItem(c)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                self.table.setItem(i, j, item)

    # -- session state -------------------------------------------------------------------------
    def state(self) -> dict:
        return {"edited": bool(self.edited)}

    def restore(self, st: dict) -> None:
        self.spec = self.freqs = self.indicator = None
        self.peaks = ()
