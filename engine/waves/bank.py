"""Complex Morlet CWT as an analytic filter bank applied in the Fourier domain.

At the analysis frequency f the wavelet's scale is a = C fs / f samples
(``Wavelet.scales``); its Fourier transform is the Gaussian
exp(-B (a w - 2 pi C)^2 / 4), applied to one FFT of the (padded) record, one
batched inverse FFT for all frequencies. Units: Hz, samples.

Why hand-written (measured, kept on purpose): on a 10,000-sample record over
100 frequencies this bank is 3-5x faster than ``pywt.cwt(method='fft')``
(bench/bench_waves.py, bench/RESULTS.md "engine.waves CWT") and is the exact
analytic transform, where PyWavelets' integrated-wavelet approximation lags it
by half a sample; ``tests/test_waves.py::test_fft_cwt_matches_pywavelets`` pins
the agreement (within 1 % of the peak once shifted by half a sample), and
``method='pywt'`` keeps PyWavelets' transform at hand.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Literal, Sequence

import numpy as np
import pywt
from scipy import fft as sfft
from scipy.special import erf

from .wavelet import PAPER_ALUMINIUM, Wavelet, WaveError

__all__ = ["cwt", "cwt_decimated", "white_noise_level"]


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


@lru_cache(maxsize=32)
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


@lru_cache(maxsize=32)
def _folding(freqs: tuple[float, ...], fs_hz: float, bandwidth: float, center: float, nfft: int, m_len: int):
    """(source bins, destination indices in the flat (nf, m_len) array, filter values) of every
    row of ``_support_bank`` folded onto ``m_len`` bins: one fancy assignment instead of a
    Python loop over the rows (issue 24, session 28: the loop was 58 % of ``cwt_decimated``).
    A row wider than ``m_len`` (never met: the step leaves 5 % room) would fold onto itself;
    the later bins then win, as they did in the loop."""
    rows = _support_bank(freqs, fs_hz, bandwidth, center, nfft)
    src = np.concatenate([np.arange(k0, k0 + h.size) for k0, h in rows])
    dst = np.concatenate([i * m_len + np.arange(k0, k0 + h.size) % m_len for i, (k0, h) in enumerate(rows)])
    h = np.concatenate([h for _, h in rows])
    for a in (src, dst, h):
        a.setflags(write=False)
    return src, dst, h


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
    xp = _pad_smoothly(x, nfft)
    X = sfft.fft(xp.astype(np.float32))
    src, dst, h = _folding(tuple(float(f) for f in freqs), float(fs_hz), float(wavelet.bandwidth),
                           float(wavelet.center), nfft, m_len)
    Yf = np.zeros(freqs.size * m_len, np.complex64)
    Yf[dst] = X[src] * h
    W = sfft.ifft(Yf.reshape(freqs.size, m_len), axis=1, workers=1, overwrite_x=True) / step
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
