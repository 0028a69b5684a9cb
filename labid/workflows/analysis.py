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
independent points) is ``engine.wavefeatures.pipeline``; this module reads the records
and the rig and builds the features document around its result.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from drivers.protocol import Record
from engine import modal, waves
from engine.waves import pair
from engine.wavefeatures import merge as waves_merge, sweep as waves_sweep
from engine.wavefeatures import pipeline as waves_pipeline
from engine.safe import ply_stiffness
from engine.wavefeatures.pipeline import WaveSettings, default_wavelet
from engine.wavefeatures.shots import more_shots_note
from engine.wavefeatures.predict import SourceModel

from ..base import atomic
from .damping import damping_summary
from ..base.errors import UserError
from ..inputs.features import features_text, validate_features
from ..inputs.rig import Rig, rig_from_text
from ..store import RunStore
from ..inputs.specimen import Specimen, specimen_from_dict

__all__ = ["AnalysisSettings", "Analysis", "modal_features", "wave_features", "analyze_store",
           "default_wavelet"]


@dataclass(frozen=True)
class AnalysisSettings:
    """Processing choices (None: automatic).

    modal_fmax_hz: top of the resonance search band (default 0.4 x rate).
    exp_tau_s: exponential window on the hammer records (None: none).
    force_window_s: force window length after the trigger (H1 only).
    indicator: 'sum' or 'cmif'.
    wavelet, wave_band_hz, n_wave_freqs, assign, min_wave_snr_db, gate_margin,
        leak_db, max_bias, min_wave_points, report_s0: the wave choices, with the defaults and
        meaning of ``engine.wavefeatures.pipeline.WaveSettings`` (wavelet, band_hz, n_freqs,
        assign, min_snr_db, gate_margin, leak_db, max_bias, min_points, report_s0).
    pair_residue_run: the run of the other mode of a collocated actuator pair (the same
        sensors): its copy in this run's records is measured and removed (``engine.waves.pair``).
    """

    modal_fmax_hz: float | None = None
    modal_fmin_hz: float = 5.0
    exp_tau_s: float | None = None
    force_window_s: float = 0.005
    indicator: str = "sum"
    wavelet: tuple[float, float] | None = WaveSettings.wavelet
    wave_band_hz: tuple[float, float] | None = WaveSettings.band_hz
    n_wave_freqs: int = WaveSettings.n_freqs
    assign: str = WaveSettings.assign
    min_wave_snr_db: float = WaveSettings.min_snr_db
    gate_margin: float = WaveSettings.gate_margin
    leak_db: float = WaveSettings.leak_db
    max_bias: float = WaveSettings.max_bias
    min_wave_points: int = WaveSettings.min_points
    report_s0: bool = WaveSettings.report_s0
    pair_residue_run: str | None = None    # the other mode's run of a collocated actuator pair


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
def _usable(records: Sequence[Record], names: Sequence[str], notes: list[str], what: str) -> list[Record]:
    ok = [r for r in records if not any(r.overload.get(n, False) for n in names)]
    if len(ok) < len(records):
        notes.append(f"{len(records) - len(ok)} overloaded {what} shot(s) left out")
    return ok


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
    recs = _usable(records, names, notes, "hammer")
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


# --------------------------------------------------------------------------- waves
def _sensor_xy(rig: Rig, name: str, rec: Record) -> tuple[float, float] | None:
    c = rec.channel(name)
    if c.x is not None and c.y is not None:
        return float(c.x), float(c.y)
    ws = rig.wave_sensor(name)
    if ws is None:
        return None
    a = math.radians(ws.direction_deg)
    return rig.wave_source.x + ws.distance_m * math.cos(a), rig.wave_source.y + ws.distance_m * math.sin(a)


def _wave_settings(settings: AnalysisSettings) -> WaveSettings:
    """The wave part of the analysis settings, for ``engine.wavefeatures.pipeline``."""
    return WaveSettings(wavelet=settings.wavelet, band_hz=settings.wave_band_hz, n_freqs=settings.n_wave_freqs,
                        assign=settings.assign, min_snr_db=settings.min_wave_snr_db,
                        gate_margin=settings.gate_margin, leak_db=settings.leak_db, max_bias=settings.max_bias,
                        min_points=settings.min_wave_points, report_s0=settings.report_s0)


def source_model(src) -> SourceModel:
    """What the analysis knows of a rig's wave source (``labid.inputs.rig.Source``)."""
    if src.kind in ("tone_burst", "pzt"):
        b = src.burst
        kw = dict(duration_s=b.duration_s, frequency_hz=b.frequency_hz, cycles=b.cycles, window=b.window)
        if src.kind == "pzt":
            faces = ((("top", 1.0), ("bottom", 1.0 if src.pair == "symmetric" else -1.0)) if src.pair
                     else ((src.face, 1.0),))
            return SourceModel("pzt", load="pin", radius_m=src.diameter_m / 2, faces=faces, electrical=True, **kw)
        return SourceModel("tone_burst", electrical=True, **kw)
    if src.kind == "hammer":
        return SourceModel("hammer", duration_s=src.contact_s)
    if getattr(src, "break_on", "face") == "edge":      # an in-plane force at mid-thickness: S modes
        return SourceModel("pencil", duration_s=src.rise_s, load="inplane", faces=(("top", 0.5), ("bottom", 0.5)))
    return SourceModel("pencil", duration_s=src.rise_s)


def _source_channel(rig: Rig, r0: Record):
    """The channel recording the wave source: the rig's ``wave_source.channel``, else the
    first force channel of the wave records."""
    names = [c.name for c in r0.channels]
    if rig.wave_source is not None and rig.wave_source.channel in names:
        return r0.channel(rig.wave_source.channel)
    return next((c for c in r0.channels if c.kind == "force"), None)


def _sweep_groups(records: Sequence[Record], rig: Rig) -> list[tuple[float | None, list[Record]]]:
    """The wave shots by the centre frequency of their burst (a sweep: the shots' meta
    'burst_frequency_hz'); one group (None) when the shots are not a sweep."""
    groups: dict = {}
    for r in records:
        f = (r.meta or {}).get("burst_frequency_hz")
        groups.setdefault(None if f is None else float(f), []).append(r)
    if len(groups) == 1 and None in groups:
        return [(None, list(records))]
    return sorted(groups.items(), key=lambda kv: (kv[0] is None, kv[0] or 0.0))


def wave_features(records: Sequence[Record], rig: Rig, specimen: Specimen,
                  settings: AnalysisSettings = AnalysisSettings(), notes: list[str] | None = None):
    """(list of wave curve dicts, curves, arrivals, extra rig info, info) from wave shots;
    a tone-burst sweep (shots at several centre frequencies) is measured per centre
    frequency and merged into one curve per mode and direction (``merge_runs``: each point
    keeps its own sigma; points of two bursts at one frequency are averaged, their sigma
    not below half their difference). See ``_wave_features_one``."""
    notes = notes if notes is not None else []
    groups = _sweep_groups(records, rig)
    if len(groups) == 1:
        out = _wave_features_one(records, rig, specimen, settings, notes)
        notes.extend(h for w in out[0] if (h := more_shots_note(f"{w['mode']} along {w['direction_deg']:g} deg", [
            (f, s / v, len(records), [])
            for f, v, s in zip(w["frequency_hz"], w["group_velocity_m_s"], w["sigma_m_s"])])))
        return out
    src = rig.wave_source
    parts = []
    for f, recs in groups:
        rig_f = rig if f is None or src is None or src.burst is None else \
            replace(rig, wave_source=replace(src, burst=src.burst.at(f)))
        sub: list[str] = []
        parts.append((f, _wave_features_one(recs, rig_f, specimen, settings, sub)))
        notes.extend(f"burst {f / 1e3:.4g} kHz: {n}" if f else n for n in sub)
    return _merge_sweep(parts, notes, {f: len(recs) for f, recs in groups})


def _merge_sweep(parts, notes: list[str], shots: dict | None = None):
    """The curves of the sweep's bursts merged per mode and direction (``wave_features``);
    ``shots``: the shots per burst, for the note on points whose sigma exceeds 1 %."""
    by_key: dict = {}
    curves, arrivals, extra, dropped, mismatch = {}, {}, {}, {}, {}
    lo, hi = np.inf, -np.inf
    odd = waves_sweep.odd_bursts(waves_sweep.survey_ratios(parts))   # one plate: the bursts agree
    notes.extend(waves_sweep.odd_note(k, v, parts) for k, v in odd.items())
    for f, (feats, cv, arr, ex, info) in parts:
        tag = f"_{f / 1e3:.4g}kHz" if f else ""
        for w in (w for w in feats if (f, w["mode"], w["direction_deg"]) not in odd):
            by_key.setdefault((w["mode"], w["direction_deg"]), []).append((f, w))
        for k, g in cv.items():
            best = curves.get(k)
            if best is None or g.valid.sum() > best.valid.sum():
                if best is not None:
                    curves[k + "_other" + tag] = best
                curves[k], arrivals[k] = g, arr[k]
            else:
                curves[k + tag] = g
        extra = extra or ex
        for k, d in info.get("dropped", {}).items():
            tot = dropped.setdefault(k, {})
            for r, n in d.items():
                tot[r] = tot.get(r, 0) + n
        for m in (m for m in info.get("mismatch", []) if (f, m["mode"], m["direction_deg"]) not in odd):
            mismatch.setdefault((m["mode"], m["direction_deg"]), m)
        if info.get("band_hz"):
            lo, hi = min(lo, info["band_hz"][0]), max(hi, info["band_hz"][1])
    out = []
    for (mode, direction), fws in sorted(by_key.items()):
        bursts, ws = [f for f, _ in fws], [w for _, w in fws]
        runs, drop = [], {}
        for w in ws:
            for r, n in w.get("dropped", {}).items():
                drop[r] = drop.get(r, 0) + n
        F, V, S, N = waves_merge.merge_runs([(np.array(w["frequency_hz"]), np.array(w["group_velocity_m_s"]),
                                              np.array(w["sigma_m_s"])) for w in ws], runs_out=runs, dropped_out=drop)
        out.append({"mode": mode, "direction_deg": float(direction), "frequency_hz": [float(x) for x in F],
                    "group_velocity_m_s": [float(x) for x in V], "sigma_m_s": [float(x) for x in S],
                    "dropped": drop})
        both = int(np.sum(N > 1))
        notes.append(f"{mode} along {direction:g} deg: {F.size} points merged from {len(ws)} burst(s) "
                     f"{F.min() / 1e3:.3g}-{F.max() / 1e3:.3g} kHz, each with its own sigma"
                     + (f"; {both} of them combine {int(N[N > 1].sum())} points of different bursts closer "
                        "than the bursts' frequency resolution" if both else ""))
        hint = more_shots_note(f"{mode} along {direction:g} deg", [
            (f, s / v, min((shots or {}).get(bursts[r], 0) for r in rr), [bursts[r] for r in rr])
            for f, v, s, rr in zip(F, V, S, runs)])
        if hint:
            notes.append(hint)
    info = {"dropped": dropped, "mismatch": list(mismatch.values())}
    if np.isfinite(lo):
        info["band_hz"] = [float(lo), float(hi)]
    return out, curves, arrivals, extra, info


def _wave_features_one(records: Sequence[Record], rig: Rig, specimen: Specimen,
                       settings: AnalysisSettings = AnalysisSettings(), notes: list[str] | None = None):
    """(list of wave curve dicts, curves, arrivals, extra rig info, info) from wave shots;
    info: the band used ('band_hz'), the drop counts per curve ('dropped'), or why there
    is no velocity ('empty').

    The records, the rig's wave sensors, its source and the specimen go through the
    wave-feature method of ``engine.wavefeatures.pipeline`` (band, packets, picks, checks, shots
    and independent points are described there); overloaded shots are left out here.
    """
    notes = notes if notes is not None else []
    if not records:
        return [], {}, {}, {}, {}
    r0 = records[0]
    fs = r0.timing.rate_hz
    pre = r0.timing.pretrigger
    ws_settings = _wave_settings(settings)
    sensors = [c for c in r0.channels if rig.wave_sensor(c.name) is not None]
    force = _source_channel(rig, r0)
    source = source_model(rig.wave_source) if rig.wave_source is not None else SourceModel()
    far = max(sensors, key=lambda c: rig.wave_sensor(c.name).distance_m) if sensors else None
    # the far sensor's record from the first possible arrival on: the direct packets; triggered
    # on a wave sensor, the onset lies its travel time before the trigger (issue 24, session 25)
    rec_far = None
    if far is not None:
        c_max = _fastest_bulk(specimen)
        r_trig = rig.wave_sensor(r0.trigger.channel) if r0.trigger is not None else None
        r_trig = r_trig.distance_m if r_trig is not None else 0.0
        k0 = pre + int(max(rig.wave_sensor(far.name).distance_m - r_trig, 0.0) / c_max * fs)
        rec_far = r0.scaled(far.name)[min(k0, r0.timing.samples - 16):]
    try:
        band = waves_pipeline.analysis_band(
            specimen.laminate, fs, ws_settings,
            r0.scaled(force.name) if force is not None and force.kind == "force" else None, pre,
            source=source, record=rec_far,
            noise=r0.scaled(far.name)[:int(0.8 * pre)] if far is not None and pre >= 80 else None)
    except waves.WaveError as e:
        raise UserError(str(e), key="wave band") from None
    notes.extend(band.notes)
    if not sensors:
        notes.append("wave shots hold no sensor with a distance (rig: distance_m): no velocities")
        return [], {}, {}, {}, {}
    if band.empty:
        notes.append(band.empty)
        return [], {}, {}, {}, {"empty": band.empty}
    freqs = band.freqs
    names = [c.name for c in sensors] + ([force.name] if force else [])
    recs = _usable(records, names, notes, "wave")
    if not recs:
        return [], {}, {}, {}, {}
    trig = rig.wave_sensor(r0.trigger.channel) if r0.trigger is not None else None
    acq = rig.device("wave").acquisitions if rig.device("wave") is not None else ()
    if len(acq) > 1:
        notes.append(f"wave shots combine {len(acq)} acquisitions on a common trigger "
                     f"({r0.trigger.channel if r0.trigger else '?'}); delays across them are good to one "
                     "sample period")

    def sensor(c):
        ws = rig.wave_sensor(c.name)
        return waves_pipeline.Sensor(ws.channel, ws.distance_m, ws.direction_deg, ws.length_m,
                                     _sensor_xy(rig, ws.channel, r0), ws.face, ws.highpass_hz,
                                     ws.resonance_hz, ws.resonance_q)

    setup = waves_pipeline.WaveSetup(
        laminate=specimen.laminate, plate_size_m=(specimen.length, specimen.width),
        source_xy=(rig.wave_source.x, rig.wave_source.y), fs_hz=fs, pretrigger=pre,
        sensors=tuple(sensor(c) for c in sensors),
        force_channel=force.name if force is not None else None,
        trigger_distance_m=trig.distance_m if trig is not None else None, source=source)
    shots = [{name: rec.scaled(name) for name in names} for rec in recs]
    if settings.pair_residue_run:     # a collocated pair's run: the other mode's copy out (engine.waves.pair)
        with RunStore(settings.pair_residue_run, "r") as other:
            others = [{c.name: r.scaled(c.name) for c in r.channels if c.name in names} for r in other.shots("wave")]
        rays: dict = {}
        for c in sorted(sensors, key=lambda c: rig.wave_sensor(c.name).distance_m):
            rays.setdefault(round(rig.wave_sensor(c.name).direction_deg, 6), []).append(c.name)
        shots, pn = pair.clean_shots(shots, others, list(rays.values()), fs, (freqs[0], freqs[-1]), pre / fs)
        notes.extend(pn)
    res = waves_pipeline.measure_waves(setup, shots, freqs, ws_settings)
    notes.extend(res.notes)
    out = [{"mode": c.mode, "direction_deg": float(c.direction_deg),
            "frequency_hz": [float(f) for f in c.frequency_hz],
            "group_velocity_m_s": [float(v) for v in c.group_velocity_m_s],
            "sigma_m_s": [float(s) for s in c.sigma_m_s],
            "dropped": {k: int(v) for k, v in c.dropped.items()}} for c in res.features]
    extra: dict[str, Any] = {}
    if res.wave_path_m is not None:
        extra["wave_path_m"] = res.wave_path_m
        extra["sensor_length_m"] = res.sensor_length_m
    info = {"band_hz": [float(freqs[0]), float(freqs[-1])], "dropped": {k: dict(v) for k, v in res.dropped.items()},
            "mismatch": [dict(m) for m in res.mismatch], "survey": [dict(m) for m in res.survey]}
    return out, dict(res.curves), dict(res.arrivals), extra, info


def _fastest_bulk(specimen: Specimen) -> float:
    """1.5 x the fastest bulk wave speed of the specimen's plies (m/s): nothing arrives sooner, even
    on a plate whose moduli are up to 2.25 x the specimen file's."""
    lam = specimen.laminate
    return 1.5 * max(float(np.sqrt(np.max(np.diag(C)[:3]) / p.material.density))
                     for p, C in zip(lam.plies, ply_stiffness(lam, 0.0)))


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
