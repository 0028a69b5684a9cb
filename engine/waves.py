"""High-frequency analysis: complex Morlet CWT, arrival times, group velocity.

Paper section 3 (Figs. 5-9): the scalogram |W(f, t)| of a guided-wave record
peaks, at each frequency, at the arrival time of the wave packet of that
frequency; distance / delay is the group velocity.

Wavelet: PyWavelets' complex Morlet ``cmorB-C``,
    psi(t) = (pi B)^(-1/2) exp(-t^2 / B) exp(2 i pi C t),
whose Fourier transform is the Gaussian exp(-B (w - 2 pi C)^2 / 4). At the
analysis frequency f (scale a = C fs / f samples) its energy has a time
standard deviation ``sigma_t = C sqrt(B) / (2 f)`` and a frequency standard
deviation ``sigma_f = f / (2 pi C sqrt(B))`` (sigma_t sigma_f = 1/(4 pi)).
Defaults are the paper's: B = 2, C = 1 (aluminium to 50 kHz); B = 2, C = 5
(CFRP to 200 kHz).

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
from functools import lru_cache
from typing import Literal, Sequence

import numpy as np
import pywt
from scipy.special import erf
from scipy import fft as sfft

__all__ = [
    "WaveError", "Wavelet", "PAPER_ALUMINIUM", "PAPER_CFRP", "cwt", "cwt_decimated", "white_noise_level",
    "Arrivals", "arrival_times", "velocity_gate", "expected_gate", "GroupVelocity",
    "group_velocity", "correct_dispersion_bias", "independent_points",
]


class WaveError(ValueError):
    """Inconsistent input to the wave analysis (rates, grids, gates)."""


@dataclass(frozen=True)
class Wavelet:
    """Complex Morlet wavelet ``cmorB-C``: bandwidth B, centre frequency C (dimensionless)."""

    bandwidth: float = 2.0
    center: float = 1.0

    def __post_init__(self) -> None:
        if not (self.bandwidth > 0 and self.center > 0):
            raise WaveError(f"Morlet bandwidth and centre must be > 0, got B={self.bandwidth!r}, C={self.center!r}")

    @property
    def name(self) -> str:
        """PyWavelets name, e.g. 'cmor2-1'."""
        return f"cmor{self.bandwidth:g}-{self.center:g}"

    def scales(self, freqs_hz: np.ndarray, fs_hz: float) -> np.ndarray:
        """Scales (samples) of the analysis frequencies, via ``pywt.frequency2scale``."""
        return np.asarray(pywt.frequency2scale(self.name, np.asarray(freqs_hz, float) / fs_hz))

    def time_std_s(self, f_hz):
        """Time standard deviation of the wavelet's energy at frequency f, s."""
        return self.center * np.sqrt(self.bandwidth) / (2.0 * np.asarray(f_hz, float))

    def freq_std_hz(self, f_hz):
        """Frequency standard deviation of the wavelet's energy at frequency f, Hz."""
        return np.asarray(f_hz, float) / (2.0 * np.pi * self.center * np.sqrt(self.bandwidth))


PAPER_ALUMINIUM = Wavelet(2.0, 1.0)
PAPER_CFRP = Wavelet(2.0, 5.0)


def _check_grid(x: np.ndarray, fs_hz: float, freqs: np.ndarray) -> None:
    if x.ndim != 1 or x.size < 8:
        raise WaveError(f"expected a 1-D record of at least 8 samples, got shape {x.shape}")
    if not fs_hz > 0:
        raise WaveError(f"sample rate must be > 0 Hz, got {fs_hz!r}")
    if freqs.ndim != 1 or freqs.size == 0 or not np.all((freqs > 0) & (freqs < fs_hz / 2)):
        raise WaveError(f"analysis frequencies must lie in (0, fs/2 = {fs_hz / 2:g}) Hz")


@lru_cache(maxsize=8)
def _bank_cached(freqs: tuple[float, ...], fs_hz: float, bandwidth: float, center: float, nfft: int,
                 dtype: str) -> np.ndarray:
    wavelet = Wavelet(bandwidth, center)
    a = wavelet.scales(np.asarray(freqs), fs_hz)[:, None]
    w = 2 * np.pi * sfft.fftfreq(nfft)[None, :]
    H = (np.sqrt(a) * np.exp(-bandwidth * (a * w - 2 * np.pi * center) ** 2 / 4)).astype(dtype)
    H.setflags(write=False)
    return H


def _bank(freqs: np.ndarray, fs_hz: float, wavelet: Wavelet, nfft: int, dtype: str = "float64") -> np.ndarray:
    """(nf, nfft) Fourier filters sqrt(a) exp(-B (a w - 2 pi C)^2 / 4), w in rad/sample (cached)."""
    return _bank_cached(tuple(float(f) for f in freqs), float(fs_hz), float(wavelet.bandwidth),
                        float(wavelet.center), int(nfft), dtype)


def _pad_smoothly(x: np.ndarray, nfft: int) -> np.ndarray:
    """``x`` padded to ``nfft`` samples with a raised-cosine ramp from its last sample
    back to its first: a record ending on an offset (the static strain under a
    pencil-lead step) must not meet the padding as a step, which every scale would see."""
    n = x.size
    xp = np.empty(nfft)
    xp[:n] = x
    m = nfft - n
    if m:
        r = 0.5 * (1 - np.cos(np.pi * (np.arange(1, m + 1) / (m + 1))))
        xp[n:] = x[-1] + (x[0] - x[-1]) * r
    return xp


def cwt(x: np.ndarray, fs_hz: float, freqs_hz: Sequence[float], wavelet: Wavelet = PAPER_ALUMINIUM,
        method: Literal["fft", "pywt"] = "fft", precision: Literal["single", "double"] = "single") -> np.ndarray:
    """Complex CWT W (nf, n) of record ``x`` sampled at ``fs_hz`` at the frequencies ``freqs_hz``.

    'fft': the exact analytic Morlet filter bank applied in the Fourier domain
    (record padded against wrap-around, with a smooth ramp from its last value
    back to its first); W = sum_n x[n] conj(psi_a[n - b]) / sqrt(a).
    'pywt': ``pywt.cwt(..., method='fft')`` (integrated-wavelet approximation;
    it lags the analytic transform by half a sample).
    precision: 'single' (complex64, twice as fast; relative error ~1e-7) or 'double'.
    The filter bank is cached per (grid, rate, wavelet, length).
    """
    x = np.asarray(x, float)
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    _check_grid(x, fs_hz, freqs)
    n = x.size
    if method == "pywt":
        W, _ = pywt.cwt(x, wavelet.scales(freqs, fs_hz), wavelet.name, sampling_period=1.0 / fs_hz, method="fft")
        return W
    if method != "fft":
        raise WaveError(f"cwt method must be 'fft' or 'pywt', got {method!r}")
    # pad by 4 time-std of the widest wavelet (the lowest frequency)
    pad = int(np.ceil(4 * wavelet.time_std_s(freqs.min()) * fs_hz))
    nfft = sfft.next_fast_len(n + pad)
    single = precision == "single"
    xp = _pad_smoothly(x, nfft)
    X = sfft.fft(xp.astype(np.float32) if single else xp)
    Y = X[None, :] * _bank(freqs, fs_hz, wavelet, nfft, "float32" if single else "float64")
    return sfft.ifft(Y, axis=1, workers=1, overwrite_x=True)[:, :n]


@lru_cache(maxsize=8)
def _support_bank(freqs: tuple[float, ...], fs_hz: float, bandwidth: float, center: float, nfft: int,
                  rel: float = 1e-7):
    """Per row: (k0, filter values on bins k0..k1-1) where the filter exceeds ``rel`` of its peak."""
    wavelet = Wavelet(bandwidth, center)
    a = wavelet.scales(np.asarray(freqs), fs_hz)
    half = np.sqrt(-4.0 * np.log(rel) / bandwidth)  # |a w - 2 pi C| below this
    rows = []
    for ai in a:
        w_lo = max((2 * np.pi * center - half) / ai, 0.0)
        w_hi = min((2 * np.pi * center + half) / ai, np.pi)
        k0 = int(np.floor(w_lo * nfft / (2 * np.pi)))
        k1 = int(np.ceil(w_hi * nfft / (2 * np.pi))) + 1
        w = 2 * np.pi * np.arange(k0, k1) / nfft
        h = (np.sqrt(ai) * np.exp(-bandwidth * (ai * w - 2 * np.pi * center) ** 2 / 4)).astype(np.float32)
        rows.append((k0, h))
    return tuple(rows)


def cwt_decimated(x: np.ndarray, fs_hz: float, freqs_hz: Sequence[float],
                  wavelet: Wavelet = PAPER_ALUMINIUM) -> tuple[np.ndarray, int]:
    """The same CWT as ``cwt`` (complex64), sampled every ``step`` samples: (W[:, ::step], step).

    Each row of the transform is band-limited (its Gaussian filter exceeds
    1e-7 of its peak on less than 1/step of the spectrum), so its samples at
    the stride ``step`` hold it exactly: the row's spectrum is folded onto
    nfft/step bins and one short inverse FFT per row gives them. About
    ``step`` times cheaper than ``cwt``; for display, or when the full-rate
    transform is not needed.
    """
    x = np.asarray(x, float)
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    _check_grid(x, fs_hz, freqs)
    n = x.size
    pad = int(np.ceil(4 * wavelet.time_std_s(freqs.min()) * fs_hz))
    nfft0 = sfft.next_fast_len(n + pad)
    probe = _support_bank(tuple(float(f) for f in freqs), float(fs_hz), float(wavelet.bandwidth),
                          float(wavelet.center), nfft0)
    frac = max(h.size for _, h in probe) / nfft0
    step = max(1, int(1.0 / (frac * 1.05)))
    m_len = sfft.next_fast_len(-(-nfft0 // step))
    nfft = m_len * step
    bank = _support_bank(tuple(float(f) for f in freqs), float(fs_hz), float(wavelet.bandwidth),
                         float(wavelet.center), nfft)
    xp = _pad_smoothly(x, nfft)
    X = sfft.fft(xp.astype(np.float32))
    Yf = np.zeros((freqs.size, m_len), np.complex64)
    for i, (k0, h) in enumerate(bank):
        idx = np.arange(k0, k0 + h.size) % m_len
        Yf[i, idx] = X[k0:k0 + h.size] * h
    W = sfft.ifft(Yf, axis=1, workers=1, overwrite_x=True) / step
    return W[:, :-(-n // step)], step


def white_noise_level(std: float, fs_hz: float, freqs_hz: Sequence[float],
                      wavelet: Wavelet = PAPER_ALUMINIUM) -> np.ndarray:
    """RMS of |W| (per frequency) that white noise of standard deviation ``std`` produces.

    E|W|^2 = std^2 (1/2pi) integral |sqrt(a) psi^(a w)|^2 dw = std^2 / sqrt(2 pi B), the same at
    every scale (the part of the filter beyond the Nyquist frequency is left out).
    """
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    a = wavelet.scales(freqs, fs_hz)
    B, C = wavelet.bandwidth, wavelet.center
    # fraction of the Gaussian |psi^|^2 (std 1/(a sqrt B) in w) that lies below w = pi
    frac = 0.5 * (1 + erf((np.pi - 2 * np.pi * C / a) * a * np.sqrt(B) / np.sqrt(2)))
    return std * np.sqrt(frac / np.sqrt(2 * np.pi * B))


@dataclass(frozen=True)
class Arrivals:
    """Arrival time of each analysis frequency (NaN where rejected).

    times_s: arrival times on the record's time axis.
    sigma_s: standard uncertainty of each time (w^2 / sigma_t / sqrt(2 SNR), w = max(sigma_t,
        the picked packet's energy time-std from the curvature of log|W|)).
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
                  max_notch_db: float = 3.0) -> Arrivals:
    """Arrival time of each frequency from the scalogram |W| (nf, n).

    gate_s: (lo, hi) times in s (scalars or per frequency); the arrival must be
        a maximum strictly inside it.
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
    """
    W = np.asarray(W)
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    nf, n = W.shape
    if nf != freqs.size:
        raise WaveError(f"{nf} scalogram rows for {freqs.size} frequencies")
    t = (np.arange(n) - t0_index) / fs_hz
    lo, hi = _as_gate(gate_s, nf, t)
    A = np.abs(W)
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
    for i in range(nf):
        k0 = max(int(np.ceil((lo[i] - t[0]) * fs_hz)), 0)
        k1 = min(int(np.floor((hi[i] - t[0]) * fs_hz)) + 1, n)
        if k1 - k0 < 3:
            reason[i] = "empty gate"
            continue
        a = A[i, k0:k1]
        m = a.max()
        if m <= 0:
            reason[i] = "no signal"
            continue
        inner = (a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:]) & (a[1:-1] >= first_fraction * m)
        cand = np.flatnonzero(inner) + 1
        if cand.size == 0:
            reason[i] = "peak on the gate edge"
            continue
        k = k0 + int(cand[0])
        la, lb, lc = np.log(np.maximum(A[i, k - 1:k + 2], tiny))
        den = la - 2 * lb + lc
        d = 0.5 * (la - lc) / den if den < 0 else 0.0
        # log|W| ~ -t^2 / (2 s_a^2) near a Gaussian peak; energy std = s_a / sqrt(2)
        width[i] = 1.0 / (fs_hz * np.sqrt(-2.0 * den)) if den < 0 else 0.0
        d = float(np.clip(d, -0.5, 0.5))
        times[i] = t[k] + d / fs_hz
        peak[i] = np.exp(lb - 0.25 * (la - lc) * d)
        # instantaneous frequency: phase slope around the peak, interpolated at k + d
        ph = np.unwrap(np.angle(W[i, k - 1:k + 2]))
        fi = np.diff(ph) * fs_hz / (2 * np.pi)  # at k - 1/2 and k + 1/2
        finst[i] = fi[0] + (fi[1] - fi[0]) * (d + 0.5)
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
        elif abs(finst[i] - freqs[i]) > max_freq_offset * wavelet.freq_std_hz(freqs[i]):
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
        sigma = np.sqrt((teff / np.sqrt(2 * snr_lin)) ** 2 + (1.0 / (fs_hz * np.sqrt(12)) / 10) ** 2)
    return Arrivals(freqs, times, sigma, snr, finst, valid, tuple(reason), wavelet)


def correct_dispersion_bias(arr: Arrivals, degree: int = 3) -> Arrivals:
    """Arrivals with the wavelet's dispersion-curvature bias removed.

    For a chirped packet with group delay tau(w) analysed by a Gaussian
    window of amplitude std s (rad/s), the scalogram maximum lies later than
    the group delay at the instantaneous frequency by
        delta = tau'' / 2 * a / (a^2 + tau'^2),   a = 1 / s^2,
    (second-order expansion, ``docs/wavelet-bias.md``); tau', tau'' are taken
    from a smooth fit (polynomial of ``degree`` in ln w, weighted by 1/sigma)
    of the measured delays against the instantaneous frequencies. Needs at
    least degree + 2 valid frequencies; returned unchanged otherwise. A quarter
    of the correction is added (in quadrature) to ``sigma_s`` for the
    neglected higher-order terms.
    """
    ok = arr.valid & np.isfinite(arr.inst_freq_hz) & (arr.inst_freq_hz > 0)
    if ok.sum() < degree + 2:
        return arr
    w = 2 * np.pi * arr.inst_freq_hz
    x = np.log(w[ok])
    c = np.polynomial.polynomial.polyfit(x - x.mean(), arr.times_s[ok], degree, w=1.0 / arr.sigma_s[ok])
    xx = np.log(np.where(ok, w, 1.0)) - x.mean()
    d1 = np.polynomial.polynomial.polyval(xx, np.polynomial.polynomial.polyder(c, 1))
    d2 = np.polynomial.polynomial.polyval(xx, np.polynomial.polynomial.polyder(c, 2))
    ww = np.where(ok, w, 1.0)
    tau1 = d1 / ww
    tau2 = (d2 - d1) / ww ** 2
    wl = arr.wavelet
    s = 2 * np.pi * arr.frequencies_hz * np.sqrt(2.0 / wl.bandwidth) / (2 * np.pi * wl.center)
    a = 1.0 / s ** 2
    delta = np.where(ok, 0.5 * tau2 * a / (a ** 2 + tau1 ** 2), 0.0)
    # the neglected higher-order terms: a quarter of the correction, as a systematic uncertainty
    return replace(arr, times_s=arr.times_s - delta, sigma_s=np.hypot(arr.sigma_s, 0.25 * delta))


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


@dataclass(frozen=True)
class GroupVelocity:
    """Group velocity per frequency (NaN where invalid)."""

    frequencies_hz: np.ndarray
    velocity_m_s: np.ndarray
    sigma_m_s: np.ndarray
    valid: np.ndarray


def group_velocity(far: Arrivals, distance_m: float, near: Arrivals | None = None, *,
                   near_distance_m: float = 0.0, source_time_s: float = 0.0,
                   assign: Literal["nominal", "instantaneous"] = "instantaneous") -> GroupVelocity:
    """Group velocity from arrival times.

    Source to sensor: ``(distance_m - near_distance_m) / (t_far - t_near)``,
    ``t_near`` from ``near`` (the force channel's or a nearer sensor's
    arrivals), else ``source_time_s``.
    assign: 'nominal' gives each velocity the analysis frequency (the paper);
    'instantaneous' gives it the instantaneous frequency of the far record at
    its arrival and interpolates back onto the analysis grid (where the
    reassigned frequencies increase monotonically), which removes the wavelet
    bandwidth bias.
    """
    d = distance_m - near_distance_m
    if not d > 0:
        raise WaveError(f"propagation distance must be > 0 m, got {d!r}")
    t1 = near.times_s if near is not None else np.full(far.times_s.shape, float(source_time_s))
    s1 = near.sigma_s if near is not None else np.zeros(far.times_s.shape)
    ok1 = near.valid if near is not None else np.ones(far.times_s.shape, bool)
    delay = far.times_s - t1
    valid = far.valid & ok1 & (delay > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(valid, d / delay, np.nan)
        sv = np.where(valid, v * np.hypot(far.sigma_s, s1) / delay, np.nan)
    f = far.frequencies_hz
    if assign == "nominal":
        return GroupVelocity(f, v, sv, valid)
    if assign != "instantaneous":
        raise WaveError(f"assign must be 'nominal' or 'instantaneous', got {assign!r}")
    fi = far.inst_freq_hz
    idx = np.flatnonzero(valid)
    # keep the longest run where the reassigned frequency increases
    keep = np.zeros(f.size, bool)
    if idx.size >= 2:
        inc = np.diff(fi[idx]) > 0
        best, start = (0, 0), 0
        for j in range(1, idx.size + 1):
            if j == idx.size or not inc[j - 1]:
                if j - start > best[1] - best[0]:
                    best = (start, j)
                start = j
        keep[idx[best[0]:best[1]]] = True
    if keep.sum() < 2:
        return GroupVelocity(f, np.full(f.shape, np.nan), np.full(f.shape, np.nan), np.zeros(f.shape, bool))
    fk, vk, sk = fi[keep], v[keep], sv[keep]
    # only where the frequency's own arrival was accepted: no bridging over rejected ones
    inside = (f >= fk[0]) & (f <= fk[-1]) & valid
    vi = np.where(inside, np.interp(f, fk, vk), np.nan)
    si = np.where(inside, np.interp(f, fk, sk), np.nan)
    return GroupVelocity(f, vi, si, inside)


def independent_points(freqs_hz: Sequence[float], valid: np.ndarray, wavelet: Wavelet,
                       spacing: float = 2.0 * np.sqrt(2.0)) -> np.ndarray:
    """Mask of valid frequencies at least ``spacing`` wavelet frequency-stds apart.

    Ridge points closer than the wavelet's frequency resolution share most of
    its energy: for white noise the CWT coefficients at two frequencies d
    energy-stds apart correlate as exp(-d^2/8), so the default spacing 2*sqrt(2)
    keeps that correlation at 1/e or less. A fit that whitens by each point's
    sigma must see only nearly independent points, or its covariance is too
    small by about the square root of the oversampling. Greedy from the lowest
    frequency up; ``spacing`` in units of ``Wavelet.freq_std_hz``.
    """
    f = np.asarray(freqs_hz, float)
    keep = np.zeros(f.shape, bool)
    last = -np.inf
    for i in np.flatnonzero(np.asarray(valid, bool)):
        # the std at the upper point (the wider of the two spectra): conservative
        if not np.isfinite(last) or f[i] - last >= spacing * float(wavelet.freq_std_hz(f[i])):
            keep[i] = True
            last = f[i]
    return keep
