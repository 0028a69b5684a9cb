"""Group velocity from arrival times, and the independent points of a measured curve.

Distance / delay is the group velocity (paper section 3). Units: s, Hz, m, m/s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

from .arrivals import Arrivals
from .wavelet import Wavelet, WaveError

__all__ = ["GroupVelocity", "group_velocity", "independent_points"]


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
