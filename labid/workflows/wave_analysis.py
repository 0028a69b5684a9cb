"""Workflow: the wave shots of a run -> the features' guided-wave curves (CONTRACT section 2).

``wave_features(records, rig, specimen, settings)`` reads the wave records and the rig, runs the
wave-feature method of ``engine.wavefeatures.pipeline`` (band, packets, picks, checks, shots,
independent points) and returns the curve dicts of the features' ``waves`` table with what is
behind them; a tone-burst sweep is measured per burst and merged (``_merge_sweep``).
``labid.workflows.analysis`` builds the features document around it (split from there in
session 29; behaviour unchanged).
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from drivers.protocol import Record
from engine import waves
from engine.waves import pair
from engine.wavefeatures import merge as waves_merge, sweep as waves_sweep
from engine.wavefeatures import pipeline as waves_pipeline
from engine.safe import ply_stiffness
from engine.wavefeatures.pipeline import WaveSettings
from engine.wavefeatures.band import source_band
from engine.wavefeatures.noise import noise_level
from engine.wavefeatures.shots import more_shots_note, stack_shots
from engine.wavefeatures.predict import SourceModel

from ..base.errors import UserError
from ..inputs.rig import Rig
from ..inputs.specimen import Specimen
from ..store import RunStore
from .analysis_settings import AnalysisSettings, usable_shots

__all__ = ["wave_features", "source_model"]


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
        g, line = waves_merge.gross_points(F, V, S, f"{mode} along {direction:g} deg (merged)", dropped_out=drop)
        F, V, S, N, runs = F[~g], V[~g], S[~g], N[~g], [r for r, b in zip(runs, g) if not b]
        k, line2 = waves_merge.misfit_scale(F, V, S, f"{mode} along {direction:g} deg (merged)")
        S = k * S                           # the merged curve judged too (bursts' biases may disagree)
        notes += [x for x in (line, line2) if x]
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
    names = [c.name for c in sensors] + ([force.name] if force else [])
    # the band is judged on what is picked: the far sensor's first group of averaged shots
    # (``stack_shots``, as ``measure_waves`` groups the usable shots), not one raw shot, whose
    # noise is sqrt(group) x higher; not the mean of all shots either: a curve is picked per
    # group. From the first possible arrival on: the direct packets; triggered on a wave
    # sensor, the onset lies its travel time before the trigger (issue 24, session 25)
    rec_far = noise = None
    if far is not None:
        ok = usable_shots(records, names, [], "wave") or list(records)
        # aligned as measure_waves aligns them (not with a recorded source), in the source's band
        lo, hi = ws_settings.band_hz or source_band(specimen.laminate, fs, source, ws_settings.band_db, None, pre)[:2]
        x_far = stack_shots([{far.name: r.scaled(far.name)} for r in ok], ref=None if force else far.name,
                            band=(lo / fs, min(hi, 0.4 * fs) / fs))[0][0][far.name]
        c_max = _fastest_bulk(specimen)
        r_trig = rig.wave_sensor(r0.trigger.channel) if r0.trigger is not None else None
        r_trig = r_trig.distance_m if r_trig is not None else 0.0
        k0 = pre + int(max(rig.wave_sensor(far.name).distance_m - r_trig, 0.0) / c_max * fs)
        rec_far = x_far[min(k0, r0.timing.samples - 16):]
        level = noise_level(x_far, pre, fs) if pre >= 80 else None    # the picks' estimate
        noise = level[0] if level is not None else None
    try:
        band = waves_pipeline.analysis_band(
            specimen.laminate, fs, ws_settings,
            r0.scaled(force.name) if force is not None and force.kind == "force" else None, pre,
            source=source, record=rec_far, noise=noise)
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
    recs = usable_shots(records, names, notes, "wave")
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
