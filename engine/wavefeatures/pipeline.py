"""The wave-feature method: group-velocity curves of a wave run from its records.

The steps live in ``engine.wavefeatures.band`` (step 1), ``engine.wavefeatures.predict`` (the packets)
and ``engine.wavefeatures.picks`` (steps 2-3); this module runs them (steps 4-8) and re-exports
their public names.

More than ``MAX_CURVES`` shots are first averaged in groups (``stack_shots``). Stage 0
(``engine.wavefeatures.survey``): the source onset of each shot voted by every direction's
sensor pairs when the source time is unknown, then per direction where each mode's direct
packet is in the records; the predictions below are rescaled by it (the nominal model only
names the mode families), and a contradiction with the nominal is said (``WaveResult.mismatch``).

For each propagation direction of the wave sensors (``measure_waves``):

1. band (``analysis_band``): ``band_hz``, else the source's band (a tone burst's -20 dB
   band; for a pencil or a hammer the paper's fmax/20..fmax, fmax = 50 kHz isotropic,
   200 kHz laminate, stopped where a recorded hammer force falls 10 dB) intersected
   with the -20 dB band of the direct packets in the far sensor's record; an empty
   intersection is an empty result that says why and which option to change;
2. path: source to sensor when the source is recorded (its scalogram gives the source
   time per frequency), else between the nearest and the farthest sensor of the
   direction (differential delays only: the source time is unknown when the record is
   triggered on a sensor, and uncertain by the transducers' delay when triggered by the
   generator: the onset is then voted for by the sensor pairs, ``survey_onsets``), else
   (one sensor) from the trigger time;
3. packets (``engine.wavefeatures.predict``): every mode's direct path and edge reflections,
   with the SAFE group velocities of the nominal specimen; a pick is a scalogram
   maximum inside the target's predicted window (nominal velocity +- ``gate_margin``)
   that lies nearer the target's prediction than any foreign packet's; the frequency is
   dropped (and counted) where foreign packets (another mode, any reflection, the
   excitation's crosstalk, measured in the record) reach ``leak_db`` of the pick's level at its time, or could
   shift it by more than ``max_bias`` of the travel time (a first-order bound, which
   otherwise joins the pick's sigma); with the source time unknown the window also spans
   its possible range;
4. checks: every velocity is compared with the predicted direct-path velocities of all
   modes; nearer another mode's: relabelled (if that mode has no point there) or
   rejected; farther than ``gate_margin`` from every mode: rejected;
5. refinement: the predictions are rescaled by what stage 1 measured (a smooth ratio
   per mode, its scatter as the new margin; the source time fitted when unknown) and
   the picks are redone (stage 2);
6. wavelet: ``wavelet``, else per frequency the longest of a few candidates (the paper's
   for the material, a tone burst's band resolution, cmor2-3, cmor2-2, cmor2-1.5, cmor2-1,
   cmor1-1, cmor0.5-1) whose first-shot picks pass (``engine.wavefeatures.merge``; at most
   three measured on all shots);
7. shots: per shot a curve; across shots the mean, with the scatter-based sigma (not
   below the per-shot noise sigma over sqrt(n)) and the wavelet-bias term of a
   centre-frequency sweep (docs/wavelet-bias.md; the swept wavelet measured once, on the
   shots' mean record) in quadrature;
8. the features keep only points a wavelet resolution apart (each point's own wavelet,
   ``merge.independent_mask``), less those off the smooth curve (``merge.off_curve``, ``odd_one``)
   and a gross point off the curve through the others (``merge.gross_points``); then the sigmas
   are scaled by the rest's misfit (``merge.misfit_scale``).

Pure: arrays and small frozen dataclasses in, a ``WaveResult`` out (its notes and the
per-curve ``dropped`` counts included); no files, no run store. Units: s, Hz, m, m/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from .. import waves
from .band import Band, analysis_band, default_wavelet, signal_band, snr_band, wavelet_candidates
from .picks import (MODES, Direction, Sensor, WaveSettings, WaveSetup, arrivals_of, direction_of, locate_onset,
                    noise_rms, nominal_cg, sensor_delay)
from . import crosstalk, memo, merge
from .shots import MAX_CURVES, align_channel, align_shots, bias_term, combine_shots, stack_shots
from .survey import survey_direction, survey_onsets

__all__ = ["WaveSettings", "Sensor", "WaveSetup", "WaveCurve", "WaveResult", "Band", "default_wavelet", "stack_shots",
           "MAX_CURVES", "analysis_band", "echo_path", "noise_rms", "combine_shots", "measure_waves", "sensor_delay",
           "signal_band", "snr_band"]


@dataclass(frozen=True)
class WaveCurve:
    """One measured curve of the features: its independent points (Hz, m/s, m/s) and
    why the other frequencies of the band were dropped ({reason: count})."""

    mode: str
    direction_deg: float
    frequency_hz: np.ndarray
    group_velocity_m_s: np.ndarray
    sigma_m_s: np.ndarray
    dropped: Mapping[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class WaveResult:
    """What ``measure_waves`` found.

    features: the curves for the features document, in order. curves / arrivals: every
    measured curve on the full grid and the first shot's far-sensor arrivals, by key
    '<mode>_<direction>' (e.g. 'A0_0'). wave_path_m / sensor_length_m: path and sensor
    length of the first direction (None without one). dropped: per key, why frequencies
    were dropped ({reason: count}). notes: what was done, in order. mismatch: where the data
    contradict the nominal (mode, direction_deg, velocity_ratio, message). survey: every mode the
    survey found, {mode, direction_deg, velocity_ratio (measured / nominal group velocity)}.
    """

    features: tuple[WaveCurve, ...]
    curves: Mapping[str, waves.GroupVelocity]
    arrivals: Mapping[str, waves.Arrivals]
    wave_path_m: float | None
    sensor_length_m: float | None
    notes: tuple[str, ...]
    dropped: Mapping[str, Mapping[str, int]] = field(default_factory=dict)
    mismatch: tuple[dict, ...] = ()
    survey: tuple[dict, ...] = ()


def _apply_survey(d: Direction, shots, settings: WaveSettings, onsets=None):
    """Stage 0 (``engine.wavefeatures.survey``): the predictions rescaled by where the records
    put each mode's direct packet; a mode the survey did not see takes the median ratio of
    those it saw, with that much more margin; the onset range when the source time is unknown."""
    sv = survey_direction(d, shots, onsets=onsets[0] if onsets else ())
    if onsets:
        d.t0_prior = d.t0 = onsets[1]
    d.absent = dict(sv.level)
    if not sv.ratio:
        return sv
    med = float(np.median(list(sv.ratio.values())))
    for m in ("A0", "S0", "SH0"):
        if m in sv.scale:
            d.prior_scale[m], d.prior_margin[m] = sv.scale[m], sv.margin[m]
        elif np.isfinite(nominal_cg(d, m)).any():
            d.prior_scale[m] = np.full(d.freqs.size, med)
            d.prior_margin[m] = float(min(settings.gate_margin + abs(math.log(med)), 0.3))
    return sv


def echo_path(src: tuple[float, float], dst: tuple[float, float], length: float, width: float) -> float:
    """Shortest source -> edge -> sensor path on a length x width plate (mirror images), m."""
    return min(p.length_m for p in waves.ray_paths(src, dst, length, width, 1) if p.order == 1)


def _velocity(d: Direction, mode: str, wl: waves.Wavelet, rec: Mapping[str, np.ndarray],
              cache: dict) -> tuple[waves.GroupVelocity, dict]:
    """One shot's curve of ``mode`` and its arrivals {'far', 'near', 'source'}."""
    far, near = d.pair(mode)
    force = d.setup.force_channel
    assign = d.settings.assign

    def W(ch):
        if (ch, wl) not in cache:
            cache[(ch, wl)] = waves.cwt(rec[ch], d.setup.fs_hz, d.freqs, wl)
        return cache[(ch, wl)]

    def known(ch):       # |W| and the noise level, read by every pick in this record (issue 24, session 28)
        if ("abs", ch, wl) not in cache:
            cache[("abs", ch, wl)] = {"A": np.abs(W(ch)),
                                      "noise": noise_rms(rec[ch], d.setup.pretrigger, d.setup.fs_hz, d.freqs, wl)}
        return cache[("abs", ch, wl)]

    src = None
    if force is not None:
        if ("src", force, wl) not in cache:
            cache[("src", force, wl)] = arrivals_of(d, rec[force], None, mode, wl, None, W(force), **known(force))
        src = cache[("src", force, wl)]
    out = {"source": src}
    path = far.distance_m - (near.distance_m if near is not None else 0.0)
    a_far = arrivals_of(d, rec[far.channel], far, mode, wl, src, W(far.channel), path, crosstalk.bound_in(
        d, rec, far, wl, cache, W), **known(far.channel))
    # the curvature correction needs a dispersive mode: fitted to S0's nearly constant
    # delays its tau'' is noise (docs/wavelet-bias.md); S0 is reassigned only
    correct = d.settings.assign == "instantaneous" and mode == "A0"
    if correct:
        a_far = waves.correct_dispersion_bias(a_far)
    out["far"] = a_far
    if src is not None:
        g = waves.group_velocity(a_far, far.distance_m, src, assign=assign)
    elif near is not None:
        a_near = arrivals_of(d, rec[near.channel], near, mode, wl, None, W(near.channel), path,
                             crosstalk.bound_in(d, rec, near, wl, cache, W), **known(near.channel))
        if correct:
            a_near = waves.correct_dispersion_bias(a_near)
        out["near"] = a_near
        g = waves.group_velocity(a_far, far.distance_m, a_near, near_distance_m=near.distance_m, assign=assign)
    else:
        g = waves.group_velocity(a_far, far.distance_m, source_time_s=0.0, assign=assign)
    return g, out


def _check_modes(d: Direction, curves: dict[str, waves.GroupVelocity], counts: dict) -> dict:
    """Relabel or reject every point nearer another mode's prediction (module step 4)."""
    nominal = {m: nominal_cg(d, m) * (d.scale[m] if m in d.scale else 1.0) for m in ("A0", "S0", "SH0")}
    nominal = {m: v for m, v in nominal.items() if np.isfinite(v).any()}
    out = {m: (g.velocity_m_s.copy(), g.sigma_m_s.copy(), g.valid.copy()) for m, g in curves.items()}
    for m, g in curves.items():
        for i in np.flatnonzero(g.valid):
            v = g.velocity_m_s[i]
            dev = {k: abs(v / c[i] - 1) for k, c in nominal.items() if np.isfinite(c[i])}
            best = min(dev, key=dev.get)
            if best == m and dev[best] <= d.margin.get(m, d.settings.gate_margin) * 1.5:
                continue
            vm, sm, ok = out[m]
            ok[i] = False
            if best != m and best in out and not out[best][2][i] and \
                    dev[best] <= d.margin.get(best, d.settings.gate_margin) * 1.5:
                vb, sb, okb = out[best]
                vb[i], sb[i], okb[i] = v, g.sigma_m_s[i], True
                counts[m]["relabelled"] = counts[m].get("relabelled", 0) + 1
            else:
                counts[m]["rejected by the mode check"] = counts[m].get("rejected by the mode check", 0) + 1
            vm[i] = sm[i] = np.nan
    return {m: waves.GroupVelocity(d.freqs, v, s, ok) for m, (v, s, ok) in out.items()}


def _reasons(arrs: dict, valid: np.ndarray) -> dict[str, int]:
    """Why the frequencies not in ``valid`` were dropped (far sensor first, then near)."""
    why: dict[str, int] = {}
    for i in np.flatnonzero(~valid):
        r = ""
        for key in ("far", "near", "source"):
            a = arrs.get(key)
            if a is not None and a.reason[i]:
                r = a.reason[i]
                break
        k = _category(r)
        why[k] = why.get(k, 0) + 1
    return why


def _category(r: str) -> str:
    if r.startswith("overlap"):
        return r
    if r.startswith("SNR") or r.startswith("energy"):
        return "weak"
    if not r:
        return "outside the reassigned frequencies"
    return r.split(":")[0].split(" (")[0]


def _shot_curves(d: Direction, wl: waves.Wavelet, shots, first_only: bool = False):
    """Per shot {mode: GroupVelocity} after the mode check, the first shot's arrivals and
    the drop counts {mode: {reason: n}} of the first shot. Each shot's picks are remembered
    (``engine.wavefeatures.memo``: the wavelet choice and the sweep redo many)."""
    per_shot, first_arrs, counts = [], None, None
    for j, rec in enumerate(shots[:1] if first_only else shots):
        key = memo.key(d, wl, j)
        if key in d.memo:
            cur, arrs, cnt, before, d.t0 = d.memo[key]
        else:
            cache = memo.shot_cache(d, wl, j)
            cur, arrs = {}, {}
            locate_onset(d, wl, rec, cache)
            for m in MODES:
                if d.pair(m)[0] is None:
                    continue
                cur[m], arrs[m] = _velocity(d, m, wl, rec, cache)
            cnt = {m: {} for m in cur}
            before = {m: g.valid for m, g in cur.items()}
            cur = _check_modes(d, cur, cnt)
            memo.keep(d, key, (cur, arrs, cnt, before, d.t0), cache)
        if j == 0:
            first_arrs = arrs
            # frequencies the pickers dropped (the mode check counts its own)
            counts = {m: {**_reasons(arrs[m], before[m] | cur[m].valid), **cnt[m]} for m in cur}
        per_shot.append(cur)
    return per_shot, first_arrs, counts


def _refine(d: Direction, per_shot: list[dict]) -> None:
    """Stage 2 predictions: per mode the smooth ratio measured / nominal and its scatter;
    the source onset when it was unknown."""
    for m in MODES:
        nom = nominal_cg(d, m)
        r = np.array([s[m].velocity_m_s / nom for s in per_shot if m in s])
        if r.size == 0 or not np.isfinite(r).any():
            continue
        has = np.isfinite(r).any(axis=0)
        rm = np.full(d.freqs.size, np.nan)
        rm[has] = np.nanmedian(r[:, has], axis=0)
        ok = np.isfinite(rm)
        if ok.sum() < 3:
            continue
        f = d.freqs
        deg = 1 if ok.sum() >= 8 else 0
        c = np.polynomial.polynomial.polyfit(f[ok] / f.max(), rm[ok], deg)
        fit = np.polynomial.polynomial.polyval(f / f.max(), c)
        res = rm[ok] - fit[ok]
        spread = 1.4826 * np.median(np.abs(res - np.median(res))) if res.size >= 3 else 0.0
        d.scale[m] = fit
        d.margin[m] = float(min(max(4 * spread, 0.015), d.settings.gate_margin))


def _measure(d: Direction, wl: waves.Wavelet, shots, first_only: bool = False):
    """Two-stage measurement with one wavelet: (per-shot curves, first arrivals, counts)."""
    d.scale, d.margin = dict(d.prior_scale), dict(d.prior_margin)
    t0 = d.t0
    # stage 1: picks by the nominal predictions (wide margins: overlaps not judged), only
    # to rescale the predictions; stage 2: the measurement
    d.strict = False
    per_shot, first_arrs, counts = _shot_curves(d, wl, shots, first_only=True)
    d.strict = True
    _refine(d, per_shot)
    out = _shot_curves(d, wl, shots, first_only=first_only)
    d.t0 = t0
    return out


def _first_shot(d: Direction, settings: WaveSettings, shots) -> dict:
    """{wavelet: first-shot curves} of every candidate (one candidate: nothing to compare)."""
    cands = wavelet_candidates(d.freqs, d.setup.laminate, settings.wavelet)
    if len(cands) == 1:
        return {cands[0]: None}
    return {wl: _measure(d, wl, shots, first_only=True)[0][0] for wl in cands}


def _wavelet_note(d: Direction, first: dict, used: list, combined: dict, which: dict) -> str:
    """Which wavelets measured which frequencies, and the candidates' first-shot counts."""
    f = d.freqs
    parts = []
    for wl in used:
        sel = [i for m in which for i, w in enumerate(which[m]) if w == wl]
        if sel:
            parts.append(f"{wl.name} at {f[min(sel)] / 1e3:.3g}-{f[max(sel)] / 1e3:.3g} kHz")
    cand = "" if None in first.values() else " (valid first-shot frequencies of the candidates: " + ", ".join(
        f"{wl.name} {sum(int(g.valid.sum()) for g in cur.values())}" for wl, cur in first.items()) + ")"
    return (f"direction {d.direction:g} deg: per frequency the longest wavelet whose picks pass: "
            + ("; ".join(parts) or "none") + cand)


def _sweep_term(d: Direction, wl: waves.Wavelet, shots, combined: dict) -> dict:
    """Half the difference to a centre-frequency sweep (C / 1.5, or x 1.5 below C = 2/3).

    The swept wavelet is measured once, on the mean of the shots (or groups): the term is a bias
    (the wavelet's spread on the dispersion, the same in every shot), and where the picks are linear
    in the noise, the mean of the shots' swept curves is the swept curve of their mean record. One
    measurement instead of one per shot (issue 24, session 29: it was 37 % of a 100-shot sweep's
    analysis, measured on each of a burst's 10 groups)."""
    c_alt = wl.center / 1.5 if wl.center / 1.5 >= 2 / 3 else wl.center * 1.5
    alt_wl = waves.Wavelet(wl.bandwidth, c_alt)
    if len(shots) > 1:
        ref = align_channel(d.setup)     # on one time base first, as stack_shots
        band = (d.freqs[0] / d.setup.fs_hz, d.freqs[-1] / d.setup.fs_hz) if ref else None
        aligned = align_shots(shots, ref, band)[0]
        mean = [{ch: np.mean([s[ch] for s in aligned], axis=0) for ch in shots[0]}]
        kept, d.memo = d.memo, {}        # the memo holds the shots' picks, by shot index: not the mean's
        try:
            per_shot, _, _ = _measure(d, alt_wl, mean)
        finally:
            d.memo = kept
    else:
        per_shot, _, _ = _measure(d, alt_wl, shots)
    return {m: bias_term(g, combine_shots([s[m] for s in per_shot if m in s])) for m, g in combined.items()}


def _pairs(sensors: Sequence[Sensor], shots) -> tuple[list[Sensor], list[dict], list[str]]:
    """Top/bottom sensor pairs at one position become their sum (S modes) and difference
    (A modes) records."""
    out, used, notes = [], set(), []
    recs = [dict(r) for r in shots]
    for a in sensors:
        if a.channel in used:
            continue
        b = next((o for o in sensors if o is not a and o.channel not in used and o.face != a.face
                  and abs(o.distance_m - a.distance_m) < 1e-3 and abs(o.direction_deg - a.direction_deg) < 0.5),
                 None)
        if b is None:
            out.append(a)
            continue
        top, bot = (a, b) if a.face == "top" else (b, a)
        used |= {a.channel, b.channel}
        for r in recs:
            r[f"{top.channel}+{bot.channel}"] = 0.5 * (r[top.channel] + r[bot.channel])
            r[f"{top.channel}-{bot.channel}"] = 0.5 * (r[top.channel] - r[bot.channel])
        out.append(replace(top, channel=f"{top.channel}+{bot.channel}", families="S"))
        out.append(replace(top, channel=f"{top.channel}-{bot.channel}", families="A"))
        notes.append(f"{top.channel} (top) and {bot.channel} (bottom): S modes from their sum, "
                     "A modes from their difference")
    return out, recs, notes


def measure_waves(setup: WaveSetup, shots: Sequence[Mapping[str, np.ndarray]], freqs: np.ndarray,
                  settings: WaveSettings = WaveSettings()) -> WaveResult:
    """Group-velocity curves of every direction from the shots' records.

    ``shots``: per shot, channel name -> record in physical units (every sensor of
    ``setup`` and the source channel); ``freqs``: the analysis grid (``analysis_band``).
    """
    notes: list[str] = []
    shots, stack_note = stack_shots(shots, ref=align_channel(setup),
                                    band=(freqs[0] / setup.fs_hz, freqs[-1] / setup.fs_hz))
    if stack_note:
        notes.append(stack_note)
    sensors, shots, pair_notes = _pairs(setup.sensors, shots)
    notes += pair_notes
    fam = setup.source.families
    if fam != frozenset("SA") and fam != frozenset("AS"):
        sensors = [replace(s, families="".join(sorted(set(s.families) & fam))) for s in sensors]
        by = "lead broken on the edge" if setup.source.load == "inplane" else "collocated actuator pair"
        notes.append(f"{by}: {'S' if 'S' in fam else 'A'} modes only")
    by_dir: dict[float, list] = {}
    for ws in sensors:
        by_dir.setdefault(round(ws.direction_deg, 6), []).append(ws)
    out, curves, arrivals, dropped, mismatch, surveyed = [], {}, {}, {}, [], []
    path_m = length_m = None
    # stage 0: one source, one onset per shot, voted for by every direction's sensor pairs
    onsets = survey_onsets([direction_of(setup, settings, freqs, dd, w) for dd, w in sorted(by_dir.items())],
                           shots)
    if onsets:
        notes.append("source onset from the records (every direction's sensor pairs): "
                     + ", ".join(f"{t * 1e6:.1f}" for t in onsets[0]) + " us on the record axis")
    for direction, wss in sorted(by_dir.items()):
        if setup.force_channel is None and len({s.distance_m for s in wss}) < 2:
            notes.append(f"direction {direction:g} deg: one sensor and no source record; "
                         "velocity from the trigger time (source assumed at t = 0)")
        d = direction_of(setup, settings, freqs, direction, wss)
        n_rec = len(next(iter(shots[0].values())))
        sv = _apply_survey(d, shots, settings, onsets)
        notes.extend(sv.notes)
        for m, (r, line) in sv.mismatch.items():
            notes.append(line)
            mismatch.append({"mode": m, "direction_deg": float(direction), "velocity_ratio": r, "message": line})
        surveyed += [{"mode": m, "direction_deg": float(direction), "velocity_ratio": float(r)} for m, r in sv.ratio.items()]
        d.record_s = (n_rec - setup.pretrigger) / setup.fs_hz - (d.t0_prior[0] if d.t0_prior else 0.0)
        first = _first_shot(d, settings, shots)
        used = merge.plan(first) if None not in first.values() else list(first)
        results = {}
        for wl in used:
            per_shot, first_arrs, counts = _measure(d, wl, shots)
            comb = {m: combine_shots([s[m] for s in per_shot if m in s]) for m in per_shot[0]}
            floor = _sweep_term(d, wl, shots, comb)
            results[wl] = ({m: combine_shots([s[m] for s in per_shot if m in s], floor[m]) for m in comb},
                           first_arrs, counts)
        primary = max(used, key=lambda w: sum(int(g.valid.sum()) for g in results[w][0].values()))
        combined, which, first_arrs = {}, {}, results[primary][1]
        for m in results[primary][0]:
            combined[m], which[m] = merge.merge({w: results[w][0][m] for w in used if m in results[w][0]})
        counts = {m: {**_reasons(first_arrs[m], combined[m].valid),
                      **{k: v for k, v in results[primary][2][m].items() if k.startswith(("relabelled", "rejected"))}}
                  for m in combined}
        notes.append(_wavelet_note(d, first, used, combined, which))
        for mode, gv in combined.items():
            key = f"{mode}_{direction:g}"
            far, near = d.pair(mode)
            dropped[key] = counts[mode]
            why = ", ".join(f"{k} x{n}" for k, n in sorted(counts[mode].items(), key=lambda t: -t[1])[:4])
            if gv.valid.sum() < settings.min_points:
                notes.append(f"{mode} along {direction:g} deg: {int(gv.valid.sum())} valid frequencies "
                             f"(< {settings.min_points}); not reported (dropped: {why or 'none'})")
                continue
            curves[key] = gv
            arrivals[key] = first_arrs[mode]["far"]
            ok = gv.valid
            if mode == "S0" and not settings.report_s0:
                notes.append(f"S0 along {direction:g} deg: {int(ok.sum())} frequencies measured and stored "
                             "in the run (analysis/waves), not put in the features")
                continue
            # the features carry only points a wavelet resolution apart: neighbours on the
            # dense grid share their errors (the full curve stays in the run file)
            ok = merge.independent_mask(freqs, ok, which[mode])
            bad = merge.off_curve(freqs[ok], gv.velocity_m_s[ok], gv.sigma_m_s[ok])
            j = merge.odd_one(freqs[ok][~bad], gv.velocity_m_s[ok][~bad], gv.sigma_m_s[ok][~bad])
            if j is not None:        # one wrong point of a short curve goes alone
                bad[np.flatnonzero(~bad)[j]] = True
            if bad.any():
                counts[mode]["off the smooth curve"] = int(bad.sum())
                ok[np.flatnonzero(ok)[bad]] = False
            spread = merge.scattered(freqs[ok], gv.velocity_m_s[ok], gv.sigma_m_s[ok])
            if spread:
                notes.append(f"{mode} along {direction:g} deg: {spread}; not reported")
                continue
            g, line = merge.gross_points(freqs[ok], gv.velocity_m_s[ok], gv.sigma_m_s[ok],
                                         f"{mode} along {direction:g} deg", dropped_out=counts[mode])
            ok[np.flatnonzero(ok)[g]] = False           # a gross point goes alone, before the sigmas are judged
            k, line2 = merge.misfit_scale(freqs[ok], gv.velocity_m_s[ok], gv.sigma_m_s[ok],
                                          f"{mode} along {direction:g} deg")    # sigmas honest about a bias
            notes += [x for x in (line, line2) if x]
            out.append(WaveCurve(mode, float(direction), freqs[ok], gv.velocity_m_s[ok], k * gv.sigma_m_s[ok],
                                 dict(counts[mode])))
            how = ("two sensors" if near is not None else
                   "source to sensor" if setup.force_channel is not None else "from the trigger time")
            notes.append(f"{mode} along {direction:g} deg: {int(ok.sum())} independent frequencies "
                         f"{freqs[ok].min() / 1e3:.3g}-{freqs[ok].max() / 1e3:.3g} kHz from {len(shots)} shot(s), "
                         f"{merge.names(which[mode], ok)}, {how}; dropped: {why or 'none'}")
        if path_m is None:
            far, near = d.pair("A0") if d.pair("A0")[0] is not None else d.pair("S0")
            path_m = far.distance_m - (near.distance_m if near is not None else 0.0)
            length_m = far.length_m
    return WaveResult(tuple(out), curves, arrivals, path_m, length_m, tuple(notes), dropped, tuple(mismatch),
                      tuple(surveyed))
