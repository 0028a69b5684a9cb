"""Workflow: the raw records of a run -> measured features (CONTRACT section 2).

``analyze_store(store)`` reads the hammer and wave shots of a ``RunStore``,
picks the resonances (``engine.modal``) and measures the A0 (and, where it
can be separated, S0) group velocity with the complex Morlet CWT
(``engine.waves``), and returns the features document with the picks and
curves behind it. ``analyze_run(path, out)`` also writes the features file
and stores everything in the run file under ``/results/analysis``:

    analysis/features   {json: features text}
    analysis/spectrum   {frequencies_hz, indicator, kind}
    analysis/peaks      {frequency_hz, damping_ratio, sigma_hz, snr_db, confidence, manual}
    analysis/arrivals   {frequencies_hz, times_s} (A0 ridge of the first shot, far sensor)
    analysis/waves      {<mode>_<dir>: {frequency_hz, group_velocity_m_s, sigma_m_s, valid}}
    analysis/settings   {...}

Wave geometry. The group velocity is measured between the source and a
sensor when the wave record holds the source's force channel (the paper's
hammer test: the force scalogram gives the source time per frequency), else
between the nearest and the farthest sensor on one propagation direction
(a pencil-lead break triggered on the first sensor: the source time is not
recorded). Gates come from the SAFE curves of the nominal specimen with a
wide margin, closed before the first edge echo.
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
from engine.laminate import Laminate

from .errors import UserError
from .features import features_text, validate_features
from .rig import Rig, rig_from_text
from .store import RunStore
from .specimen import Specimen, specimen_from_dict

__all__ = ["AnalysisSettings", "Analysis", "modal_features", "wave_features", "analyze_store",
           "analyze_run", "default_wavelet"]


@dataclass(frozen=True)
class AnalysisSettings:
    """Processing choices (None: automatic).

    modal_fmax_hz: top of the resonance search band (default 0.4 x rate).
    exp_tau_s: exponential window on the hammer records (None: none).
    force_window_s: force window length after the trigger (H1 only).
    indicator: 'sum' or 'cmif'.
    wavelet: (B, C) of the complex Morlet; default by specimen: (2, 1) for an
        isotropic plate, (2, 5) for a laminate (the paper's choices).
    wave_band_hz: (fmin, fmax) of the CWT grid; default (fmax / 20, fmax)
        with fmax = 50 kHz (isotropic) or 200 kHz (laminate), at most 0.4 x rate.
    n_wave_freqs: points of the CWT grid.
    assign: 'instantaneous' (reassigned, bias-corrected) or 'nominal' (the paper).
    min_wave_snr_db: reject arrivals weaker than this over the pre-trigger noise.
    gate_margin: relative velocity margin of the gates around the nominal SAFE curves.
    echo_margin: how much faster than nominal an edge echo may travel (it closes the gate).
    report_s0: put the S0 curve in the features too (it is always measured, with a wavelet
        of bandwidth B/4, and stored in the run): off by default; the A0 tail that biased
        it 1-7 % is gone (docs/wavelet-bias.md), but the short wavelet leaves about one
        independent point and the low end's sigma is still small by up to ~2.
    """

    modal_fmax_hz: float | None = None
    modal_fmin_hz: float = 5.0
    exp_tau_s: float | None = None
    force_window_s: float = 0.005
    indicator: str = "sum"
    wavelet: tuple[float, float] | None = None
    wave_band_hz: tuple[float, float] | None = None
    n_wave_freqs: int = 100
    assign: str = "instantaneous"
    min_wave_snr_db: float = 20.0
    gate_margin: float = 0.35
    echo_margin: float = 0.10
    min_wave_points: int = 5
    report_s0: bool = False


@dataclass
class Analysis:
    """What ``analyze_store`` found: the features document and what is behind it."""

    features: dict
    spectrum: modal.Spectra | None = None
    peaks: tuple[modal.Peak, ...] = ()
    curves: dict[str, waves.GroupVelocity] = field(default_factory=dict)
    arrivals: dict[str, waves.Arrivals] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def default_wavelet(laminate: Laminate) -> waves.Wavelet:
    """The paper's wavelet: cmor2-1 for an isotropic plate, cmor2-5 for a laminate."""
    iso = all(m.isotropic for m in laminate.materials.values()) and len(laminate.plies) == 1
    return waves.PAPER_ALUMINIUM if iso else waves.PAPER_CFRP


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


def _echo_path(src: tuple[float, float], dst: tuple[float, float], length: float, width: float) -> float:
    """Shortest source -> edge -> sensor path on a length x width plate (mirror images), m."""
    sx, sy = src
    x, y = dst
    images = [(-x, y), (2 * length - x, y), (x, -y), (x, 2 * width - y)]
    return min(math.hypot(ix - sx, iy - sy) for ix, iy in images)


def _noise_rms(x: np.ndarray, pre: int, fs: float, freqs: np.ndarray, wl: waves.Wavelet) -> np.ndarray | None:
    m = int(0.8 * pre)
    if m < 64:
        return None
    std = float(np.std(x[:m] - np.mean(x[:m])))
    if not std > 0:  # a noiseless (simulated) record: nothing to compare with
        return None
    return waves.white_noise_level(std, fs, freqs, wl)


def _combine(curves: list[waves.GroupVelocity]) -> waves.GroupVelocity:
    """Inverse-variance mean over shots, sigma scaled by the Birge ratio where shots disagree."""
    f = curves[0].frequencies_hz
    V = np.array([c.velocity_m_s for c in curves])
    S = np.array([c.sigma_m_s for c in curves])
    ok = np.isfinite(V) & np.isfinite(S) & (S > 0)
    w = np.where(ok, 1.0 / np.where(ok, S, 1.0) ** 2, 0.0)
    n = ok.sum(axis=0)
    sw = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(sw > 0, (w * np.where(ok, V, 0.0)).sum(axis=0) / sw, np.nan)
        s = np.where(sw > 0, 1.0 / np.sqrt(sw), np.nan)
        chi2 = (w * (np.where(ok, V, 0.0) - v) ** 2).sum(axis=0)
        birge = np.where(n > 1, np.sqrt(chi2 / np.maximum(n - 1, 1)), 1.0)
    s = s * np.maximum(birge, 1.0)
    valid = n > 0
    return waves.GroupVelocity(f, np.where(valid, v, np.nan), np.where(valid, s, np.nan), valid)


def wave_features(records: Sequence[Record], rig: Rig, specimen: Specimen,
                  settings: AnalysisSettings = AnalysisSettings(), notes: list[str] | None = None):
    """(list of wave curve dicts, curves, arrivals, extra rig info) from wave shots.

    Wavelet: ``settings.wavelet``, else the paper's for the material; if that
    one resolves fewer than half the frequencies of A0 (two sensors close to
    the source: A0 and S0 overlap within a long wavelet), cmor2-2 then
    cmor2-1 are tried and the best is kept (said in the notes). Each curve
    is also measured with a centre frequency 1.5 x lower (higher below
    C = 1); half the difference is added to sigma (systematic wavelet term).
    """
    from engine import safe
    notes = notes if notes is not None else []
    if not records:
        return [], {}, {}, {}
    r0 = records[0]
    fs = r0.timing.rate_hz
    pre = r0.timing.pretrigger
    lam = specimen.laminate
    wl0 = waves.Wavelet(*settings.wavelet) if settings.wavelet else default_wavelet(lam)
    if settings.wave_band_hz:
        fmin, fmax = settings.wave_band_hz
    else:
        fmax = min(50e3 if default_wavelet(lam) == waves.PAPER_ALUMINIUM else 200e3, 0.4 * fs)
        fmin = fmax / 20
    if not 0 < fmin < fmax < fs / 2:
        raise UserError(f"wave band {fmin:g}..{fmax:g} Hz: expected 0 < fmin < fmax < rate/2 = {fs / 2:g} Hz",
                        key="wave band")
    sensors = [c for c in r0.channels if rig.wave_sensor(c.name) is not None]
    force = next((c for c in r0.channels if c.kind == "force"), None)
    if force is not None and not settings.wave_band_hz:
        # a hammer's spectrum has zeros (half-sine: 1.5 / contact time): near and above the
        # first one the ridges are biased (the window straddles the zero; beyond it the
        # scalograms show the pulse's two edges, not its centre): docs/wavelet-bias.md
        fr = r0.scaled(force.name)
        spec_f = np.abs(np.fft.rfft(fr - np.median(fr[:max(pre, 1)]), 1 << 16))
        ff = np.fft.rfftfreq(1 << 16, 1.0 / fs)
        low = np.flatnonzero((spec_f < 10 ** (-10 / 20) * spec_f.max()) & (ff > ff[np.argmax(spec_f)]))
        if low.size and ff[low[0]] < fmax:
            fmax = max(float(ff[low[0]]), 2 * fmin)
            notes.append(f"wave band limited to {fmax / 1e3:.3g} kHz, where the source force spectrum "
                         "falls 10 dB below its peak (closer to its first zero the ridge is biased)")
    freqs = np.linspace(fmin, fmax, settings.n_wave_freqs)
    if not sensors:
        notes.append("wave shots hold no sensor with a distance (rig: distance_m): no velocities")
        return [], {}, {}, {}
    recs = _usable(records, [c.name for c in sensors] + ([force.name] if force else []), notes, "wave")
    if not recs:
        return [], {}, {}, {}
    by_dir: dict[float, list] = {}
    for c in sensors:
        ws = rig.wave_sensor(c.name)
        by_dir.setdefault(round(ws.direction_deg, 6), []).append(ws)
    src_xy = (rig.wave_source.x, rig.wave_source.y)
    out, curves, arrivals = [], {}, {}
    extra: dict[str, Any] = {}
    for direction, wss in sorted(by_dir.items()):
        wss = sorted(wss, key=lambda w: w.distance_m)
        far = wss[-1]
        near = None if force is not None or len(wss) < 2 else wss[0]
        if force is None and near is None:
            notes.append(f"direction {direction:g} deg: one sensor and no source force channel; "
                         "velocity from the trigger time (source assumed at t = 0)")
        cg = {m: np.asarray(safe.group_velocity(lam, freqs, m, direction), float) for m in ("A0", "S0")}
        cg_s0 = np.where(np.isfinite(cg["S0"]), cg["S0"], np.nanmax(cg["S0"]))
        # source time on the record axis: unknown when triggered on a sensor, between the
        # fastest A0 and the fastest S0 front reaching the trigger sensor
        t_early = t_late = 0.0
        if r0.trigger is not None:
            tw = rig.wave_sensor(r0.trigger.channel)
            if tw is not None:
                t_early = -tw.distance_m / float(np.nanmax(cg["A0"])) * 1.3
                t_late = -tw.distance_m / float(np.nanmax(cg_s0)) / 1.3

        def gates(ws, mode, wl):
            xy = _sensor_xy(rig, ws.channel, r0)
            echo = _echo_path(src_xy, xy, specimen.length, specimen.width) if xy else None
            ts = wl.time_std_s(freqs)
            kw = dict(reflection_m=echo, time_std_s=ts, echo_margin=settings.echo_margin)
            if mode == "A0":
                kw.update(cg_expected=cg["A0"], margin=settings.gate_margin, faster_cg=cg_s0)
            else:
                # A0 is the strong one under a normal force: keep S0 well clear of its arrival
                kw.update(cg_expected=cg_s0, margin=settings.gate_margin / 2, slower_cg=cg["A0"],
                          mode_clearance=3.0)
            lo, _ = waves.expected_gate(ws.distance_m, source_time_s=t_early, **kw)
            _, hi = waves.expected_gate(ws.distance_m, source_time_s=t_late, **kw)
            return lo, hi

        def measure(mode, wl, shots):
            shot_curves, first = [], None
            for rec in shots:
                def arr(name, ws):
                    x = rec.scaled(name)
                    W = waves.cwt(x, fs, freqs, wl)
                    a = waves.arrival_times(W, fs, freqs, wl, t0_index=pre,
                                            gate_s=gates(ws, mode, wl) if ws is not None else None,
                                            noise_rms=_noise_rms(x, pre, fs, freqs, wl),
                                            min_snr_db=settings.min_wave_snr_db)
                    # S0 (nearly flat below the knee): no curvature to correct; a cubic fitted
                    # to its noisy delays would only add its noise
                    return waves.correct_dispersion_bias(a) if settings.assign == "instantaneous" \
                        and mode == "A0" else a
                # S0 is flat below the knee: the nominal frequency is as good, and the
                # reassigned one of a short wavelet drifts with the source spectrum's slope
                assign = settings.assign if mode == "A0" else "nominal"
                a_far = arr(far.channel, far)
                if force is not None:
                    g = waves.group_velocity(a_far, far.distance_m, arr(force.name, None), assign=assign)
                elif near is not None:
                    g = waves.group_velocity(a_far, far.distance_m, arr(near.channel, near),
                                             near_distance_m=near.distance_m, assign=assign)
                else:
                    g = waves.group_velocity(a_far, far.distance_m, source_time_s=0.0, assign=assign)
                shot_curves.append(g)
                first = first or a_far
            return _combine(shot_curves), first

        wl = wl0
        if not settings.wavelet:
            tried = []
            for cand in (wl0, waves.Wavelet(2.0, 2.0), waves.PAPER_ALUMINIUM):
                if cand in [c for c, _ in tried]:
                    continue
                n_ok = int(measure("A0", cand, recs[:1])[0].valid.sum())
                tried.append((cand, n_ok))
                if n_ok >= 0.5 * freqs.size:
                    break
            wl = max(tried, key=lambda t: (t[1] >= 0.5 * freqs.size, -tried.index(t), t[1]))[0] \
                if any(n >= 0.5 * freqs.size for _, n in tried) else max(tried, key=lambda t: t[1])[0]
            if wl != wl0:
                notes.append(f"direction {direction:g} deg: {wl0.name} resolves too few A0 frequencies "
                             f"({dict((c.name, n) for c, n in tried)}); used {wl.name}")
        for mode in ("A0", "S0"):
            # S0 through a wavelet twice as short (B / 4): under a normal force S0 is ~100 x
            # weaker than A0 and the tail of A0 in a cmor2-C scalogram shifted its maximum
            # by several % (docs/wavelet-bias.md, "S0 next to a strong A0"); S0 is nearly
            # non-dispersive below the knee, so the coarser frequency resolution costs nothing
            wm = wl if mode == "A0" else waves.Wavelet(wl.bandwidth / 4, wl.center)
            gv, first_arr = measure(mode, wm, recs)
            # centre-frequency sweep (docs/wavelet-bias.md): the same records through a
            # wavelet 1.5 x shorter (longer if that would go below C = 2/3); half the
            # difference joins sigma as a systematic term
            c_alt = wm.center / 1.5 if wm.center / 1.5 >= 2 / 3 else wm.center * 1.5
            alt, _ = measure(mode, waves.Wavelet(wm.bandwidth, c_alt), recs)
            both = gv.valid & alt.valid
            if both.any():
                sys_term = np.where(both, 0.5 * np.abs(gv.velocity_m_s - alt.velocity_m_s), 0.0)
                gv = waves.GroupVelocity(gv.frequencies_hz, gv.velocity_m_s,
                                         np.hypot(gv.sigma_m_s, sys_term), gv.valid)
            key = f"{mode}_{direction:g}"
            if gv.valid.sum() < settings.min_wave_points:
                why: dict[str, int] = {}
                for r in (first_arr.reason if first_arr is not None else ()):
                    if r:
                        k = r.split(" (")[0].split(":")[0].split(" -")[0]
                        k = "SNR too low" if k.startswith("SNR") else k
                        why[k] = why.get(k, 0) + 1
                top = ", ".join(f"{k} x{n}" for k, n in sorted(why.items(), key=lambda t: -t[1])[:3])
                notes.append(f"{mode} along {direction:g} deg: {int(gv.valid.sum())} valid frequencies "
                             f"(< {settings.min_wave_points}); not reported (far sensor: {top}; an empty gate "
                             "means an edge echo or the other mode within the wavelet's reach)")
                continue
            curves[key] = gv
            arrivals[key] = first_arr
            ok = gv.valid
            if mode == "S0" and not settings.report_s0:
                notes.append(f"S0 along {direction:g} deg: {int(ok.sum())} frequencies measured and stored "
                             "in the run (analysis/waves), not put in the features (--with-s0)")
                continue
            # the features carry only points a wavelet resolution apart: neighbours on the
            # dense grid share their errors (the full curve stays in the run file)
            ok = waves.independent_points(freqs, ok, wm)
            out.append({"mode": mode, "direction_deg": float(direction),
                        "frequency_hz": [float(f) for f in freqs[ok]],
                        "group_velocity_m_s": [float(v) for v in gv.velocity_m_s[ok]],
                        "sigma_m_s": [float(s) for s in gv.sigma_m_s[ok]]})
            notes.append(f"{mode} along {direction:g} deg: {int(ok.sum())} independent frequencies "
                         f"{freqs[ok].min() / 1e3:.3g}-{freqs[ok].max() / 1e3:.3g} kHz from {len(recs)} shot(s), "
                         f"{wm.name}, {'source to sensor' if force is not None or near is None else 'two sensors'}")
        path = far.distance_m - (near.distance_m if near is not None else 0.0)
        extra.setdefault("wave_path_m", path)
        extra.setdefault("sensor_length_m", far.length_m)
    return out, curves, arrivals, extra


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
    wfeat, curves, arrivals, extra = wave_features(wave, rig, specimen, settings, notes)
    doc: dict[str, Any] = {"specimen": spec_doc}
    if mfeat:
        doc["modal"] = mfeat
    if wfeat:
        doc["waves"] = wfeat
    doc["rig"] = _rig_section(rig, extra)
    doc["analysis"] = {"run": Path(src).name, "notes": notes}
    return Analysis(validate_features(doc, src), spectrum, peaks, curves, arrivals, notes)


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
    res["settings"] = {k: ("none" if v is None else (list(v) if isinstance(v, tuple) else v)) for k, v in s.items()}
    return res


def analyze_run(run: str | Path, out: str | Path | None = None,
                settings: AnalysisSettings = AnalysisSettings()) -> dict:
    """Analyse a run file: write the features JSON (``out``, default
    ``<run>.features.json``) and store features, picks and curves in the run
    (``/results/analysis``). Returns the features document."""
    run = Path(run)
    out = Path(out) if out is not None else run.with_name(run.stem + ".features.json")
    with RunStore(run, "r") as st:
        an = analyze_store(st, settings)
    store_analysis(run, an, out, settings)
    return an.features


def store_analysis(run: str | Path, an: Analysis, out: str | Path,
                   settings: AnalysisSettings = AnalysisSettings()) -> str:
    """Write the features JSON ``out`` and ``/results/analysis`` of ``run``; returns the JSON text."""
    text = features_text(an.features, str(out))
    try:
        Path(out).write_text(text)
    except OSError as e:
        raise UserError(f"cannot write: {e.strerror}", file=str(out)) from None
    with RunStore(run, "a") as st:
        st.write_group("analysis", analysis_results(an, text, settings))
    return text
