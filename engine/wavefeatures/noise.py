"""One estimate of a wave record's noise std, for the picks' SNR test and sigmas
(``picks.noise_rms``), the crosstalk bound (``crosstalk.noise_std``) and the band check
(``band.analysis_band``).

In time: the record's wave-free parts are its pre-trigger samples (the first 0.8 x ``pre``)
and its last quarter (a record triggered on a sensor holds a packet, or the source, before
its trigger; one whose source is recorded ends quiet). Each is cut in 64-sample blocks; a
part's level is the MEDIAN of its blocks' std (a packet or a coda swell in fewer than half the
blocks does not move it), and the noise is the quieter part's. (The smallest block's std, used
before session 29, reads 17-22 % under white noise's std for 38-150 blocks.)

In frequency, when neither part is wave-free: a pencil break triggered on a sensor starts its
record after the break (bench rig cfrp_pencil_2dir_s0: 64 us after it, its quasi-static strain
and A0 coda fill the whole record: the median block std read 0.29 mV on the far sensor and
3.5 mV on the trigger sensor for a pair of breaks whose noise is 0.145 mV); a record without a
pre-trigger ends in its coda (eriknbd's line scan: the tail read 0.7-2.4 mV). So the record's
complex Morlet scalogram |W| is taken on 16 rows over 0.2-0.45 x the sample rate (above the
packets of a plate: a pencil's 400 kHz of the bench rigs is 0.2 x 2 MHz), each row's level the
lower quartile of |W| over time (edges cut) scaled to a std by the Rayleigh law of noise-only
|W| (quartile = rms sqrt(ln 4/3)): a packet in under ~half a row's time leaves it near the
noise. Where those rows are white (the median of the upper 8 within 20 % of the lower 8's; a
row is good to ~8 % on 4096 samples) their median is white noise's std, and it replaces the
time estimate when that one is over 1.2 x it (signal in the "wave-free" parts). Else (coloured
noise: Yeum et al.'s records fall 20 dB over that band, eriknbd's 250 kHz file 1.3 x; or
packets up there) the time estimate stands: a white level read above the band would be 11-330 x
under Yeum's pre-trigger noise. Units: those of the record.
"""
from __future__ import annotations

import hashlib

import numpy as np

from .. import waves

__all__ = ["BLOCK", "HIGH_BAND", "noise_level", "white_level"]

BLOCK = 64    # samples per block: the std of one block of white noise is good to ~9 %
HIGH_BAND = (0.2, 0.45)     # the rows of the white level, x the sample rate
_ROWS, _Q, _WHITE, _OVER = 16, 0.25, 1.2, 1.2
_WL = waves.Wavelet(2.0, 3.0)    # +-10 % in frequency: rows 1.7 % of the rate apart overlap
_SEEN: dict = {}                 # white_level per record digest, the oldest dropped past 1024


def white_level(x: np.ndarray, fs: float) -> float | None:
    """The std of white noise that the record's scalogram rows over ``HIGH_BAND`` read (module
    docstring), None when those rows are not white (their upper half's median more than 20 %
    from their lower half's) or the record is under 256 samples. Remembered per record (its
    bytes' digest): the picks, the survey and the crosstalk ask again per wavelet and direction
    (1773 calls for 290 records, 6.2 of 32 s CPU, on an 80-shot sweep of bench rig
    cfrp_pzt_sweep_2dir_far_pre; ~4 ms each)."""
    x = np.asarray(x, float)
    if x.size < 256:
        return None
    key = (hashlib.blake2b(x.tobytes(), digest_size=16).digest(), x.size, float(fs))
    if key not in _SEEN:
        if len(_SEEN) >= 1024:
            _SEEN.pop(next(iter(_SEEN)))
        _SEEN[key] = _white_level(x, fs)
    return _SEEN[key]


def _white_level(x: np.ndarray, fs: float) -> float | None:
    n = x.size
    f = np.linspace(HIGH_BAND[0] * fs, HIGH_BAND[1] * fs, _ROWS)
    W = np.abs(waves.cwt(x - x.mean(), fs, f, _WL))
    cut = np.ceil(3 * _WL.scales(f, fs) * np.sqrt(_WL.bandwidth / 2)).astype(int)   # 3 envelope sd
    q = np.array([np.quantile(W[i, c:n - c], _Q) for i, c in enumerate(cut)])
    s = q / (waves.white_noise_level(1.0, fs, f, _WL) * np.sqrt(-np.log(1 - _Q)))
    lo, hi = float(np.median(s[:_ROWS // 2])), float(np.median(s[_ROWS // 2:]))
    if not (lo > 0 and hi > 0) or max(lo / hi, hi / lo) > _WHITE:
        return None
    return float(np.median(s))


def noise_level(x: np.ndarray, pre: int, fs: float | None = None) -> tuple[float, float | None] | None:
    """(std, baseline) of record ``x`` whose first ``pre`` samples precede the trigger: the
    std is the quieter of the two parts' median block std, or, with the rate ``fs`` (Hz), the
    white level above the packets when the parts read over 1.2 x it (module docstring); the
    baseline is the median of the pre-trigger blocks' means when that part is the quieter and
    wave-free, else None (the caller's choice: a tail holds the coda, a slow swing off the
    baseline). None when neither part holds a 64-sample block."""
    x = np.asarray(x, float)
    m = int(0.8 * pre)
    levels = []
    for seg, head in ((x[:m], True), (x[-(len(x) // 4):], False)):
        blocks = [b for b in np.array_split(seg, max(len(seg) // BLOCK, 1)) if b.size >= BLOCK]
        if blocks:
            levels.append((float(np.median([np.std(b - b.mean()) for b in blocks])), head, blocks))
    if not levels:
        return None
    std, head, blocks = min(levels, key=lambda lv: lv[0])
    white = white_level(x, fs) if fs else None
    if white is not None and std > _OVER * white:
        return white, None
    return std, (float(np.median([np.mean(b) for b in blocks])) if head else None)
