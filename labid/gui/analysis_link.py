"""How the panel calls the analysis workflow (``labid.analysis``, as ``labid analyze``).

``analysis_job`` runs ``analyze_store`` on the run file and stores the result the
way ``analyze_run`` does (``/results/analysis`` and ``<run>.features.json``),
keeping the ``Analysis`` object (spectra, peaks, arrivals, curves) for the
views. ``save_picks`` writes hand-edited peaks back into the run's features.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

#: names the analysis module must define for the panel to use it
ANALYSIS_API: tuple[str, ...] = ("analyze_store", "modal_features", "AnalysisSettings", "store_analysis",
                                 "modal_table")


def features_path(run: str) -> Path:
    r = Path(run)
    return r.with_name(r.stem + ".features.json")


def analysis_job(link, run: str, temperature_c, progress, should_stop):
    """Background part: analyse the run file, store the results; returns the Analysis."""
    from ..store import RunStore
    settings = link.AnalysisSettings()
    with RunStore(run, "r") as st:
        an = link.analyze_store(st, settings)
    if temperature_c is not None and math.isfinite(temperature_c):
        an.features.setdefault("rig", {}).setdefault("temperature_c", float(temperature_c))
    link.store_analysis(run, an, features_path(run), settings)
    return an


def show_analysis(main, an) -> None:
    main.modes.set_modal(an.spectrum, an.peaks) if an.spectrum is not None else main.modes.reload()
    main.waves.set_analysis(an)


def analysis_summary(an) -> str:
    f = an.features
    n_modes = len((f.get("modal") or {}).get("frequencies_hz", []))
    n_w = sum(len(w.get("frequency_hz", [])) for w in f.get("waves") or [])
    return f"{n_modes} resonances, {n_w} group-velocity points"


def modal_section(link, peaks, old: dict | None) -> dict | None:
    """The features' ``modal`` table for (edited) peaks, as the analysis writes it."""
    ms = (old or {}).get("mode_shapes")
    return link.modal_table(peaks, ms["points"] if ms else None)


def save_picks(link, run: str, peaks) -> dict:
    """Replace the run's modal features (and stored peaks) by ``peaks``; returns the features."""
    from ..features import features_text
    from ..store import RunStore
    with RunStore(run, "r") as st:
        try:
            res = st.read_group("analysis")
        except KeyError:
            raise ValueError("the run has not been analysed yet") from None
    doc = json.loads(res["features"]["json"])
    modal = modal_section(link, peaks, doc.get("modal"))
    if modal is None:
        doc.pop("modal", None)
    else:
        doc["modal"] = modal
    notes = doc.setdefault("analysis", {}).setdefault("notes", [])
    notes.append(f"modal picks edited by hand in the panel ({len(peaks)} peaks)")
    out = features_path(run)
    text = features_text(doc, str(out))
    out.write_text(text)
    res["features"] = {"json": text}
    if peaks:
        res["peaks"] = {k: np.array([getattr(p, k) for p in peaks], float)
                        for k in ("frequency_hz", "damping_ratio", "sigma_hz", "snr_db", "confidence", "manual")}
    else:
        res.pop("peaks", None)
    with RunStore(run, "a") as st:
        st.write_group("analysis", res)
    return doc


def spectra_of_run(link, run: str):
    """Spectra of the run's hammer shots (for editing picks after reopening a run)."""
    from ..store import RunStore
    with RunStore(run, "r") as st:
        recs = st.shots("hammer")
    _, spec, _ = link.modal_features(recs, link.AnalysisSettings())
    return spec


def stored_peaks(res: dict) -> tuple:
    """engine.modal.Peak objects from a stored ``analysis/peaks`` group."""
    from engine.modal import Peak
    pk = (res or {}).get("peaks")
    if not isinstance(pk, dict) or "frequency_hz" not in pk:
        return ()
    n = len(np.atleast_1d(pk["frequency_hz"]))
    col = {k: np.atleast_1d(np.asarray(pk[k], float)) for k in pk}
    return tuple(Peak(float(col["frequency_hz"][i]), float(col["damping_ratio"][i]), float(col["sigma_hz"][i]),
                      float(col["snr_db"][i]), float(col["confidence"][i]), (), bool(col["manual"][i]))
                 for i in range(n))
