"""The modal picks of an analysed run, as the panel edits them: the part of the ``labid.services``
facade (front-ends import these names from there) that reads the stored peaks and settings,
recomputes the spectra the picks were made on, adds or removes a pick and stores the edited
features (``save_picks``). ``features_path``: where a run's features file goes by default.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from drivers.protocol import Record
from engine import modal

from .base import atomic
from .base.errors import UserError
from .inputs.features import features_text, specimen_of
from .store import RunStore
from .workflows.analysis import AnalysisSettings, modal_features, modal_table
from .workflows.damping import damping_summary

__all__ = ["features_path", "stored_peaks", "save_picks", "spectra_of_run", "stored_settings", "analysed_spectra",
           "spectrum_indicator", "toggle_peak"]


def features_path(run: str | Path) -> Path:
    """Where the features of ``run`` are written by default: ``RUN.features.json`` beside it."""
    r = Path(run)
    return r.with_name(r.stem + ".features.json")


def stored_peaks(res: Mapping | None) -> tuple[modal.Peak, ...]:
    """The peaks of a stored ``/results/analysis`` group (``read_result(run, 'analysis')``)."""
    pk = (res or {}).get("peaks")
    if not isinstance(pk, dict) or "frequency_hz" not in pk:
        return ()
    n = len(np.atleast_1d(pk["frequency_hz"]))
    col = {k: np.atleast_1d(np.asarray(pk[k], float)) for k in pk}
    return tuple(modal.Peak(float(col["frequency_hz"][i]), float(col["damping_ratio"][i]),
                            float(col["sigma_hz"][i]), float(col["snr_db"][i]), float(col["confidence"][i]),
                            (), bool(col["manual"][i]))
                 for i in range(n))


def save_picks(run: str | Path, peaks: Sequence[modal.Peak]) -> dict:
    """Replace the run's modal features (features file and stored peaks) by ``peaks``;
    returns the features. ValueError if the run has not been analysed."""
    with RunStore(run, "r") as st:
        try:
            res = st.read_group("analysis")
        except KeyError:
            raise ValueError("the run has not been analysed yet") from None
    doc = json.loads(res["features"]["json"])
    ms = (doc.get("modal") or {}).get("mode_shapes")
    modal_sec = modal_table(peaks, ms["points"] if ms else None)
    out = features_path(run)
    if modal_sec is None:
        doc.pop("modal", None)
        doc.pop("damping", None)
    else:
        doc["modal"] = modal_sec
        try:  # the loss factors follow the edited picks (labels need the specimen)
            spec = specimen_of(doc, out.parent, str(out))
        except UserError:
            spec = None
        doc["damping"] = damping_summary(modal_sec, spec)
    notes = doc.setdefault("analysis", {}).setdefault("notes", [])
    notes.append(f"modal picks edited by hand in the panel ({len(peaks)} peaks)")
    text = features_text(doc, str(out))
    atomic.write_text(out, text)
    res["features"] = {"json": text}
    if peaks:
        res["peaks"] = {k: np.array([getattr(p, k) for p in peaks], float)
                        for k in ("frequency_hz", "damping_ratio", "sigma_hz", "snr_db", "confidence", "manual")}
    else:
        res.pop("peaks", None)
    with RunStore(run, "a") as st:
        st.write_group("analysis", res)
    return doc


def spectra_of_run(run: str | Path) -> modal.Spectra | None:
    """Spectra of the run's hammer shots, as the analysis computes them (for editing picks)."""
    with RunStore(run, "r") as st:
        recs = st.shots("hammer")
    _, spec, _ = modal_features(recs, AnalysisSettings())
    return spec


def stored_settings(analysis: Mapping | None) -> AnalysisSettings:
    """The modal settings a run was analysed with (its stored ``/results/analysis``; defaults
    for what is not stored)."""
    s = (analysis or {}).get("settings") or {}
    kw: dict[str, Any] = {}
    for k in ("modal_fmax_hz", "modal_fmin_hz", "exp_tau_s", "force_window_s", "indicator"):
        v = s.get(k)
        if v is None or v == "none":
            continue
        kw[k] = str(v) if k == "indicator" else float(v)
    return AnalysisSettings(**kw)


def analysed_spectra(hammer: Sequence[Record], analysis: Mapping | None) -> modal.Spectra | None:
    """The spectra (H1 with a force) of hammer records as the run's stored analysis computed them."""
    return modal_features(hammer, stored_settings(analysis), [])[1]


def spectrum_indicator(spec: modal.Spectra) -> np.ndarray:
    """The summed normalised spectrum the picks are made on (``engine.modal.indicator``)."""
    return modal.indicator(spec)


def toggle_peak(peaks: Sequence[modal.Peak], spec: modal.Spectra, f_hz: float,
                tol_hz: float | None = None) -> tuple[tuple[modal.Peak, ...], str]:
    """Remove the pick within ``tol_hz`` (default 2 bins) of ``f_hz``, else fit one there.
    Returns (new peaks, 'removed' or 'added'); ValueError if no peak can be fitted."""
    tol = 2 * spec.df if tol_hz is None else tol_hz
    if any(abs(p.frequency_hz - f_hz) <= tol for p in peaks):
        return modal.remove_peak(peaks, f_hz, tol), "removed"
    return modal.add_peak(peaks, spec, f_hz), "added"
