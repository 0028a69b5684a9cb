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
packet, against the level the nominal expects there. The picker's overlap bound then uses
the level the records allow, not the model's.

Pure: arrays in, numbers out. Units: Hz, m/s, s.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

__all__ = ["lone_label", "absent_level", "SHAPE_MIN"]

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
                 width: np.ndarray, W_near: np.ndarray | None = None, r_near: float = 0.0) -> float | None:
    """The factor (<= 1) by which the records hold a mode less than the nominal expects, or
    None when they cannot say. ``W_far`` / ``W_near``: the far / a nearer sensor's |W|
    (frequency x time) on the record axis ``t`` less the sensors' delay; ``t_ref``: the source
    time per frequency; ``r_far`` / ``r_near``: their distances (m); ``v_range``: the (slowest,
    fastest) c_g the mode may have per frequency (where the picker will look for it);
    ``found_v``: the found packet's measured c_g (NaN where not seen); ``expected``: the
    mode's nominal level relative to the found mode's at the far sensor; ``width``: the found
    packet's half-width (s) where no nearer record is given.

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
        if W_near is not None and r_near < r_far:
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
