"""A lone packet's mode and the level of a mode the records do not hold (survey, stage 0).

When the survey finds one direct packet along a direction (one mode family in the records),
the nominal model's absolute times cannot name it: with constants 30-40 % off (the lab's
normal case) the nominal A0 and S0 curves can both be scaled onto it within the survey's
scale range (bench/RESULTS.md, issue 24, session 26: eriknbd/Lamb_wave_analisis' A0 taken for
S0 at 0.67 x S0's nominal). What the records say instead:

1. the shape: A0 is dispersive at low frequency-thickness, S0 and SH0 nearly flat; where the
   nominal curves' changes across the surveyed band differ by more than the survey's
   resolution (``SHAPE_MIN``), the family whose log-slope d ln c_g / d ln f is nearer the
   measured one names the packet;
2. otherwise (a tone burst's narrow band), one common stiffness factor: scaling every
   stiffness by k moves a mode's curve to sqrt(k) c_g(f / sqrt(k)) (exact for a plate), so a
   measured / nominal ratio r means k = r^(2 / (1 - s)) with s the nominal's log-slope; the
   family whose k is nearer 1 names it (a nominal 30-40 % off: |ln k| ~ 0.3-0.5; the other
   label needs k ~ 0.45 or ~ 2-4 for the same packet).

A foreign mode the nominal predicts but the survey did not find keeps its predicted place
(timed with the measured ratios) but not its predicted level: ``absent_level`` measures, at
the farthest sensor, the strongest scalogram maximum where that mode could be (its nominal
times scaled as the picker will scale them) apart from the found packets, relative to the found
packet, against the level the nominal expects there: in the far record less the found packet
moved from the near one by a filter fitted between them (``residue_scalogram``), over the
share of an absent packet that survives that removal. The picker's overlap bound then uses
the level the records allow, not the model's.

Pure: arrays in, numbers out. Units: Hz, m/s, s.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np
from scipy import signal

from .. import waves

__all__ = ["lone_label", "absent_level", "found_removed", "residue_scalogram", "SHAPE_MIN"]

SHAPE_MIN = 0.09      # nominal curves' relative change across the band that the survey's shape resolves (3 TAU)


def _slope(f: np.ndarray, v: np.ndarray) -> float:
    """d ln v / d ln f (least squares over the finite points)."""
    ok = np.isfinite(v) & (v > 0)
    if ok.sum() < 2 or np.ptp(np.log(f[ok])) <= 0:
        return 0.0
    return float(np.polyfit(np.log(f[ok]), np.log(v[ok]), 1)[0])


def lone_label(freqs: np.ndarray, v: np.ndarray, nominal: Mapping[str, np.ndarray], found: str,
               scale_range: tuple[float, float]) -> tuple[str, str]:
    """(label, why) of a lone packet measured at ``v`` (m/s, NaN where not seen) on ``freqs``
    (Hz), found as ``found`` by the scale search; ``nominal``: the A0 and S0 nominal c_g on
    the same grid. The label stays ``found`` unless the records name the other family
    (module docstring); ``why`` says how ('' when there was nothing to decide)."""
    ok = np.isfinite(v)
    fams = [m for m in ("A0", "S0") if m in nominal and np.isfinite(nominal[m][ok]).sum() >= 3]
    if found not in fams or len(fams) < 2 or ok.sum() < 3:
        return found, ""
    f = freqs[ok]
    s_meas = _slope(f, v[ok])
    s_nom = {m: _slope(f, nominal[m][ok]) for m in fams}
    r = {m: float(np.nanmedian(v[ok] / nominal[m][ok])) for m in fams}
    fits = [m for m in fams if scale_range[0] <= r[m] <= scale_range[1]]
    if len(fits) < 2:
        if len(fits) == 1 and fits[0] != found:      # the track drifted out of the scale range
            return fits[0], f"its ratio to the nominal: {found} {r[found]:.2f}, {fits[0]} {r[fits[0]]:.2f} x"
        return found, ""
    span = math.log(f.max() / f.min())
    if abs(s_nom["A0"] - s_nom["S0"]) * span >= SHAPE_MIN:
        lab = min(fits, key=lambda m: abs(s_meas - s_nom[m]))
        why = (f"its dispersion d ln c_g / d ln f = {s_meas:.2f} (nominal A0 {s_nom['A0']:.2f}, "
               f"S0 {s_nom['S0']:.2f})")
    else:
        k = {m: r[m] ** (2.0 / max(1.0 - s_nom[m], 0.2)) for m in fits}
        lab = min(fits, key=lambda m: abs(math.log(k[m])))
        why = ("one stiffness factor: " + ", ".join(f"{m} {r[m]:.2f} x nominal needs {k[m]:.2f} x its stiffness"
                                                    for m in fits)
               + f" (the band's shapes do not differ: A0 {s_nom['A0']:.2f}, S0 {s_nom['S0']:.2f} "
               f"d ln c_g / d ln f, measured {s_meas:.2f})")
    return lab, why


def absent_level(W_far: np.ndarray, t: np.ndarray, t_ref: np.ndarray, r_far: float,
                 v_range: tuple[np.ndarray, np.ndarray], found_v: np.ndarray, expected: np.ndarray,
                 width: np.ndarray, W_near: np.ndarray | None = None, r_near: float = 0.0,
                 W_rest: np.ndarray | None = None) -> float | None:
    """The factor (<= 1) by which the records hold a mode less than the nominal expects, or
    None when they cannot say. ``W_far`` / ``W_near``: the far / a nearer sensor's |W|
    (frequency x time) on the record axis ``t`` less the sensors' delay; ``t_ref``: the source
    time per frequency; ``r_far`` / ``r_near``: their distances (m); ``v_range``: the (slowest,
    fastest) c_g the mode may have per frequency (where the picker will look for it);
    ``found_v``: the found packet's measured c_g (NaN where not seen); ``expected``: the
    mode's nominal level relative to the found mode's at the far sensor; ``width``: the found
    packet's half-width (s) where no nearer record is given; ``W_rest``: |W| of the far record
    less the found packet, over the share of an absent packet that survives the removal
    (``residue_scalogram``), used instead of the |W| difference when given: the difference
    is no bound where the absent packet's near copy, moved with the found delay, overlaps
    its far one (a 10-cycle 250 kHz S0-like packet over 45 mm read at 0.61 x its level, numpy
    records; tests/unit/engine/test_wave_lone.py).

    Per frequency, what of the far record inside the mode's possible times the found packet
    does not explain: with a nearer record, the far |W| less the near one moved by the found
    packet's delay between their maxima and scaled to its far peak (a packet of another speed does not
    move with it: it stays in the difference; what the found packet's own dispersion
    changes between the sensors stays too, so this bounds from above); without, the far |W|
    more than ``width`` from the found packet. Its largest value over the found packet's far
    peak, divided by ``expected``; the largest over the band where the mode is predicted
    within 12 dB of its strongest (in a notch of the prediction the ratio is large and the
    packet too weak to matter)."""
    out = []
    strong = expected >= 0.25 * np.nanmax(np.where(np.isfinite(expected), expected, 0.0))
    for i in range(W_far.shape[0]):
        if not (np.isfinite(found_v[i]) and np.isfinite(v_range[0][i]) and np.isfinite(t_ref[i]) and strong[i]):
            continue
        t_found = t_ref[i] + r_far / found_v[i]
        near = np.abs(t - t_found) <= width[i]
        inside = (t >= t_ref[i] + r_far / v_range[1][i]) & (t <= t_ref[i] + r_far / v_range[0][i])
        if not near.any() or not inside.any():
            continue
        peak = float(W_far[i, near].max())
        if W_rest is not None:
            rest = W_rest[i, inside]
        elif W_near is not None and r_near < r_far:
            # the found packet's own delay between the sensors: its maxima, each near its survey time
            at_near = np.abs(t - t_ref[i] - r_near / found_v[i]) <= width[i]
            if not at_near.any():
                continue
            delay = t[near][np.argmax(W_far[i, near])] - t[at_near][np.argmax(W_near[i, at_near])]
            moved = np.interp(t - delay, t, W_near[i], left=0.0, right=0.0)
            g = peak / max(float(moved[near].max()), 1e-300)
            rest = np.abs(W_far[i] - g * moved)[inside]
        else:
            inside &= ~near
            if not inside.any():
                continue
            rest = W_far[i, inside]
        out.append(float(rest.max()) / peak / expected[i])
    if len(out) < 3:
        return None
    return float(min(max(out), 1.0))


def found_removed(far: np.ndarray, near: np.ndarray, fs: float, delay_s: float, span_s: float,
                  band_hz: tuple[float, float], fit: tuple[int, int], skip: tuple[int, int] = (0, 0)
                  ):
    """The far record less what the near one explains of it through a filter whose impulse
    response lies within ``span_s`` of ``delay_s`` (s): the found packet's own travel
    between the sensors, with its measured delay, amplitude and dispersion (a least-squares
    FIR on both records band-passed to ``band_hz``, taps every 1 / (4 f_max), fitted over the
    far samples ``fit`` = [k0, k1) less ``skip``, where the other mode may be: it does not
    steer the filter). A mode of another speed needs a delay outside the span: the filter
    cannot move it onto its far packet, so it stays in the residue (and its near copy, moved
    with the found delay, adds to it): the residue bounds it from above, as the |W|
    difference of ``absent_level`` does, without the found packet's own change between the
    sensors (eriknbd: A0's change read as S0 at -21 to -41 dB of its nominal level). Denser
    taps (1 / (8 f_max)) fit the out-of-band rest and blow up over the skipped samples (on
    eriknbd 340-640 kHz the residue there reached 0.05-10 x the far peak). None when the span
    holds fewer than 3 taps, the fit is shorter than 4 x the taps, or the filter's output over
    the skipped samples exceeds 4 x the far record's energy there (it does not carry over); else
    (residue, the same operator for any (far, near) pair of records)."""
    lo, hi = band_hz
    sos = signal.butter(4, [0.8 * lo, min(1.2 * hi, 0.45 * fs)], "bandpass", fs=fs, output="sos")
    x = signal.sosfiltfilt(sos, np.asarray(far, float))
    y = signal.sosfiltfilt(sos, np.asarray(near, float))
    step = max(int(fs / (4.0 * hi)), 1)
    lags = np.arange(int(round((delay_s - span_s) * fs)), int(round((delay_s + span_s) * fs)) + 1, step)
    k0, k1 = max(int(fit[0]), 0), min(int(fit[1]), x.size)
    if lags.size < 3 or lags.min() < 0 or k1 - k0 - max(min(skip[1], k1) - max(skip[0], k0), 0) < 4 * lags.size:
        return None
    pad = int(lags.max())

    def moved(near_f, rows):     # the band-passed near record at each row less each lag (0 before its start)
        return np.concatenate([np.zeros(pad), near_f])[rows[:, None] - lags[None, :] + pad]

    rows = np.arange(k0, k1)
    rows = rows[(rows < skip[0]) | (rows >= skip[1])]
    h = np.linalg.lstsq(moved(y, rows), x[rows], rcond=None)[0]
    res = x - moved(y, np.arange(x.size)) @ h
    s0, s1 = max(skip[0], 0), min(skip[1], x.size)
    if s1 > s0 and np.sum((x - res)[s0:s1] ** 2) > 4.0 * np.sum(x[s0:s1] ** 2):
        # the filter's output over the skipped samples far over the far record there: it does
        # not carry over (an absent packet's near copy moved onto them is ~ its far one)
        return None

    def residue_of(far_like: np.ndarray, near_like: np.ndarray) -> np.ndarray:
        return signal.sosfiltfilt(sos, far_like) - moved(signal.sosfiltfilt(sos, near_like),
                                                         np.arange(far_like.size)) @ h

    return res, residue_of


def residue_scalogram(pairs, fs: float, pre: int, r: tuple[float, float], found_v: np.ndarray,
                      v_k: tuple[np.ndarray, np.ndarray], t_ref: np.ndarray, width: np.ndarray,
                      freqs: np.ndarray, wl: waves.Wavelet, burst) -> np.ndarray | None:
    """Mean |W| (``freqs`` x record samples, wavelet ``wl``) over the shots' (far, near) record
    ``pairs`` of the far record less the found packet (``found_removed``), divided per
    frequency by the least share of an absent packet that survives that removal; ``r``:
    (near, far) distances (m), ``found_v``: the found packet's c_g, ``v_k``: the (slowest,
    fastest) c_g the absent mode may have (m/s, per frequency), ``t_ref``: the source time
    (s, record axis without the pre-trigger), ``width``: the found packet's half-width (s),
    ``burst``: the source's history (a function of the time since its onset, s; the absent
    packet's shape). The filter is centred on the found packet's delays between the sensors
    and reaches half way to the nearest delay the absent mode may have; it is fitted from the
    record's start to the found packet's end at the far sensor, less where the absent mode
    may be there (+- 2 wavelet time std): a packet the records hold there does not steer it.

    The share: the absent packet's near copy, moved with the found delay, lands on its far
    packet when the delays differ by less than its length and cancels part of it (a comb
    |1 - e^(-i 2 pi f dD)| across frequency): a 10-cycle 250 kHz burst over 45 mm kept 0.61-0.75
    of an S0-like packet (numpy records, session 28). So the source's burst is put through
    the same removal as an absent packet at 7 speeds across ``v_k`` (cylindrical spreading
    between the sensors) and the least ratio of its residue inside the window to its far
    packet, per frequency, divides the residue (floored at 0.05: a share below that says
    nothing). None when the delays do not separate or the records are too short."""
    dr = r[1] - r[0]
    ok = np.isfinite(found_v) & np.isfinite(v_k[0]) & np.isfinite(v_k[1]) & np.isfinite(t_ref)
    if dr <= 0 or ok.sum() < 3 or not pairs:
        return None
    a, b = float(np.min(dr / found_v[ok])), float(np.max(dr / found_v[ok]))
    c, e = float(np.min(dr / v_k[1][ok])), float(np.max(dr / v_k[0][ok]))
    gap = a - e if e < a else c - b
    if not gap > 0:
        return None
    ts = 2.0 * float(np.max(wl.time_std_s(freqs[ok])))
    t1 = float(np.max(t_ref[ok] + r[1] / found_v[ok] + width[ok]))
    skip = (pre + int(np.floor((float(np.min(t_ref[ok] + r[1] / v_k[1][ok])) - ts) * fs)),
            pre + int(np.ceil((float(np.max(t_ref[ok] + r[1] / v_k[0][ok])) + ts) * fs)))
    acc, ops = None, []
    for far, near in pairs:
        got = found_removed(far, near, fs, 0.5 * (a + b), 0.5 * (b - a + gap), (float(freqs.min()), float(freqs.max())),
                            (0, pre + int(np.ceil(t1 * fs))), skip)
        if got is None:
            return None
        W = np.abs(waves.cwt(got[0], fs, freqs, wl))
        acc = W if acc is None else acc + W
        ops.append(got[1])
    n = acc.shape[1]
    t = (np.arange(n) - pre) / fs
    # the burst's start such that its centre lies at t_ref (the source signature's centre)
    dur = float(np.ptp(t[np.abs(burst(t - t[0])) > 1e-9 * np.max(np.abs(burst(t - t[0])))])) if n else 0.0
    start = float(np.median(t_ref[ok])) - 0.5 * dur
    lo_i = t_ref + r[1] / v_k[1]
    hi_i = t_ref + r[1] / v_k[0]
    share = np.full(freqs.size, np.inf)
    for v in np.geomspace(float(np.nanmedian(v_k[0][ok])), float(np.nanmedian(v_k[1][ok])), 7):
        far_t = burst(t - start - r[1] / v) / math.sqrt(r[1])
        near_t = burst(t - start - r[0] / v) / math.sqrt(r[0])
        Wf = np.abs(waves.cwt(far_t, fs, freqs, wl))
        Wr = np.abs(waves.cwt(ops[0](far_t, near_t), fs, freqs, wl))
        for i in np.flatnonzero(ok):
            inside = (t >= lo_i[i]) & (t <= hi_i[i])
            if inside.any() and Wf[i].max() > 0:
                share[i] = min(share[i], float(Wr[i, inside].max()) / float(Wf[i].max()))
    share = np.where(np.isfinite(share), np.clip(share, 0.05, 1.0), 1.0)
    return acc / len(pairs) / share[:, None]
