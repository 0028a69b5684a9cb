"""Arrival time of each analysis frequency from a scalogram, its bias correction and gates.

Arrival of a frequency: the first maximum of the scalogram in a time gate
(so that edge reflections and the other mode cannot capture it), refined by a
parabola through log|W| (exact for a Gaussian envelope). Frequency of an
arrival: either the nominal analysis frequency (the paper) or the
instantaneous frequency of W at the arrival ("reassigned"), which removes
the bias the wavelet's finite bandwidth causes on a dispersive signal with
a sloping spectrum (``docs/wavelet-bias.md``).

Units: s, Hz, m, m/s. Times are on the record's axis: t = (n - t0_index) / fs.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from .wavelet import PAPER_ALUMINIUM, Wavelet, WaveError

__all__ = ["Arrivals", "arrival_times", "correct_dispersion_bias", "ridge_points", "velocity_gate", "expected_gate"]


@dataclass(frozen=True)
class Arrivals:
    """Arrival time of each analysis frequency (NaN where rejected).

    times_s: arrival times on the record's time axis.
    sigma_s: standard uncertainty of each time (w^2 / sigma_t / sqrt(2 SNR) * sqrt(1 + x^2),
        w = max(sigma_t, the picked packet's energy time-std from the curvature of log|W|),
        x = (instantaneous - analysis frequency) / the wavelet's frequency std).
    snr_db: scalogram peak over the noise level at that frequency.
    inst_freq_hz: instantaneous frequency of W at the arrival.
    valid: accepted (inside the gate, enough energy, no leakage from other frequencies).
    reason: '' or why a frequency was rejected.
    """

    frequencies_hz: np.ndarray
    times_s: np.ndarray
    sigma_s: np.ndarray
    snr_db: np.ndarray
    inst_freq_hz: np.ndarray
    valid: np.ndarray
    reason: tuple[str, ...]
    wavelet: Wavelet


def _as_gate(gate, nf: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if gate is None:
        return np.full(nf, t[0]), np.full(nf, t[-1])
    lo, hi = (np.broadcast_to(np.asarray(g, float), (nf,)).copy() for g in gate)
    return lo, hi


def arrival_times(W: np.ndarray, fs_hz: float, freqs_hz: Sequence[float], wavelet: Wavelet = PAPER_ALUMINIUM, *,
                  t0_index: int = 0, gate_s=None, first_fraction: float = 0.5,
                  noise_rms: np.ndarray | float | None = None, min_snr_db: float = 20.0,
                  min_rel_db: float = -30.0, max_freq_offset: float = 1.0,
                  max_notch_db: float = 3.0, A: np.ndarray | None = None) -> Arrivals:
    """Arrival time of each frequency from the scalogram |W| (nf, n).

    gate_s: (lo, hi) times in s (scalars or per frequency); the arrival must be
        a maximum strictly inside it (a NaN gate: the frequency is rejected).
    first_fraction: the first local maximum reaching this fraction of the
        gate's maximum is the arrival (the direct wave, not a later echo).
    noise_rms: RMS of |W| of the noise per frequency (``white_noise_level``
        of the pre-trigger noise); if None the SNR is not checked (inf).
    min_snr_db: reject weaker arrivals. min_rel_db: reject frequencies whose
        peak is that far below the strongest frequency's.
    max_freq_offset: reject arrivals whose instantaneous frequency is more
        than this many wavelet frequency-std away from the analysis frequency
        (the scalogram there shows leakage of other frequencies).
    max_notch_db: reject frequencies sitting in a spectral notch (e.g. a zero
        of the hammer spectrum): where the peak level, averaged over the
        frequencies one wavelet frequency-std either side, exceeds the level
        at the frequency by more than this (the window then straddles a sign
        change of the spectrum and the ridge is not the group delay).
    A: |W| when the caller has it (a scalogram read by several picks).
    """
    W = np.asarray(W)
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    nf, n = W.shape
    if nf != freqs.size:
        raise WaveError(f"{nf} scalogram rows for {freqs.size} frequencies")
    t = (np.arange(n) - t0_index) / fs_hz
    lo, hi = _as_gate(gate_s, nf, t)
    A = np.abs(W) if A is None else A
    tiny = np.finfo(float).tiny
    times = np.full(nf, np.nan)
    finst = np.full(nf, np.nan)
    peak = np.zeros(nf)
    noise = np.full(nf, np.nan)
    reason = [""] * nf
    tstd = wavelet.time_std_s(freqs)
    width = np.zeros(nf)  # energy time-std of the picked packet, from the curvature of log|W|
    if noise_rms is not None:
        noise = np.broadcast_to(np.asarray(noise_rms, float), (nf,)).copy()
    k, ok = _first_peaks(A, t, fs_hz, lo, hi, first_fraction, reason)
    rows, k = np.flatnonzero(ok), k[ok]
    # the parabola through log|W| at the peak, every row at once (the same float operations as
    # the per-row loop they replace, in the same order and precision: outputs equal bit for bit;
    # issue 24, session 29: that loop was a sixth of a sweep's analysis)
    la, lb, lc = (np.log(np.maximum(A[rows, k + j], tiny)) for j in (-1, 0, 1))
    den = la - 2 * lb + lc
    curved = den < 0
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(curved, 0.5 * (la - lc) / den, 0.0)
        # log|W| ~ -t^2 / (2 s_a^2) near a Gaussian peak; energy std = s_a / sqrt(2)
        width[rows] = np.where(curved, 1.0 / (fs_hz * np.sqrt(-2.0 * den)), 0.0)
    d = np.clip(d, -0.5, 0.5)
    times[rows] = t[k] + d / fs_hz
    peak[rows] = np.exp(lb - 0.25 * (la - lc) * d)
    # instantaneous frequency: phase slope around the peak, interpolated at k + d
    ph = np.angle(W[rows[:, None], k[:, None] + np.arange(-1, 2)])
    dph = ph[:, 1:] - ph[:, :-1]
    fi = dph * fs_hz / (2 * np.pi)  # at k - 1/2 and k + 1/2
    # d is a Python float in the per-row form: it then takes fi's precision
    finst[rows] = fi[:, 0] + (fi[:, 1] - fi[:, 0]) * (d + 0.5).astype(fi.dtype)
    for j in np.flatnonzero(~(np.abs(dph) < np.pi).all(axis=1)):
        # a jump of pi or more: np.unwrap's correction (without one, np.unwrap returns
        # the phases unchanged and this skips its cost: 13 % of a sweep's analysis)
        fj = np.diff(np.unwrap(ph[j])) * fs_hz / (2 * np.pi)
        finst[rows[j]] = fj[0] + (fj[1] - fj[0]) * (float(d[j]) + 0.5)
    snr = 20 * np.log10(np.maximum(peak, tiny) / np.maximum(noise, tiny))
    snr[~np.isfinite(noise)] = np.inf
    rel = 20 * np.log10(np.maximum(peak, tiny) / max(peak.max(), tiny))
    valid = np.isfinite(times)
    lp = np.log(np.maximum(peak, tiny))
    sf = wavelet.freq_std_hz(freqs)
    if nf >= 3:
        side = 0.5 * (np.interp(freqs - sf, freqs, lp) + np.interp(freqs + sf, freqs, lp))
        notch = 20 / np.log(10) * (side - lp)
        edge = (freqs - sf < freqs[0]) | (freqs + sf > freqs[-1])
        notch[edge] = -np.inf  # one-sided at the ends of the grid: not judged
    else:
        notch = np.full(nf, -np.inf)
    for i in range(nf):
        if not valid[i]:
            continue
        if snr[i] < min_snr_db:
            reason[i] = f"SNR {snr[i]:.1f} dB < {min_snr_db:g} dB"
        elif rel[i] < min_rel_db:
            reason[i] = f"energy {rel[i]:.1f} dB below the strongest frequency"
        elif abs(finst[i] - freqs[i]) > max_freq_offset * sf[i]:
            reason[i] = f"leakage: instantaneous frequency {finst[i]:.4g} Hz"
        elif notch[i] > max_notch_db:
            reason[i] = f"spectral notch ({notch[i]:.1f} dB below its neighbours)"
        if reason[i]:
            valid[i] = False
    snr_lin = np.where(np.isfinite(snr), 10 ** (np.minimum(snr, 200) / 10), np.inf)
    with np.errstate(divide="ignore"):
        # a packet longer than the wavelet (a broad source pulse seen through a short
        # wavelet) has a flatter maximum (curvature ~ 1/width^2) while the noise in |W|
        # varies on the wavelet's scale: the peak moves by ~ width^2 / tstd / sqrt(2 SNR)
        teff = np.maximum(tstd, width) ** 2 / tstd
        # off the packet's own frequency (a band's ends: finst != f) the noise in W turns at
        # f while the packet's phase turns at finst: the in-phase noise then varies faster,
        # its slope's variance grows by 1 + (dw / s_w)^2 (dw = 2 pi (finst - f), s_w the
        # wavelet's angular frequency std, 2 tstd s_w = 1). Measured on numpy records of a
        # Hann burst + white noise, 300 draws: scatter / old sigma 1.0 at the centre, 1.3-1.9
        # at 0.9-1.5 frequency std off (tests/unit/engine/test_wave_arrival_sigma.py).
        off = np.where(np.isfinite(finst), (finst - freqs) / sf, 0.0)
        teff = teff * np.sqrt(1.0 + off ** 2)
        sigma = np.sqrt((teff / np.sqrt(2 * snr_lin)) ** 2 + (1.0 / (fs_hz * np.sqrt(12)) / 10) ** 2)
    return Arrivals(freqs, times, sigma, snr, finst, valid, tuple(reason), wavelet)


def _first_peaks(A: np.ndarray, t: np.ndarray, fs_hz: float, lo: np.ndarray, hi: np.ndarray,
                 first_fraction: float, reason: list) -> tuple[np.ndarray, np.ndarray]:
    """Per row of |W|, the sample of the first local maximum strictly inside the gate [lo, hi] (s)
    reaching ``first_fraction`` of the gate's maximum: (k, found); ``reason`` says why not.
    The windows are gathered into one (rows, widest window) array."""
    nf, n = A.shape
    k = np.zeros(nf, int)
    fin = np.isfinite(lo) & np.isfinite(hi)
    k0 = np.zeros(nf, int)
    k1 = np.zeros(nf, int)
    k0[fin] = np.maximum(np.ceil((lo[fin] - t[0]) * fs_hz), 0)
    k1[fin] = np.minimum(np.floor((hi[fin] - t[0]) * fs_hz) + 1, n)
    wide = fin & (k1 - k0 >= 3)
    for i in np.flatnonzero(~wide):
        reason[i] = "empty gate"
    rows = np.flatnonzero(wide)
    if rows.size == 0:
        return k, np.zeros(nf, bool)
    w = k1[rows] - k0[rows]
    j = np.arange(int(w.max()))
    a = A[rows[:, None], np.minimum(k0[rows, None] + j, n - 1)]
    inside = j < w[:, None]
    m = np.where(inside, a, 0).max(axis=1)
    signal = m > 0
    inner = np.zeros(a.shape, bool)
    inner[:, 1:-1] = ((a[:, 1:-1] >= a[:, :-2]) & (a[:, 1:-1] > a[:, 2:])
                      & (a[:, 1:-1] >= first_fraction * m[:, None]) & (j[1:-1] <= w[:, None] - 2))
    has = inner.any(axis=1)
    first = np.argmax(inner, axis=1)
    for r, i in enumerate(rows):
        if not signal[r]:
            reason[i] = "no signal"
        elif not has[r]:
            reason[i] = "peak on the gate edge"
    found = np.zeros(nf, bool)
    found[rows] = signal & has
    k[rows] = k0[rows] + first
    return k, found


def correct_dispersion_bias(arr: Arrivals, degree: int = 3) -> Arrivals:
    """Arrivals with the wavelet's dispersion-curvature bias removed.

    For a chirped packet with group delay tau(w) analysed by a Gaussian
    window of amplitude std s (rad/s), the scalogram maximum lies later than
    the group delay at the instantaneous frequency by
        delta = tau'' / 2 * a / (a^2 + tau'^2),   a = 1 / s^2,
    (second-order expansion, ``docs/wavelet-bias.md``); tau', tau'' are taken
    from a smooth fit (polynomial of ``degree`` in ln w, weighted by 1/sigma)
    of the measured delays against the instantaneous frequencies. Needs at
    least degree + 2 valid frequencies whose instantaneous frequencies span at least the
    wavelet's frequency std; returned unchanged otherwise. A quarter
    of the correction is added (in quadrature) to ``sigma_s`` for the
    neglected higher-order terms. The fit takes only the points on one smooth ridge
    (``ridge_points``): a pick of another packet (a lobe of a spectral notch, a
    neighbour) bent the cubic, and with it the correction of every other frequency; those
    picks are returned invalid ("off the packet's smooth ridge"). When fewer than half the
    valid picks lie on one ridge, the arrivals are returned unchanged.
    """
    ok = arr.valid & np.isfinite(arr.inst_freq_hz) & (arr.inst_freq_hz > 0)
    if ok.sum() < degree + 2:
        return arr
    w = 2 * np.pi * arr.inst_freq_hz
    wl = arr.wavelet
    s = 2 * np.pi * arr.frequencies_hz * np.sqrt(2.0 / wl.bandwidth) / (2 * np.pi * wl.center)
    if np.ptp(w[ok]) < np.median(s[ok]):
        # the instantaneous frequencies span less than the wavelet's frequency std: tau'' is
        # not determined (a long tone burst reassigns every analysis frequency into a few kHz:
        # the fit then moved a 250 kHz A0 pick by 13 us; bench/RESULTS.md, issue 24, session 27)
        return arr
    ridge = ridge_points(arr.inst_freq_hz, arr.times_s, arr.sigma_s, wl.time_std_s(arr.frequencies_hz), ok, degree,
                         least=0.5)
    if ridge.sum() < max(degree + 2, 0.5 * ok.sum()) or np.ptp(w[ridge]) < np.median(s[ridge]):
        # most picks on no one smooth ridge (a short wavelet across a notch: two lobes): tau''
        # is not determined; the picks stay as they are
        return arr
    off = ok & ~ridge      # picks of another packet: not this packet's group delay either
    ok = ridge
    x = np.log(w[ok])
    c = np.polynomial.polynomial.polyfit(x - x.mean(), arr.times_s[ok], degree, w=1.0 / arr.sigma_s[ok])
    xx = np.log(np.where(ok, w, 1.0)) - x.mean()
    d1 = np.polynomial.polynomial.polyval(xx, np.polynomial.polynomial.polyder(c, 1))
    d2 = np.polynomial.polynomial.polyval(xx, np.polynomial.polynomial.polyder(c, 2))
    ww = np.where(ok, w, 1.0)
    tau1 = d1 / ww
    tau2 = (d2 - d1) / ww ** 2
    a = 1.0 / s ** 2
    delta = np.where(ok, 0.5 * tau2 * a / (a ** 2 + tau1 ** 2), 0.0)
    # the neglected higher-order terms: a quarter of the correction, as a systematic uncertainty
    reason = tuple("off the packet's smooth ridge" if o else r for o, r in zip(off, arr.reason))
    return replace(arr, times_s=arr.times_s - delta, sigma_s=np.hypot(arr.sigma_s, 0.25 * delta),
                   valid=arr.valid & ~off, reason=reason)


def ridge_points(f_hz, t_s, sigma_s, tstd_s, valid, degree: int = 3, frac: float = 0.1, k: float = 3.0,
                 least: float = 0.0) -> np.ndarray:
    """The ``valid`` arrivals on one smooth ridge: the others, picks of another packet, left out.

    A polynomial of ``degree`` in ln f (weights 1 / sigma) is fitted to the times; the point
    farthest from it (relative to its limit) goes when it is off by more than ``frac`` of the
    wavelet's time std at its frequency (``tstd_s``) and more than ``k`` of its own sigma, and
    the fit is redone, until none is. One packet's ridge is smooth on that scale (its group
    delay bends over many frequency stds); the lobes either side of a spectral zero, or a
    neighbouring packet, lie a good part of a time std off it (A0 along 90 deg, 100 kHz burst,
    a PZT's aperture zero: picks 40-50 us off a ridge whose other points lie within 0.2 us; the
    time std of cmor2-5 is 35 us there: issue 24, session 30). Returns the mask (``valid`` when
    it holds degree + 2 points or fewer); ``least``: stop once fewer than this fraction of
    ``valid`` remain (the caller then takes no ridge)."""
    keep = np.asarray(valid, bool).copy()
    f, t, sig, lim = (np.asarray(a, float) for a in (f_hz, t_s, sigma_s, tstd_s))
    x = np.log(np.where(keep, f, 1.0))
    floor = max(degree + 2, least * keep.sum())
    if keep.sum() <= degree + 2:
        return keep
    # polyfit's weighted least squares on one Vandermonde matrix: polyfit's set-up per fit took
    # 0.92 s of a profiled 80-shot sweep's analysis (208 calls), this 0.54 s
    V = np.vander(x - x[keep].mean(), degree + 1, increasing=True)
    wt = np.where(keep, 1.0 / np.where(keep, sig, 1.0), 0.0)
    tt = np.where(keep, t, 0.0)
    lim = np.maximum(frac * lim, k * np.where(keep, sig, 1.0))
    while keep.sum() > degree + 2 and keep.sum() >= floor:
        c = np.linalg.lstsq(V[keep] * wt[keep, None], tt[keep] * wt[keep], rcond=None)[0]
        score = np.where(keep, np.abs(tt - V @ c) / lim, 0.0)
        j = int(np.argmax(score))
        if score[j] <= 1.0:
            break
        keep[j] = False
    return keep


def velocity_gate(distance_m: float, v_min: float, v_max: float, source_time_s: float = 0.0) -> tuple[float, float]:
    """Time gate (s) for waves from a source at ``source_time_s`` travelling ``distance_m`` at v_min..v_max (m/s)."""
    if not 0 < v_min < v_max:
        raise WaveError(f"velocity gate needs 0 < v_min < v_max, got {v_min!r}, {v_max!r}")
    return source_time_s + distance_m / v_max, source_time_s + distance_m / v_min


def expected_gate(distance_m: float, cg_expected: np.ndarray, *, margin: float = 0.25,
                  source_time_s: float | np.ndarray = 0.0, reflection_m: float | None = None,
                  faster_cg: np.ndarray | None = None, slower_cg: np.ndarray | None = None,
                  time_std_s: np.ndarray | float = 0.0, clearance: float = 3.0,
                  mode_clearance: float = 1.0, echo_margin: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-frequency gate (s) around an expected group velocity curve (m/s).

    Arrivals between ``distance / (cg (1 + margin))`` and ``distance / (cg (1 - margin))``
    after the source. Closed ``clearance`` wavelet time-std (``time_std_s``,
    from ``Wavelet.time_std_s``) before the earliest echo over
    ``reflection_m`` (shortest reflected path) travelling at up to
    ``cg (1 + echo_margin)`` (default: ``margin``; a smaller one when the
    nominal velocities are known better than the gate's width), and opened as long after the
    latest possible arrival of a faster mode (``faster_cg``, e.g. S0 when
    picking A0), and before the earliest arrival of a slower mode
    (``slower_cg``, e.g. A0 when picking S0), so that none can pull the
    scalogram maximum (|psi| has an amplitude std of sqrt(2) time-std, hence
    the default echo clearance of 3). The other mode gets ``mode_clearance``
    (default 1) time-std only: under a normal force S0 is much weaker than A0,
    and a long wavelet (C = 5) would otherwise leave no gate at low frequency.
    Where they leave no room the gate is empty and the frequency is rejected.
    """
    cg = np.asarray(cg_expected, float)
    ts = np.asarray(time_std_s, float)
    lo = source_time_s + distance_m / (cg * (1 + margin))
    hi = source_time_s + distance_m / (cg * (1 - margin))
    if reflection_m is not None:
        em = margin if echo_margin is None else echo_margin
        hi = np.minimum(hi, source_time_s + reflection_m / (cg * (1 + em)) - clearance * ts)
    if faster_cg is not None:
        fast = np.asarray(faster_cg, float)
        lo = np.maximum(lo, source_time_s + distance_m / (fast * (1 - margin)) + mode_clearance * ts)
    if slower_cg is not None:
        slow = np.asarray(slower_cg, float)
        hi = np.minimum(hi, source_time_s + distance_m / (slow * (1 + margin)) - mode_clearance * ts)
    return lo, hi
