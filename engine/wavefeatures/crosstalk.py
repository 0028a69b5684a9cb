"""The excitation's electrical crosstalk in a sensor record, measured from the record.

An electrically driven source (a PZT burst) may leak into every sensor channel: that part
arrives with the drive itself (zero delay, the drive's shape), at every sensor, while a wave
packet moves out with distance. So the part of a sensor's record that lies inside the drive
but before any wave can have reached that sensor (distance / ``v_bound``, a bound on the
plate's fastest wave) is crosstalk plus noise, and its energy against the drive's over the
same samples bounds the coupling:

    c^2 <= (sum x^2 - N s^2 + k sqrt(2 N s^4 + 4 s^2 sum x^2)) / sum e^2

(x the record, e the drive, s the record's noise std, N samples, k = 3 times the spread of
the noise's share of sum x^2). The bound holds for any coupling shape (it is an energy ratio, not a fit) and grows
when the wave-free window holds little of the drive (a sensor close to the source, a long
burst): then the crosstalk cannot be told apart from the packet and the pick is dropped, as
before. The crosstalk's scalogram is c |W_e|: the drive's own (the recorded drive channel, or
the source model's history at the onset when the drive is not recorded).

Measured (bench/RESULTS.md, issue 24, session 24): the simulated rig's -60 dB crosstalk is
bounded at 1-4 x its true coupling on the 25 cm sensors of the 1 m bench plate; the real
Yeum et al. records show ~1e-3 of the S0 packet inside the drive at the 420 mm sensor.
Units: s, V (any), m, m/s.
"""
from __future__ import annotations

import math

from typing import Mapping

import numpy as np

from .. import waves
from .noise import noise_level
from .picks import Direction, Sensor, nominal_cg

__all__ = ["coupling_bound", "noise_std", "bound_in"]


def noise_std(x: np.ndarray, pre: int, fs: float | None = None) -> tuple[float, float] | None:
    """(std, baseline) of a record: the std is ``noise.noise_level``'s, the one the picks' SNR
    test uses (``picks.noise_rms``: the quieter of the pre-trigger samples and the last quarter,
    by the median std of their 64-sample blocks, or, with the rate ``fs`` (Hz), the white level
    above the packets when those parts hold signal; the smallest block's std, used here before
    session 29, reads 17-22 % under white noise). The baseline is the pre-trigger blocks' median
    mean when that part is the quieter (wave-free), else the whole record's mean: a tail holds
    the coda, a slow swing off the baseline (issue 24, session 28: on the eriknbd 250 kHz
    records, no pre-trigger, the tail's quietest block's mean was 0.0029 V against a baseline of
    0.0002 V, 14 x the noise, and the offset, read as crosstalk over the drive's window, bounded
    the coupling at 0.0056 instead of ~5e-4); a sensor's record of waves is AC, so its mean over
    the record is the baseline. None when too short."""
    est = noise_level(x, pre, fs)
    if est is None:
        return None
    std, base = est
    return std, base if base is not None else float(np.mean(np.asarray(x, float)))


def coupling_bound(x: np.ndarray, drive: np.ndarray, k_onset: int, k_first: int,
                   noise: tuple[float, float] | None, k: float = 3.0) -> float:
    """Upper bound of the crosstalk coupling |x / e| (record units per drive unit) from the
    samples [k_onset, k_first) of record ``x`` and drive ``drive`` (same axis, the drive
    without its baseline): the drive's start up to the first possible wave arrival at the
    sensor; ``noise``: the record's (std, baseline) (``noise_std``). inf when the window
    holds none of the drive."""
    k_onset = max(int(k_onset), 0)
    k_first = min(int(k_first), len(x), len(drive))
    if k_first - k_onset < 2:
        return math.inf
    e = np.asarray(drive[k_onset:k_first], float)
    ee = float(np.sum(e * e))
    if not ee > 0:
        return math.inf
    std, base = noise if noise is not None else (0.0, 0.0)
    xs = np.asarray(x[k_onset:k_first], float) - base
    n = xs.size
    s2 = std * std
    xx = float(np.sum(xs * xs))
    # the spread of sum x^2 - N s^2 about the signal's energy E: sqrt(2 N s^4 + 4 s^2 E)
    return math.sqrt((max(xx - n * s2, 0.0) + k * math.sqrt(2.0 * n * s2 * s2 + 4.0 * s2 * xx)) / ee)


def bound_in(d: Direction, rec: Mapping[str, np.ndarray], s: Sensor, wl: waves.Wavelet, cache: dict, W):
    """The bound of an electrical source's crosstalk in sensor ``s``'s record of shot ``rec``
    on its scalogram grid (``W(channel)``: the shot's scalograms; ``cache``: the shot's
    cache); None for a source that is not electrical."""
    if not d.setup.source.electrical:
        return None
    if ("xt", s.channel, wl) not in cache:
        drive, Wd, onset = _drive(d, rec, wl, cache, W)
        cache[("xt", s.channel, wl)] = _bound(d, rec[s.channel], s, drive, Wd, onset)[0]
    return cache[("xt", s.channel, wl)]


def _drive(d: Direction, rec: Mapping[str, np.ndarray], wl: waves.Wavelet, cache: dict, W):
    """(drive on the record axis without its baseline, its scalogram, its onset (s)) of an
    electrical source: the recorded excitation channel (onset: where it first exceeds 2 %
    of its peak), else the source model's history from the earliest onset ``d.t0``."""
    if ("drive", wl) not in cache:
        fs, pre = d.setup.fs_hz, d.setup.pretrigger
        force = d.setup.force_channel
        if force is not None:
            x = np.asarray(rec[force], float)
            e = x - float(np.mean(x[-(len(x) // 4):]))
            k = int(np.argmax(np.abs(e) > 0.02 * np.max(np.abs(e))))
            cache[("drive", wl)] = (e, W(force), (k - pre) / fs)
        else:
            n = len(next(iter(rec.values())))
            t = (np.arange(n) - pre) / fs - d.t0[0]
            e = d.setup.source.force()(t) * (t >= 0)
            e[np.abs(e) < 1e-12] = 0.0          # the unit force's numerical tail (~1e-47) is no drive
            cache[("drive", wl)] = (e, waves.cwt(e, fs, d.freqs, wl), d.t0[0])
    return cache[("drive", wl)]


def _bound(d: Direction, x: np.ndarray, s: Sensor, drive: np.ndarray, W_drive: np.ndarray, onset_s: float
           ) -> tuple[np.ndarray, float]:
    """(bound of the electrical source's crosstalk in record ``x`` on the scalogram grid,
    the coupling bound c): c |W_drive|, c from ``coupling_bound`` over the drive's
    samples (``drive``, baseline removed, on the record axis; onset at ``onset_s``) before
    the first wave can reach the sensor's near edge: at 1.5 x the fastest nominal group
    velocity, or 1.25 x the fastest the survey measured if that is more. Where that window
    holds none of the drive, c is the record's peak over the drive's (all of it may be
    crosstalk); a drive wholly outside the record leaves none (c = 0)."""
    fs, pre = d.setup.fs_hz, d.setup.pretrigger
    fast = 0.0
    for m in ("A0", "S0", "SH0"):
        v = nominal_cg(d, m)
        if np.isfinite(v).any():
            sc = d.prior_scale.get(m)
            r = max(1.5, 1.25 * float(np.nanmax(sc))) if sc is not None and np.isfinite(sc).any() else 1.5
            fast = max(fast, r * float(np.nanmax(v)))
    k_on = pre + int(np.floor(onset_s * fs))
    k_first = pre + int(np.floor((onset_s + max(s.distance_m - 0.5 * s.length_m, 0.0) / fast) * fs))
    peak = float(np.max(np.abs(drive))) if drive.size else 0.0
    if not peak > 0:
        # the drive lies wholly outside the record (an onset measured before its start): no
        # crosstalk inside it (was: the record's peak over 1e-300, an overflow)
        return np.zeros(np.shape(W_drive)), 0.0
    noise = noise_std(x, pre, fs)
    c = coupling_bound(x, drive, k_on, k_first, noise)
    if not math.isfinite(c):
        c = float(np.max(np.abs(x - (noise[1] if noise else 0.0))) / max(float(np.max(np.abs(drive))), 1e-300))
    return c * np.abs(W_drive), c
