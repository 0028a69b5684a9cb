"""Workflow: the raw records of a run -> measured features (CONTRACT section 2).

``analyze_store(store)`` reads the hammer and wave shots of a ``RunStore``,
picks the resonances (``engine.modal``) and measures the A0 (and, where it
can be separated, S0) group velocity with the complex Morlet CWT
(``engine.waves``), and returns the features document with the picks and
curves behind it. ``store_analysis(run, analysis, out)`` (``labid.services.run_analysis``) writes
the features file and stores everything in the run file under ``/results/analysis``:

    analysis/features   {json: features text}
    analysis/spectrum   {frequencies_hz, indicator, kind}
    analysis/peaks      {frequency_hz, damping_ratio, sigma_hz, snr_db, confidence, manual}
    analysis/arrivals   {frequencies_hz, times_s} (A0 ridge of the first shot, far sensor)
    analysis/waves      {<mode>_<dir>: {frequency_hz, group_velocity_m_s, sigma_m_s, valid}}
    analysis/settings   {...}

The wave-feature method itself (band, path, gates, wavelet choice, S0, shots,
independent points) is ``engine.wavefeatures.pipeline``; ``labid.workflows.wave_analysis``
reads the wave records and the rig for it, and this module builds the features document
around its result. The settings are ``labid.workflows.analysis_settings.AnalysisSettings``
(re-exported here).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from drivers.protocol import Record
from engine import modal, waves
from engine.wavefeatures.pipeline import default_wavelet

from ..base import atomic
from .damping import damping_summary
from ..base.errors import UserError
from ..inputs.features import features_text, validate_features
from ..inputs.rig import Rig, rig_from_text
from ..store import RunStore
from ..inputs.specimen import specimen_from_dict
from .analysis_settings import AnalysisSettings, usable_shots
from .wave_analysis import wave_features

__all__ = ["AnalysisSettings", "Analysis", "modal_features", "wave_features", "analyze_store",
           "default_wavelet"]


@dataclass
class Analysis:
    """What ``analyze_store`` found: the features document and what is behind it."""

    features: dict
    spectrum: modal.Spectra | None = None
    peaks: tuple[modal.Peak, ...] = ()
    curves: dict[str, waves.GroupVelocity] = field(default_factory=dict)
    arrivals: dict[str, waves.Arrivals] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    wave_band_hz: tuple[float, float] | None = None
    dropped: dict[str, dict[str, int]] = field(default_factory=dict)
    no_velocity: str = ""


# --------------------------------------------------------------------------- modal
def modal_features(records: Sequence[Record], settings: AnalysisSettings = AnalysisSettings(),
                   notes: list[str] | None = None):
    """(modal features dict or None, Spectra, peaks) from hammer shots (all channels at once)."""
    notes = notes if notes is not None else []
    if not records:
        return None, None, ()
    r0 = records[0]
    accs = [c for c in r0.channels if c.kind == "accelerometer"]
    if not accs:
        accs = [c for c in r0.channels if c.kind != "force"]
    forces = [c for c in r0.channels if c.kind == "force"]
    names = [c.name for c in accs] + [c.name for c in forces[:1]]
    recs = usable_shots(records, names, notes, "hammer")
    if not recs or not accs:
        notes.append("no usable hammer shots" if accs else "hammer shots hold no response channel")
        return None, None, ()
    fs = r0.timing.rate_hz
    x = np.stack([np.stack([r.scaled(c.name) for c in accs]) for r in recs])
    force = np.stack([r.scaled(forces[0].name) for r in recs]) if forces else None
    pre = r0.timing.pretrigger
    try:
        spec = modal.spectra(x, fs, force, exp_tau_s=settings.exp_tau_s,
                             force_window_s=settings.force_window_s if force is not None else None,
                             pretrigger=pre, channels=[c.name for c in accs])
        fmax = settings.modal_fmax_hz or 0.4 * fs
        peaks = modal.pick_peaks(spec, fmin=settings.modal_fmin_hz, fmax=fmax, method=settings.indicator)
    except modal.ModalError as e:
        raise UserError(str(e), key="hammer shots") from None
    notes.append(f"modal: {len(peaks)} resonances from {len(recs)} hit(s), "
                 f"{'H1 (force recorded)' if spec.kind == 'frf' else 'auto-spectra'}, {len(accs)} channel(s)")
    if not peaks:
        return None, spec, peaks
    points = ([[float(c.x), float(c.y)] for c in accs]
              if all(c.x is not None and c.y is not None for c in accs) else None)
    return modal_table(peaks, points), spec, peaks


def modal_table(peaks: Sequence[modal.Peak], points: Sequence[Sequence[float]] | None = None) -> dict | None:
    """The features' ``modal`` table for ``peaks`` (None when there are none).

    sigma_hz has a floor of 1e-5 of the frequency. ``points``: the (x, y) of the
    channels in each peak's shape, in m; mode shapes are included when every
    peak has one value per point.
    """
    if not peaks:
        return None
    feats: dict[str, Any] = {
        "frequencies_hz": [float(p.frequency_hz) for p in peaks],
        "sigma_hz": [max(p.sigma_hz if math.isfinite(p.sigma_hz) else 0.0, 1e-5 * p.frequency_hz)
                     for p in peaks],
        "damping_ratio": [float(p.damping_ratio) for p in peaks],
        "confidence": [float(p.confidence) for p in peaks],
    }
    if points and all(len(p.shape) == len(points) for p in peaks):
        feats["mode_shapes"] = {"points": [list(map(float, xy)) for xy in points],
                                "values": [[float(v) for v in p.shape] for p in peaks]}
    return feats


# --------------------------------------------------------------------------- run
def _rig_section(rig: Rig, extra: dict) -> dict:
    out: dict[str, Any] = {}
    acc = [{"x": float(c.x), "y": float(c.y), "mass_kg": float(c.mass_kg)}
           for c in rig.accelerometers if c.x is not None and c.y is not None]
    if acc:
        out["accelerometers"] = acc
    if rig.supports:
        out["supports"] = [{"x": float(x), "y": float(y)} for x, y in rig.supports]
    out.update({k: float(v) for k, v in extra.items()})
    return out


def analyze_store(store: RunStore, settings: AnalysisSettings = AnalysisSettings()) -> Analysis:
    """Features of the shots in an open run store (specimen inline, from the run's config)."""
    src = str(store.path)
    spec_text, rig_text = store.specimen_toml(), store.rig_toml()
    if not spec_text or not rig_text:
        raise UserError("the run holds no specimen/rig configuration; expected a file written by labid acquire",
                        file=src, key="config")
    try:
        spec_doc = tomllib.loads(spec_text)
    except tomllib.TOMLDecodeError as e:
        raise UserError(f"stored specimen is not valid TOML ({e})", file=src, key="config/specimen_toml") from None
    specimen = specimen_from_dict(spec_doc, f"{src}#config/specimen_toml")
    rig = rig_from_text(rig_text, f"{src}#config/rig_toml")
    notes: list[str] = []
    hammer = store.shots("hammer")
    wave = store.shots("wave")
    if not hammer and not wave:
        raise UserError("the run holds no hammer or wave shots; expected shots recorded by labid acquire",
                        file=src, key="shots")
    mfeat, spectrum, peaks = modal_features(hammer, settings, notes)
    wfeat, curves, arrivals, extra, winfo = wave_features(wave, rig, specimen, settings, notes)
    doc: dict[str, Any] = {"specimen": spec_doc}
    if mfeat:
        doc["modal"] = mfeat
        doc["damping"] = damping_summary(mfeat, specimen)   # issue 16 (helper s6): loss factors
    if wfeat:
        doc["waves"] = wfeat
    doc["rig"] = _rig_section(rig, extra)
    doc["analysis"] = {"run": Path(src).name, "notes": notes}
    if winfo.get("dropped"):
        doc["analysis"]["dropped"] = winfo["dropped"]
    if winfo.get("mismatch"):
        # the data contradict the specimen file (issue 24): said once per mode and direction
        doc["analysis"]["nominal_mismatch"] = winfo["mismatch"]
    band = tuple(winfo["band_hz"]) if winfo.get("band_hz") else None
    return Analysis(validate_features(doc, src), spectrum, peaks, curves, arrivals, notes, band,
                    winfo.get("dropped", {}), winfo.get("empty", ""))


def analysis_results(an: Analysis, text: str, settings: AnalysisSettings) -> dict:
    """What ``/results/analysis`` holds for an analysis whose features JSON is ``text``."""
    res: dict[str, Any] = {"features": {"json": text}, "notes": list(an.notes) or ["(none)"]}
    if an.spectrum is not None:
        sp = an.spectrum
        fmax = settings.modal_fmax_hz or 0.4 * sp.fs_hz
        k = int(np.searchsorted(sp.frequencies_hz, fmax)) + 1
        res["spectrum"] = {"frequencies_hz": sp.frequencies_hz[:k],
                           "indicator": modal.indicator(sp, settings.indicator)[:k], "kind": sp.kind}
    if an.peaks:
        res["peaks"] = {k: np.array([getattr(p, k) for p in an.peaks], float)
                        for k in ("frequency_hz", "damping_ratio", "sigma_hz", "snr_db", "confidence", "manual")}
    if an.curves:
        res["waves"] = {k: {"frequency_hz": g.frequencies_hz, "group_velocity_m_s": g.velocity_m_s,
                            "sigma_m_s": g.sigma_m_s, "valid": g.valid.astype(np.uint8)}
                        for k, g in an.curves.items()}
        key = next((k for k in an.curves if k.startswith("A0")), next(iter(an.curves)))
        a = an.arrivals[key]
        res["arrivals"] = {"frequencies_hz": a.frequencies_hz[a.valid], "times_s": a.times_s[a.valid],
                           "sigma_s": a.sigma_s[a.valid], "channel_curve": key,
                           "wavelet": a.wavelet.name}
    s = asdict(settings)
    if an.wave_band_hz and not settings.wave_band_hz:
        s["wave_band_hz"] = an.wave_band_hz          # the band the analysis chose (the panel shows it)
    res["settings"] = {k: ("none" if v is None else (list(v) if isinstance(v, tuple) else v)) for k, v in s.items()}
    return res


def store_analysis(run: str | Path, an: Analysis, out: str | Path,
                   settings: AnalysisSettings = AnalysisSettings()) -> str:
    """Write the features JSON ``out`` and ``/results/analysis`` of ``run``; returns the JSON text."""
    text = features_text(an.features, str(out))
    atomic.write_text(out, text)              # temp + rename: never a half-written JSON
    with RunStore(run, "a") as st:
        st.write_group("analysis", analysis_results(an, text, settings))
    return text
