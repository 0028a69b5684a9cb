"""Where the packets are, found in the records themselves (stage 0 of the wave method).

The picker of ``engine.wavefeatures.picks`` looks for each mode's direct packet inside a
window around a prediction. When the specimen's constants are far off (the lab's normal
case: they are what the test is to find), a window around the nominal prediction holds the
wrong packet or none. This stage measures, from the records alone, where each mode's
direct packet is, and hands the picker predictions rescaled by it:

1. scalogram maxima: per sensor and analysis frequency (a coarse subset of the grid), the
   local maxima of |W| (a short wavelet: time resolution first) above the noise, on the
   mean scalogram of the first shots;
2. time origin: the source record's own scalogram maximum when the source is recorded;
   else (triggered on a sensor) the onset common to all frequencies: every pair of maxima
   (nearer sensor, farther sensor) of one frequency implies a velocity (distance difference
   over time difference) and an onset; direct packets of every mode and frequency agree on
   one onset, reflections do not (their implied onset depends on the frequency or the mode),
   so the onset is the peak of the amplitude-weighted histogram of the implied onsets,
   searched over a range set by the trigger alone (no velocity assumed);
3. direct packets: with the onset, each maximum has an apparent velocity r / (t - onset);
   a direct packet has the same one at every sensor of the direction (it moves out at one
   speed); a reflection does not (its path grows differently), and with two sensors only
   the maxima found at both within the time resolution are kept;
4. mode labels: the nominal model gives each mode's curve shape (A0 slow and dispersive,
   S0 fast and flat, SH0 between); per mode, the scale s (0.6..1.6) of its nominal curve
   that passes through the most candidate energy is searched, the fastest mode first, each
   slower one below the faster ones' measured curves; among the strong solutions the
   fastest is the direct path (a mode's reflections arrive after its direct packet); one
   packet alone along a direction is named by its dispersion or one common stiffness factor,
   and a mode the records do not hold gets the level they allow (``engine.wavefeatures.lone``);
5. the result: per mode the measured / nominal ratio per frequency (a smooth fit), its
   scatter as the picker's margin, the onset range, and, where a mode's ratio is off by
   more than the usual uncertainty of nominal constants, one line saying so.

Pure: arrays in, a ``Survey`` out. Units: s, Hz, m, m/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .. import waves
from . import lone
from .picks import (Direction, arrivals_of, noise_rms, nominal_cg, sensor_delay)
from .predict import predict_packets, source_signature

__all__ = ["Survey", "survey_onsets", "survey_direction", "mismatch_line", "SCALE_RANGE"]

SCALE_RANGE = (0.6, 1.6)      # measured / nominal velocity ratios searched (moduli ~0.36..2.6 x)
TAU = 0.03                    # log-velocity tolerance of the scale match
N_SUB = 28                    # coarse analysis frequencies
SURVEY_WAVELET = waves.Wavelet(2.0, 1.0)
ABSENT = 0.5                  # a missing mode's level bound below which its predictions are scaled down
INCONSISTENT = 0.25           # weight of a maximum the nearer sensors do not confirm (source recorded)


@dataclass(frozen=True)
class Survey:
    """What the records say of the direct packets of one direction.

    scale / margin: per mode, measured / nominal group-velocity ratio on the analysis grid
    (a smooth fit) and its relative uncertainty (the picker's window half-width). ratio:
    per mode, the median ratio. band: per mode, the (lowest, highest) frequency it was seen
    at. t0_range: the source onset range on the record axis (None: the source is recorded or
    the onset is not sought). onset_shots: the onset found per surveyed shot. notes: what
    was done. mismatch: per mode (ratio, line) where the data contradict the nominal. level:
    per mode the records did not show (a lone packet's direction), the factor (< ``ABSENT``)
    by which they hold it less than the nominal predicts (``lone.absent_level``)."""

    scale: Mapping[str, np.ndarray]
    margin: Mapping[str, float]
    ratio: Mapping[str, float]
    band: Mapping[str, tuple[float, float]]
    t0_range: tuple[float, float] | None
    onset_shots: tuple[float, ...] = ()
    notes: tuple[str, ...] = ()
    mismatch: Mapping[str, tuple[float, str]] = field(default_factory=dict)
    level: Mapping[str, float] = field(default_factory=dict)


def _maxima(A: np.ndarray, t: np.ndarray, t_min: float, floor: np.ndarray, k_max: int = 12):
    """Per row: [(time, amplitude), ...] of the local maxima after ``t_min`` above ``floor``
    (parabolic refinement in log|W|), the ``k_max`` strongest."""
    out = []
    dt = t[1] - t[0]
    for i in range(A.shape[0]):
        a = A[i]
        m = np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] >= a[2:])) + 1
        m = m[(t[m] > t_min) & (a[m] > floor[i])]
        if m.size > k_max:
            m = m[np.argsort(a[m])[-k_max:]]
        row = []
        for k in m:
            la, lb, lc = np.log(np.maximum(a[k - 1:k + 2], 1e-300))
            den = la - 2 * lb + lc
            d = float(np.clip(0.5 * (la - lc) / den, -0.5, 0.5)) if den < 0 else 0.0
            row.append((t[k] + d * dt, float(a[k])))
        out.append(row)
    return out


def _mean_scalograms(d: Direction, shots, freqs, wl) -> dict:
    """{channel: mean |W| over the shots} and the noise floor per channel (|W| units)."""
    fs, pre = d.setup.fs_hz, d.setup.pretrigger
    out, floors = {}, {}
    for s in d.sensors:
        acc, fl = None, None
        for rec in shots:
            A = np.abs(waves.cwt(rec[s.channel], fs, freqs, wl))
            acc = A if acc is None else acc + A
            nz = noise_rms(rec[s.channel], pre, fs, freqs, wl)
            fl = nz if fl is None or nz is None else np.maximum(fl, nz)
        A = acc / len(shots)
        top = A.max(axis=1)
        floor = 0.03 * top
        if fl is not None:
            floor = np.maximum(floor, 10 ** (14 / 20) * fl)
        out[s.channel], floors[s.channel] = A, floor
    return out, floors


def _onset_votes(d: Direction, peaks: dict, freqs, c_src, grid: np.ndarray, width: float) -> np.ndarray:
    """Votes for each onset of ``grid`` (record axis, s): every pair of maxima (nearest
    sensor, farthest sensor) of one frequency implies a velocity and an onset; per frequency
    the best pair within ``width`` of the onset counts (amplitude relative to that frequency's
    strongest pair), so an onset supported across the band outvotes one strong echo pair."""
    votes = np.zeros(grid.size)
    for fam in "AS":                  # per mode family's records (a top/bottom pair: sum and difference)
        ss = [s for s in d.sensors if fam in s.families]
        if len(ss) >= 2 and ss[-1].distance_m > ss[0].distance_m:
            votes += _pair_votes(ss[0], ss[-1], peaks, freqs, c_src, grid, width)
    return votes


def _pair_votes(near, far, peaks: dict, freqs, c_src, grid: np.ndarray, width: float) -> np.ndarray:
    """``_onset_votes`` of one (nearer, farther) sensor pair."""
    dr = far.distance_m - near.distance_m
    votes = np.zeros(grid.size)
    dn, dff = sensor_delay(near, freqs), sensor_delay(far, freqs)
    for i in range(freqs.size):
        t0s, ws = [], []
        for tn, an in peaks[near.channel][i]:
            for tf, af in peaks[far.channel][i]:
                dt = (tf - dff[i]) - (tn - dn[i])
                if dt > 0:
                    t0s.append(tn - dn[i] - near.distance_m * dt / dr - c_src[i])
                    ws.append(math.sqrt(an * af))
        if not ws:
            continue
        t0s, ws = np.array(t0s), np.array(ws) / max(ws)
        k = np.exp(-0.5 * ((grid[:, None] - t0s[None, :]) / width) ** 2) * ws[None, :]
        votes += k.max(axis=1)
    return votes


def survey_onsets(dirs: Sequence[Direction], shots: Sequence[Mapping[str, np.ndarray]], n_shots: int = 3
                  ) -> tuple[tuple[float, ...], tuple[float, float]] | None:
    """The source onset of each of the first ``n_shots`` shots (record axis, s) when the source
    is not recorded, from every direction with two sensors at different distances (their votes
    add up: one source, one onset), and the onset range they span (plus the resolution); None
    when no direction can say. Triggered on a sensor: the onset lies before the trigger.
    Triggered by the generator: the onset is the trigger's up to the transducers' delay, which
    nothing in the rig states (a real actuator and its bond lag the drive: 3.6-3.7 us on both
    modes of Yeum's aluminium plate, bench/RESULTS.md issue 24 session 26), searched within
    one source duration either side."""
    usable = [d for d in dirs if any(len({s.distance_m for s in d.sensors if f in s.families}) >= 2 for f in "AS")]
    if not usable or usable[0].setup.force_channel is not None:
        return None
    setup = usable[0].setup
    fs, pre = setup.fs_hz, setup.pretrigger
    d0 = usable[0]
    step = max(1, d0.freqs.size // N_SUB)
    freqs = d0.freqs[::step]
    wl = SURVEY_WAVELET
    c_src = source_signature(setup.source, freqs, wl)[0]
    dur = setup.source.force().duration_s
    if setup.trigger_distance_m is None:
        lo, hi = -dur, dur
    else:
        # the onset lies before the trigger, by at most the trigger sensor's distance at half the
        # slowest nominal velocity (no velocity of the nominal model is trusted more than that)
        slow = min(float(np.nanmin(nominal_cg(d, m))) for d in usable for m in ("A0", "S0")
                   if np.isfinite(nominal_cg(d, m)).any())
        lo, hi = -setup.trigger_distance_m / (0.5 * slow) - dur, 2.0 / fs
    grid = np.arange(lo, hi, 0.25 / fs)
    width = 1.0e-6 + 1.0 / fs
    onsets = []
    for rec in shots[:n_shots]:
        votes = np.zeros(grid.size)
        for d in usable:
            A, floors = _mean_scalograms(d, [rec], freqs, wl)
            n = next(iter(A.values())).shape[1]
            t = (np.arange(n) - pre) / fs
            pk = {ch: _maxima(a, t, -np.inf, floors[ch]) for ch, a in A.items()}
            votes += _onset_votes(d, pk, freqs, c_src, grid, width)
        if not votes.max() > 0:
            return None
        onsets.append(float(grid[int(np.argmax(votes))]))
    half = 0.5 * (max(onsets) - min(onsets)) + width + 2.0e-6     # later shots: their own onset, refined by the picker
    mid = 0.5 * (max(onsets) + min(onsets))
    return tuple(onsets), (mid - half, mid + half)


def _candidates(d: Direction, peaks: dict, freqs, wl, t_ref: np.ndarray, tol_s: np.ndarray,
                known_time: bool = False, family: str = "A"):
    """Per frequency [(velocity, weight), ...] of the maxima that move out at one speed: with
    several sensors, apparent velocities r / (t - t_ref) matching at every sensor (times within
    ``tol_s``), weighted by the geometric mean amplitude; with one sensor, all of its maxima;
    with the source time measured (``known_time``) the unconfirmed maxima of the farthest sensor
    too, with ``INCONSISTENT`` of their weight."""
    ss = [s for s in d.sensors if family in s.families]      # the records holding that family
    if not ss:
        return [[] for _ in range(freqs.size)]
    out = []
    for i in range(freqs.size):
        if not np.isfinite(t_ref[i]):
            out.append([])
            continue
        per = []
        for s in ss:
            sd = sensor_delay(s, freqs[i:i + 1])[0]
            per.append([(s.distance_m / (t - sd - t_ref[i]), t - sd, a) for t, a in peaks[s.channel][i]
                        if t - sd - t_ref[i] > 0])
        row = []
        ref = per[-1]                                   # the farthest sensor: the longest lever
        for v, t, a in ref:
            ok, wsum = True, math.log(a)
            for s, lst in zip(ss[:-1], per[:-1]):
                t_exp = t_ref[i] + s.distance_m / v
                best = min(lst, key=lambda c: abs(c[1] - t_exp), default=None)
                if best is None or abs(best[1] - t_exp) > tol_s[i]:
                    ok = False
                    break
                wsum += math.log(best[2])
            if ok:
                row.append((v, math.exp(wsum / len(ss))))
            elif known_time:
                # the source time is measured: a far-sensor maximum stands on its own, but one the
                # nearer sensors do not confirm weighs less (near the source the modes of a burst
                # overlap in time and no separate maximum confirms them)
                row.append((v, INCONSISTENT * a))
        out.append(row)
    return out


def _scale_search(cands, nom: np.ndarray, upper: np.ndarray | None, expected: np.ndarray
                  ) -> tuple[float, float, np.ndarray] | None:
    """(scale, score, per-frequency matched velocity or NaN) of the fastest strong scale of
    the nominal curve ``nom`` through the candidates, below ``upper`` (a faster mode's curve).
    A candidate weighs its amplitude relative to the strongest of its frequency over the
    level ``expected`` of this mode there (relative to the strongest mode, nominal model),
    capped at 1: a weak mode's packet counts as fully as a strong mode's."""
    grid = np.geomspace(*SCALE_RANGE, 400)
    nf = len(cands)
    score = np.zeros(grid.size)
    for i in range(nf):
        if not np.isfinite(nom[i]) or not cands[i]:
            continue
        v = np.array([c[0] for c in cands[i]])
        w = np.array([c[1] for c in cands[i]])
        exp_i = expected[i] if np.isfinite(expected[i]) and expected[i] > 0 else 1.0
        w = np.minimum(w / w.max() / max(exp_i, 1e-3), 1.0)
        keep = np.ones(v.size, bool) if upper is None or not np.isfinite(upper[i]) else v < upper[i] * 0.97
        if not keep.any():
            continue
        z = np.log(v[keep][None, :] / (grid[:, None] * nom[i])) / TAU
        # each frequency contributes its best candidate (sqrt of energy: one strong packet
        # does not outvote a consistent curve)
        score += (np.sqrt(w[keep])[None, :] * np.exp(-0.5 * z * z)).max(axis=1)
    if not score.max() > 0:
        return None
    # strong local maxima; the fastest of them (the direct path comes before the echoes)
    sm = np.convolve(score, np.ones(5) / 5, mode="same")
    loc = [j for j in range(1, grid.size - 1) if sm[j] >= sm[j - 1] and sm[j] > sm[j + 1]]
    strong = [j for j in loc if sm[j] >= 0.5 * sm.max()] or [int(np.argmax(sm))]
    j = max(strong)
    s = float(grid[j])
    matched = np.full(nf, np.nan)
    for i in range(nf):
        if not np.isfinite(nom[i]) or not cands[i]:
            continue
        v = np.array([c[0] for c in cands[i]])
        z = np.abs(np.log(v / (s * nom[i])))
        k = int(np.argmin(z))
        if z[k] <= 2.5 * TAU and (upper is None or not np.isfinite(upper[i]) or v[k] < upper[i] * 0.97):
            matched[i] = v[k]
    return s, float(score[j]), matched


def _track(cands, nom: np.ndarray, s: float, freqs: np.ndarray, upper: np.ndarray | None, n_iter: int = 4):
    """Follow the ridge the scale search found: the measured / nominal ratio as a line in
    ln f, started at the constant ``s``; each pass takes per frequency the candidate nearest
    the current line (within 2.5 TAU, below ``upper``), refits, and leaves out points more
    than 3 robust stds (at least 1 %) off the line (a spectral notch of the source splits a
    packet in two lobes, neither of which is the group delay). Returns (coefficients in
    ln(f / f_max), mask of the points kept, their ratios, robust std) or None (< 3 points)."""
    x = np.log(freqs / freqs.max())
    c = np.array([s])
    ok, r, spread = None, None, 0.0
    for _ in range(n_iter):
        center = nom * np.polynomial.polynomial.polyval(x, c)
        matched = np.full(freqs.size, np.nan)
        for i in range(freqs.size):
            if not np.isfinite(nom[i]) or not cands[i]:
                continue
            v = np.array([cc[0] for cc in cands[i]])
            z = np.abs(np.log(v / center[i]))
            k = int(np.argmin(z))
            if z[k] <= 2.5 * TAU and (upper is None or not np.isfinite(upper[i]) or v[k] < upper[i] * 0.97):
                matched[i] = v[k]
        ok = np.isfinite(matched)
        if ok.sum() < 3:
            return None
        ratio = matched / nom
        keep = ok.copy()
        for _ in range(3):
            deg = 1 if keep.sum() >= 8 else 0
            c = np.polynomial.polynomial.polyfit(x[keep], ratio[keep], deg)
            res = ratio - np.polynomial.polynomial.polyval(x, c)
            spread = 1.4826 * float(np.median(np.abs(res[keep] - np.median(res[keep]))))
            new = ok & (np.abs(res) <= max(3 * spread, 0.01 * np.median(ratio[ok])))
            if new.sum() < 3 or np.array_equal(new, keep):
                break
            keep = new
        ok, r = keep, ratio[keep]
    return c, ok, r, spread


def _direct_levels(d: Direction, freqs, wl) -> dict:
    """{mode: relative amplitude of its direct packet at the farthest sensor} (nominal model)."""
    s = d.sensors[-1]
    setup = d.setup
    xy = (setup.source_xy[0] + s.distance_m * math.cos(math.radians(s.direction_deg)),
          setup.source_xy[1] + s.distance_m * math.sin(math.radians(s.direction_deg)))
    pk = predict_packets(setup.laminate, setup.source, setup.source_xy, xy, setup.plate_size_m, freqs, wl,
                         sensor_face=s.face if s.families == "AS" else "top", sensor_length_m=s.length_m,
                         order=0, min_level=0.0)
    return {p.mode: p.amplitude for p in pk if p.path == "direct"}


def mismatch_line(mode: str, direction: float, ratio: float, band: tuple[float, float]) -> str:
    """The console line for a mode whose measured velocity contradicts the nominal model."""
    late = 1.0 / ratio - 1.0
    when = f"{abs(late) * 100:.0f} % {'later' if late > 0 else 'earlier'}"
    return (f"{mode} along {direction:g} deg arrives {when} than the nominal specimen predicts "
            f"(measured group velocity {ratio:.2f} x nominal, {band[0] / 1e3:.3g}-{band[1] / 1e3:.3g} kHz): "
            "the specimen's constants are far off; the velocities below are measured from the records, "
            "not from the nominal model (identify them, then analyze again with the identified constants)")


def survey_direction(d: Direction, shots: Sequence[Mapping[str, np.ndarray]],
                     modes: Sequence[str] = ("S0", "SH0", "A0"), n_shots: int = 3,
                     onsets: Sequence[float] = ()) -> Survey:
    """Stage 0 (module docstring) on the first ``n_shots`` shots of one direction; ``onsets``:
    the source onsets of those shots (``survey_onsets``) when the source time is unknown."""
    setup, freqs_all = d.setup, d.freqs
    fs, pre = setup.fs_hz, setup.pretrigger
    step = max(1, freqs_all.size // N_SUB)
    idx = np.arange(0, freqs_all.size, step)
    freqs = freqs_all[idx]
    wl = SURVEY_WAVELET
    use = list(shots[:n_shots])
    notes: list[str] = []
    A, floors = _mean_scalograms(d, use, freqs, wl)
    n = next(iter(A.values())).shape[1]
    t = (np.arange(n) - pre) / fs
    tstd = wl.time_std_s(freqs)
    c_src, _, _ = source_signature(setup.source, freqs, wl)
    t_min = -np.inf
    t0_range = None
    if setup.force_channel is not None:
        src = arrivals_of(d, use[0][setup.force_channel], None, "A0", wl, None)
        t_ref = np.where(src.valid, src.times_s, np.nan)
        how = "the source record"
    elif onsets:
        t0 = float(np.mean(onsets[:len(use)]))
        t0_range = (min(onsets) - 1.0e-6, max(onsets) + 1.0e-6)
        t_ref = t0 + c_src
        how = f"the onset common to the sensors' packets ({t0 * 1e6:.1f} us on the record axis)"
    else:
        t_ref = c_src + d.t0[0]
        how = "the trigger time"
    peaks = {ch: _maxima(a, t, t_min, floors[ch]) for ch, a in A.items()}
    tol = 0.6 * tstd + 2.0 / fs
    cands = {fm: _candidates(d, peaks, freqs, wl, t_ref, tol, known_time=setup.force_channel is not None,
                             family=fm) for fm in "AS"}
    nominal = {m: nominal_cg(d, m)[idx] for m in modes}
    nominal = every = {m: v for m, v in nominal.items() if np.isfinite(v).sum() >= 3}
    # a mode the source hardly excites (or the sensor hardly sees: SH0 under a normal force or
    # a disc, along a symmetry axis) is not searched: its curve would claim another's packets
    level = _direct_levels(d, freqs, wl)
    top = max((np.nanmax(v) for v in level.values()), default=0.0)
    strongest = np.nanmax(np.array(list(level.values())), axis=0) if level else np.ones(freqs.size)
    nominal = {m: v for m, v in nominal.items() if m in level and np.nanmax(level[m]) >= 0.05 * top}
    fam = set("".join(s.families for s in d.sensors))
    scale, margin, ratio, band, mismatch, absent, meas = {}, {}, {}, {}, {}, {}, {}
    upper = None
    x_all = np.log(freqs_all / freqs_all.max())

    def keep(m, track):
        c, ok, r, spread = track
        f_ok = freqs[ok]
        scale[m] = np.polynomial.polynomial.polyval(x_all, c)
        margin[m] = float(min(max(4 * spread, 0.02), 0.06))
        ratio[m] = float(np.median(r))
        band[m] = (float(f_ok.min()), float(f_ok.max()))
        meas[m] = np.full(freqs.size, np.nan)
        meas[m][ok] = r * nominal[m][ok]
        return c, ok

    for m in sorted(nominal, key=lambda m: -np.nanmedian(nominal[m])):      # fastest first
        if ("A" if m.startswith("A") else "S") not in fam:
            continue
        res = _scale_search(cands["A" if m.startswith("A") else "S"], nominal[m], upper,
                            level[m] / np.maximum(strongest, 1e-300))
        if res is None:
            continue
        track = _track(cands["A" if m.startswith("A") else "S"], nominal[m], res[0], freqs, upper)
        if track is None:
            continue
        c, ok = keep(m, track)
        cur = nominal[m] * np.polynomial.polynomial.polyval(np.log(freqs / freqs_all.max()), c)
        upper = cur if upper is None else np.fmin(upper, cur)
    both = all(set(s.families) >= {"A", "S"} for s in d.sensors)      # one record holds both families
    if len(scale) == 1 and both:
        # a lone packet: its family from its dispersion or one common stiffness factor (lone.py)
        m = next(iter(scale))
        lab, why = lone.lone_label(freqs, meas[m], every, m, SCALE_RANGE)     # every mode: a level is no label
        if lab != m:
            track = _track(cands["A" if lab.startswith("A") else "S"], every[lab],
                           float(np.nanmedian(meas[m] / every[lab])), freqs, None)
            if track is not None:
                for dct in (scale, margin, ratio, band, meas):
                    dct.pop(m)
                nominal[lab] = every[lab]
                keep(lab, track)
                notes.append(f"direction {d.direction:g} deg: one packet in the records, {lab} by {why}, "
                             f"not {m}")
        found = next(iter(scale))
        far = d.sensors[-1]
        med = ratio[found]
        mu = float(min(d.settings.gate_margin + abs(math.log(med)), 0.3))
        width = 2 * tstd + 0.5 * setup.source.force().duration_s
        for k in nominal if found in level else ():
            if k in scale or k not in level:
                continue
            rel = level[k] / np.maximum(level[found], 1e-300)
            nr = d.sensors[0] if d.sensors[0].distance_m < far.distance_m else None
            v_k = (nominal[k] * med * (1 - mu), nominal[k] * med * (1 + mu))
            rest = None if nr is None else lone.residue_scalogram(
                [(r[far.channel], r[nr.channel]) for r in use[:4]], fs, pre, (nr.distance_m, far.distance_m),
                meas[found], v_k, t_ref, width, freqs, wl, setup.source.force())
            fac = lone.absent_level(A[far.channel], t - float(np.median(sensor_delay(far, freqs))), t_ref,
                                    far.distance_m, v_k, meas[found], rel, width, None if nr is None else A[nr.channel],
                                    0.0 if nr is None else nr.distance_m, rest)
            if fac is not None and fac < ABSENT:
                absent[k] = fac
                notes.append(f"direction {d.direction:g} deg: no {k} packet in the records where the picker will "
                             f"look for it: at most {20 * math.log10(max(fac, 1e-6)):.0f} dB of its nominal level; "
                             "its predicted packets bound the picks at that level")
    for m in scale:
        notes.append(f"direction {d.direction:g} deg: {m} found in the records at {np.isfinite(meas[m]).sum()} of "
                     f"{freqs.size} surveyed frequencies ({band[m][0] / 1e3:.3g}-{band[m][1] / 1e3:.3g} kHz), "
                     f"{ratio[m]:.3f} x the nominal group velocity, time origin from {how}")
        if abs(math.log(ratio[m])) > max(d.settings.gate_margin, 0.05):
            mismatch[m] = (ratio[m], mismatch_line(m, d.direction, ratio[m], band[m]))
    return Survey(scale, margin, ratio, band, t0_range, tuple(onsets), tuple(notes), mismatch, absent)
