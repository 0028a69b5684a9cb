"""The dispersion-curvature correction on a long tone burst (engine.waves.correct_dispersion_bias);
issue 24, session 27.

A 30-cycle Hann burst at 250 kHz (the eriknbd line scan's 250 kHz records are this narrow: -46 dB
at 200 kHz) through an A0-like dispersive phase (group delay r / c_g, c_g = 2700 (f / 250 kHz)^0.25
m/s, applied by FFT; numpy only), recorded at 60 and 105 mm. Every analysis frequency of the CWT
is reassigned into a few kHz of 250 kHz; before, the correction's fit of tau'' over that cluster
moved the picks by up to 13 us (bench/RESULTS.md, issue 24, session 27: 2592 m/s against the
envelope estimates' 2700).
"""
from __future__ import annotations

import numpy as np

from engine import waves

FS, F0, CYC, N = 41.67e6, 250e3, 30, 8192
C_A, P_A = 2700.0, 0.25


def _packet(r: float) -> np.ndarray:
    t = np.arange(N) / FS
    T = CYC / F0
    b = np.where(t <= T, np.sin(np.pi * t / T) ** 2 * np.sin(2 * np.pi * F0 * t), 0.0)
    f = np.fft.rfftfreq(N, 1 / FS)
    phase = 2 * np.pi * r * f ** (1 - P_A) * F0 ** P_A / (C_A * (1 - P_A))
    return np.fft.irfft(np.fft.rfft(b) * np.exp(-1j * phase), N)


def test_a_long_bursts_cluster_of_instantaneous_frequencies_is_not_curvature_corrected():
    freqs = np.linspace(225e3, 275e3, 40)
    truth = C_A * (freqs / F0) ** P_A
    wl = waves.Wavelet(2.0, 3.0)
    arr = {}
    for r in (0.06, 0.105):
        arr[r] = waves.arrival_times(waves.cwt(_packet(r), FS, freqs, wl), FS, freqs, wl,
                                     max_freq_offset=np.inf, min_rel_db=-60.0)
    fi = arr[0.105].inst_freq_hz[arr[0.105].valid]
    assert 2 * np.pi * np.ptp(fi) < 2 * np.pi * F0 * np.sqrt(2.0 / wl.bandwidth) / wl.center   # < 1 std
    corrected = {r: waves.correct_dispersion_bias(a) for r, a in arr.items()}
    g = waves.group_velocity(corrected[0.105], 0.105, corrected[0.06], near_distance_m=0.06)
    ok = g.valid & (np.abs(g.frequencies_hz - F0) < 10e3)
    assert ok.sum() >= 3
    # within 0.5 % of the analytic group velocity (after: 0.2 %; before: 2660 m/s at 245.5 kHz, -1.0 %)
    assert np.all(np.abs(g.velocity_m_s[ok] / np.interp(g.frequencies_hz[ok], freqs, truth) - 1) < 0.005)
