"""The wavelet-bias sweep term measured once, on the mean of a burst's shots or groups (issue 24,
session 29), instead of on every group.

1. ``pipeline._sweep_term`` measures the swept wavelet once, on the groups' mean record, outside
   the shot memo (which holds the groups' picks by index), and returns half the difference.
2. Why that is the same term: the bias is deterministic (the wavelet's spread on the dispersion),
   the noise enters each pick linearly at a good SNR, so the swept curve of the mean record is the
   mean of the groups' swept curves. Numpy-made records: an A0-like dispersive packet (group delay
   r / c_g, c_g ~ f^0.5, applied by FFT) at 60 and 105 mm, two groups with their own white noise.
"""
from __future__ import annotations

import numpy as np
import pytest

from engine import waves
from engine.wavefeatures import pipeline
from engine.wavefeatures.picks import Direction, WaveSettings
from engine.wavefeatures.shots import combine_shots

FS, N, F0 = 5e6, 4096, 150e3
FREQS = np.linspace(90e3, 220e3, 30)


def test_sweep_term_measures_the_swept_wavelet_once_on_the_mean_record(monkeypatch):
    d = Direction(None, WaveSettings(), FREQS[:5], 0.0, [])
    d.memo = {"kept": 1}
    calls = []

    def fake(dd, wl, shots, first_only=False):
        calls.append((wl, [dict(s) for s in shots], dict(dd.memo)))
        v = 1000.0 + shots[0]["x"][:5]
        return [{"A0": waves.GroupVelocity(FREQS[:5], v, np.full(5, 1.0), np.ones(5, bool))}], None, None

    monkeypatch.setattr(pipeline, "_measure", fake)
    rng = np.random.default_rng(0)
    groups = [{"x": rng.normal(size=8)} for _ in range(2)]
    g = waves.GroupVelocity(FREQS[:5], np.full(5, 1001.0), np.full(5, 1.0), np.array([1, 1, 1, 1, 0], bool))
    term = pipeline._sweep_term(d, waves.Wavelet(2.0, 3.0), groups, {"A0": g})
    assert len(calls) == 1
    wl, shots, memo_seen = calls[0]
    assert wl == waves.Wavelet(2.0, 2.0) and len(shots) == 1 and memo_seen == {}
    assert np.array_equal(shots[0]["x"], np.mean([s["x"] for s in groups], axis=0))
    assert d.memo == {"kept": 1}
    alt = 1000.0 + np.mean([s["x"] for s in groups], axis=0)[:5]
    assert np.array_equal(term["A0"], np.where(g.valid, 0.5 * np.abs(1001.0 - alt), 0.0))


def _record(r: float) -> np.ndarray:
    t = np.arange(N) / FS
    T = 3 / F0
    b = np.where(t <= T, np.sin(np.pi * t / T) ** 2 * np.sin(2 * np.pi * F0 * t), 0.0)
    f = np.fft.rfftfreq(N, 1 / FS)
    phase = 2 * np.pi * r * 2 * np.sqrt(f * F0) / 1500.0        # c_g = 1500 (f / F0)^0.5 m/s
    return np.roll(np.fft.irfft(np.fft.rfft(b) * np.exp(-1j * phase), N), 200)


def _curve(near, far, wl):
    a = [waves.arrival_times(waves.cwt(x, FS, FREQS, wl), FS, FREQS, wl, min_snr_db=-np.inf,
                             max_freq_offset=np.inf, min_rel_db=-40.0) for x in (near, far)]
    return waves.group_velocity(a[1], 0.105, a[0], near_distance_m=0.06)


def test_the_sweep_term_of_the_mean_record_is_the_groups_term():
    wl, alt = waves.Wavelet(2.0, 3.0), waves.Wavelet(2.0, 2.0)
    clean = [_record(0.06), _record(0.105)]
    rng = np.random.default_rng(1)
    level = 0.001 * np.abs(clean[1]).max()
    groups = [[x + level * rng.normal(size=N) for x in clean] for _ in range(2)]
    mean = [0.5 * (groups[0][k] + groups[1][k]) for k in (0, 1)]
    comb = combine_shots([_curve(*g, wl) for g in groups])
    per_group = combine_shots([_curve(*g, alt) for g in groups])
    on_mean = _curve(*mean, alt)
    noiseless = 0.5 * np.abs(_curve(*clean, wl).velocity_m_s - _curve(*clean, alt).velocity_m_s)
    ok = comb.valid & per_group.valid & on_mean.valid & np.isfinite(noiseless)
    assert ok.sum() >= 15
    old = 0.5 * np.abs(comb.velocity_m_s - per_group.velocity_m_s)[ok]
    new = 0.5 * np.abs(comb.velocity_m_s - on_mean.velocity_m_s)[ok]
    sigma = comb.sigma_m_s[ok]                      # the groups' noise sigma of the combined curve
    # the bias is there (the two wavelets disagree by 0.5-0.7 m/s, ~2.6 x the noise sigma), and
    # both ways measure it alike: within a tenth of the combined curve's noise sigma (measured:
    # 0.03), the noise both carry; and within 2 sigma of the noiseless records' term (measured: 0.64)
    assert np.median(noiseless[ok] / sigma) > 1.5
    assert np.all(np.abs(new - old) <= 0.1 * sigma)
    assert np.all(np.abs(new - noiseless[ok]) <= 2 * sigma)


def test_bias_term_where_the_swept_wavelet_has_no_pick_takes_the_larger_neighbour():
    """Where only the reported wavelet picked, the term is the larger relative term of the nearest
    frequencies on each side where both picked (not 0: issue 24, session 30), at the end points
    the one side's; a curve whose swept wavelet picked nowhere keeps 0; an invalid point none."""
    from engine.wavefeatures.shots import bias_term
    f = np.linspace(100e3, 190e3, 10)
    v = np.linspace(1500.0, 1700.0, 10)
    d = np.array([3.0, 0, 0, 10.0, 0, 4.0, 0, 0, 2.0, 0])       # |v - v_alt| where both picked
    alt_ok = np.array([1, 0, 0, 1, 0, 1, 0, 0, 1, 0], bool)
    g_ok = np.array([1, 1, 1, 1, 1, 1, 0, 1, 1, 1], bool)
    g = waves.GroupVelocity(f, v, np.full(10, 1.0), g_ok)
    alt = waves.GroupVelocity(f, np.where(alt_ok, v + d, np.nan), np.full(10, 1.0), alt_ok)
    t = bias_term(g, alt)
    half = 0.5 * d / v
    assert t[[0, 3, 5, 8]] == pytest.approx(0.5 * d[[0, 3, 5, 8]], rel=1e-12)
    for i, (lo, hi) in {1: (0, 3), 2: (0, 3), 4: (3, 5), 7: (5, 8)}.items():
        assert t[i] == pytest.approx(max(half[lo], half[hi]) * v[i], rel=1e-12)
    assert t[9] == pytest.approx(half[8] * v[9], rel=1e-12)     # past the last: that side only
    assert t[6] == 0.0                                           # not a valid point of the curve
    none = waves.GroupVelocity(f, np.full(10, np.nan), np.full(10, 1.0), np.zeros(10, bool))
    assert np.all(bias_term(g, none) == 0.0)
