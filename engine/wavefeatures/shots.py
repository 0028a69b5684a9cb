"""A run's shots: averaged in groups when there are many (``stack_shots``, before the picks)
and their curves combined into one (``combine_shots``, after). Moved out of
``engine.wavefeatures.pipeline`` (issue 24, session 28), which re-exports them. Units: m/s, Hz.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .. import waves

__all__ = ["bias_term", "MAX_CURVES", "TARGET_REL", "MIN_CORR", "align_channel", "shot_lags", "align_shots", "combine_shots",
           "stack_shots", "more_shots_note"]


def combine_shots(curves: list[waves.GroupVelocity], floor: np.ndarray | None = None) -> waves.GroupVelocity:
    """Mean over shots; sigma: the scatter over shots / sqrt(n), not below the mean
    per-shot sigma / sqrt(n) (a single shot: its own sigma), with ``floor`` (a bias
    term, m/s) added in quadrature. A frequency is valid where more than half the shots
    measured it: at the ends of a reassigned range the one shot whose noise moved its
    instantaneous frequency furthest would give the point alone (issue 24, session 27: a
    sweep's S0 90 kHz +7.3 % was one shot's, with 2 and with 12 shots; the 12 shots' mean
    delays there lie within 0.3 % of the true plate's)."""
    f = curves[0].frequencies_hz
    V = np.array([c.velocity_m_s for c in curves])
    S = np.array([c.sigma_m_s for c in curves])
    ok = np.isfinite(V) & np.isfinite(S) & (S > 0)
    n = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(n > 0, np.where(ok, V, 0.0).sum(axis=0) / np.maximum(n, 1), np.nan)
        scatter = np.sqrt(np.where(ok, (V - v) ** 2, 0.0).sum(axis=0) / np.maximum(n - 1, 1))
        noise = np.where(ok, S, 0.0).sum(axis=0) / np.maximum(n, 1)
        s = np.where(n > 1, np.maximum(scatter, noise), noise) / np.sqrt(np.maximum(n, 1))
    if floor is not None:
        s = np.hypot(s, np.where(np.isfinite(floor), floor, 0.0))
    valid = 2 * n > len(curves)
    return waves.GroupVelocity(f, np.where(valid, v, np.nan), np.where(valid, s, np.nan), valid)


def bias_term(g: waves.GroupVelocity, alt: waves.GroupVelocity) -> np.ndarray:
    """The wavelet-bias term (m/s) of curve ``g`` against the same records picked with a swept
    wavelet ``alt``: half their difference where both are valid; where only ``g`` is (the swept
    wavelet's pick was dropped there), the larger relative term of the nearest frequency on
    each side where both are, x its velocity (0 when none is). It was 0 there: on the preamp
    sweep (bench rig cfrp_pzt_sweep_2dir_far_pre, file +40 %, 80 shots) 453 of 1733 valid picks,
    among them A0 90 deg 109-129 kHz where the neighbours' term is 0.8-1.2 %, the stretch whose
    points lay 12 sigmas off the true plate (issue 24, session 30)."""
    both = g.valid & alt.valid
    term = np.where(both, 0.5 * np.abs(g.velocity_m_s - alt.velocity_m_s), 0.0)
    miss = np.flatnonzero(g.valid & ~both)
    have = np.flatnonzero(both)
    if miss.size and have.size:
        rel = term[have] / g.velocity_m_s[have]
        right = np.minimum(np.searchsorted(have, miss), have.size - 1)
        left = np.maximum(np.searchsorted(have, miss) - 1, 0)
        term[miss] = np.maximum(rel[left], rel[right]) * g.velocity_m_s[miss]
    return term


MAX_CURVES = 12     # shots beyond this are averaged in groups (bench/RESULTS.md, issue 24: cost)

#: a lag is applied only where the normalised correlation of the shot's reference record with
#: the first shot's peaks at least this high, and at least twice white noise's expected peak
#: sqrt(2 ln(2 L + 1) / N_eff) over the 2 L + 1 lags searched (N_eff = 2 x band x record length,
#: the band's degrees of freedom: 0.22 for 4096 samples, +-1024 lags and 80 kHz of 2 MHz): two
#: records of one packet with independent noise at energy SNR S peak at ~S / (1 + S) (the face
#: breaks of bench rig cfrp_pencil_2dir_s0: 0.943 or more), so a shot whose reference record is
#: noise (a missed packet) keeps its trigger's time base
MIN_CORR = 0.3


def align_channel(setup) -> str | None:
    """The channel each shot's lag is measured on: None (no alignment) when a source channel is
    recorded (``setup.force_channel``: the shots are timed by their drive, the delays from it);
    else the sensor at the trigger sensor's distance (``trigger_distance_m``; the trigger sensor
    itself when the record is triggered on a wave sensor: its threshold crossing is what jitters),
    else the sensor nearest the source (the largest, least dispersed packet: the sharpest
    correlation). ``setup``: an ``engine.wavefeatures.picks.WaveSetup``."""
    if setup is None or setup.force_channel is not None or not setup.sensors:
        return None
    near = min(setup.sensors, key=lambda s: s.distance_m)
    if setup.trigger_distance_m is not None:
        near = next((s for s in setup.sensors if abs(s.distance_m - setup.trigger_distance_m) < 1e-3), near)
    return near.channel


def _band_weight(nfft: int, band: tuple[float, float] | None) -> np.ndarray:
    """A flat weight over ``band`` (cycles / sample) with cosine edges a quarter of its width
    wide each; ones without a band."""
    f = np.fft.rfftfreq(nfft)
    if band is None:
        return np.ones(f.size)
    lo, hi = float(band[0]), float(band[1])
    edge = 0.25 * (hi - lo)
    w = np.clip(np.minimum(f - lo, hi - f) / edge + 0.5, 0.0, 1.0)
    return np.sin(0.5 * np.pi * w) ** 2


def shot_lags(shots: Sequence[Mapping[str, np.ndarray]], ref: str, band: tuple[float, float] | None = None,
              max_lag: int | None = None, min_corr: float = MIN_CORR) -> tuple[np.ndarray, np.ndarray]:
    """Per shot, the lag (samples, sub-sample) of channel ``ref`` behind shot 0's: the peak of
    their cross-correlation within +-``max_lag`` samples (default a quarter of the record: a
    stronger break crosses the trigger's level on an earlier, weaker packet, 93-176 us early on 3
    of bench rig cfrp_pencil_2dir_s0's 72 soft-plate breaks, the others within 16 us),
    refined by a parabola through the peak and its neighbours. The correlation is taken in
    ``band`` (cycles / sample: the analysis band, ``_band_weight``) of records tapered over their
    first and last tenth: a pencil break's quasi-static strain, which runs past the record's end
    and does not move with the trigger, held the whole record's correlation near lag 0 (4.6
    samples for 6 on bench rig cfrp_pencil_2dir_s0's trigger sensor, 0.1 for 6 on the other
    direction's; issue 24, session 29). Returns (lags, the correlations' normalised peaks);
    a lag whose peak is below ``min_corr`` or twice noise's (``MIN_CORR``) is NaN (not known)."""
    x0 = np.asarray(shots[0][ref], float)
    n = x0.size
    max_lag = n // 4 if max_lag is None else int(max_lag)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    m = max(1, n // 10)
    taper = np.ones(n)
    taper[:m] = taper[-m:][::-1] = np.sin(0.5 * np.pi * (np.arange(m) + 0.5) / m) ** 2
    w = _band_weight(nfft, band)

    def spectrum(x):
        x = np.asarray(x, float)
        X = np.fft.rfft((x - x.mean()) * taper, nfft) * w
        return X, float(np.sum(np.abs(X[1:]) ** 2))

    X0, e0 = spectrum(x0)
    n_eff = 2.0 * n / nfft * float(np.sum(w ** 2))
    floor = max(min_corr, 2.0 * np.sqrt(2.0 * np.log(2 * max_lag + 1) / max(n_eff, 1.0)))
    lags, rho = np.zeros(len(shots)), np.ones(len(shots))
    lags[1:] = np.nan
    for j in range(1, len(shots)):
        Xj, ej = spectrum(shots[j][ref])
        c = np.fft.irfft(np.conj(X0) * Xj, nfft)                      # c[k] = sum x0[i] xj[i + k]
        c = np.concatenate([c[nfft - max_lag:], c[:max_lag + 1]])       # k = -max_lag .. max_lag
        i = int(np.argmax(c))
        rho[j] = 0.5 * c[i] * nfft / np.sqrt(e0 * ej) if e0 > 0 and ej > 0 else 0.0   # Parseval, one-sided
        if not rho[j] >= floor:
            continue
        frac = 0.0
        if 0 < i < c.size - 1:
            a, b, d = c[i - 1], c[i], c[i + 1]
            if a - 2 * b + d < 0:
                frac = 0.5 * (a - d) / (a - 2 * b + d)
        lags[j] = i - max_lag + frac
    return lags, rho


def align_shots(shots: Sequence[Mapping[str, np.ndarray]], ref: str | None, band: tuple[float, float] | None = None,
                max_lag: int | None = None) -> tuple[list[dict], np.ndarray]:
    """The shots on one time base, the median shot's: each shot's lag measured on ``ref``
    (``shot_lags``), less the median lag (a first shot whose trigger walked, 3 of 72 soft-plate
    breaks, does not move the others by 176 us), and ALL its channels advanced by it, by a linear
    phase ramp on the spectrum (a sub-sample shift), so the delays between channels, the
    measurement, are untouched; a shot whose lag is not known is left as recorded. The record is padded with its
    end value, then its first (a pencil break's quasi-static strain does not start or end at 0):
    the samples shifted in repeat the record's edge, and the wrap's step lies half a record away.
    ``ref`` None or absent: the shots as they are (lags 0). Returns (shots, the shifts applied,
    samples; NaN: not known, not shifted)."""
    if ref is None or len(shots) < 2 or ref not in shots[0]:
        return [dict(s) for s in shots], np.zeros(len(shots))
    lags, _ = shot_lags(shots, ref, band, max_lag)
    known = np.isfinite(lags)
    lags = np.where(known, lags - np.median(lags[known]), np.nan)
    out = []
    for s, lag in zip(shots, lags):
        if not np.isfinite(lag) or lag == 0.0:
            out.append(dict(s))
            continue
        n = next(iter(s.values())).size
        nfft = 1 << int(np.ceil(np.log2(2 * n + 2 * abs(lag))))
        tail = (nfft - n) // 2
        ramp = np.exp(2j * np.pi * np.fft.rfftfreq(nfft) * lag)

        def shifted(x):
            x = np.asarray(x, float)
            padded = np.concatenate([x, np.full(tail, x[-1]), np.full(nfft - n - tail, x[0])])
            return np.fft.irfft(np.fft.rfft(padded) * ramp, nfft)[:n]
        out.append({ch: shifted(x) for ch, x in s.items()})
    return out, lags


def stack_shots(shots: Sequence[Mapping[str, np.ndarray]], max_curves: int = MAX_CURVES, ref: str | None = None,
                band: tuple[float, float] | None = None):
    """At most ``max_curves`` records per channel: beyond that, consecutive shots averaged in
    groups of ONE size, so every group has the same
    noise: the curves are measured per group and their scatter over the groups gives the sigma
    as over shots (a scatter of groups of 1 and 2 shots mixes two noise levels; issue 24,
    session 28), and each group's noise falls as 1 / sqrt(size), raising the SNR of a weak
    band edge before its pick. The size: from ceil(n / max_curves) up to n // 4 (at least 4
    groups for a scatter), the one that leaves the fewest shots over (then the smallest); the
    shots left over (fewer than a group) are not used and the note says so. Returns the records
    and a note ('' when nothing was averaged).

    ``ref``: the channel the shots are aligned on before averaging (``align_channel``; None: as
    recorded, on their trigger); ``band``: where their lags are measured (cycles / sample,
    ``shot_lags``). A threshold trigger on a pencil break's front moves with the
    break's force and the sample clock's phase: 24 face breaks of bench rig cfrp_pencil_2dir_s0
    averaged in pairs without it lost 9 dB at 48 kHz (issue 24, session 29)."""
    n = len(shots)
    if n <= max_curves:
        return list(shots), ""
    shots, lags = align_shots(shots, ref, band)
    lo = -(-n // max_curves)
    size = min(range(lo, max(lo, n // 4) + 1), key=lambda g: (n % g, g))
    k = n // size
    out = [{ch: np.mean([shots[j][ch] for j in range(i * size, (i + 1) * size)], axis=0) for ch in shots[0]}
           for i in range(k)]
    left = n - k * size
    ok = np.isfinite(lags)
    how = "aligned on their trigger"
    if ref is not None and ok.any():
        how = f"aligned on {ref}, shifted {np.min(lags[ok]):+.2f} .. {np.max(lags[ok]):+.2f} samples"
        how += f", {int((~ok).sum())} shot(s) as recorded (no clear correlation)" if not ok.all() else ""
    return out, (f"{n} wave shots averaged in {k} groups of {size} ({how}); curves and their "
                 "scatter from the groups"
                 + (f"; the last {left} shot(s), fewer than a group, not used" if left else ""))


#: the relative sigma more shots should bring a point to: the 1 % the features are held to, at 2 sigma
TARGET_REL = 0.005


def more_shots_note(curve: str, points, held: float = 0.01, target: float = TARGET_REL) -> str:
    """A console line for the points of ``curve`` (e.g. 'S0 along 0 deg') whose sigma exceeds
    ``held`` of their velocity: how many shots per burst would bring each to ``target`` at the
    least, sigma x sqrt(n / N) (the shots' noise alone; on the sweep rig, 3 noise seeds, both
    files, the median sigma fell to 0.58-0.64 of its 2-shot value with 6 shots (sqrt: 0.58) and
    to 0.40-0.56 with 16 (0.35): the bias terms in it do not fall; bench/RESULTS.md, issue 24,
    session 28).
    ``points``: (frequency Hz, sigma / velocity, shots per burst (of the run without a sweep),
    [centre frequencies Hz of the bursts combined in it, none without a sweep]). '' when none
    exceeds."""
    parts = []
    for f, rel, n, bursts in points:
        if not (rel > held and n > 0):
            continue
        need = math.ceil(n * (rel / target) ** 2)
        which = " and ".join(f"{b / 1e3:.4g}" for b in bursts)
        of = f" of the {which} kHz burst{'s' if len(bursts) > 1 else ''}" if bursts else ""
        parts.append(f"{f / 1e3:.0f} kHz: sigma {100 * rel:.1f} % from {n} shots{of}; {100 * target:.1f} % needs "
                     f"{need} or more")
    if not parts:
        return ""
    return (f"more shots: {curve}, " + "; ".join(parts) + f" (sigma x sqrt(shots / N), the shots' noise alone; "
            f"the features are held to {100 * held:.0f} %)")
