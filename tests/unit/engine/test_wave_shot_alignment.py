"""Shots aligned before they are averaged (engine.wavefeatures.shots: shot_lags, align_shots,
stack_shots(ref=...), align_channel; issue 24, session 29), on numpy-made records: a 50 kHz Hann
burst on a near channel "a" and the same burst DELAY later on a far channel "b", every shot's whole
record shifted by a known sub-sample lag (the burst evaluated analytically at t - lag, no FFT)
plus white noise. No labid model.

The mean of K copies shifted by tau_k keeps |mean_k exp(-i w tau_k)| of the packet's amplitude at
angular frequency w (analytic); aligned, it keeps all of it less the lag errors' share."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from engine.wavefeatures.shots import MIN_CORR, align_channel, align_shots, shot_lags, stack_shots

FS, N, F0 = 2e6, 4096, 50e3
T_A, DELAY = 400e-6, 37.3e-6          # the burst's start on channel a; b's delay after a (s)
NOISE = 0.02                          # white noise std, of the burst's peak 1
BAND = (20e3 / FS, 100e3 / FS)        # cycles / sample


def _burst(t):
    """4 cycles of F0 under a Hann window, starting at t = 0."""
    L = 4 / F0
    inside = (t >= 0) & (t < L)
    return np.where(inside, np.sin(2 * np.pi * F0 * t) * np.sin(np.pi * t / L) ** 2, 0.0)


def _shots(lags_samples, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS
    out = []
    for lag in lags_samples:
        tau = lag / FS
        out.append({"a": _burst(t - T_A - tau) + NOISE * rng.standard_normal(N),
                    "b": _burst(t - T_A - DELAY - tau) + NOISE * rng.standard_normal(N)})
    return out


GATE = slice(720, 1120)               # samples holding both packets at every lag used here


def _dft(x, f=F0):
    """DFT of record x at f (Hz) over GATE."""
    t = np.arange(x.size)[GATE] / FS
    return np.sum(x[GATE] * np.exp(-2j * np.pi * f * t))


def _amp(x, f=F0):
    return abs(_dft(x, f))


def _phase_delay(x_a, x_b, f=F0):
    """b's delay after a from the phase of their cross-spectrum at f (s), within one period."""
    return -np.angle(_dft(x_b, f) * np.conj(_dft(x_a, f))) / (2 * np.pi * f)


def _sigma_t(noise):
    """The std (s) of one record's phase time at F0 from white noise of std ``noise`` in GATE:
    noise sqrt(n / 2) / |DFT of the noiseless burst| / (2 pi F0)."""
    t = np.arange(N) / FS
    n = GATE.stop - GATE.start
    return noise * np.sqrt(n / 2) / _amp(_burst(t - T_A)) / (2 * np.pi * F0)


def _wrap(dt, f=F0):
    return (dt + 0.5 / f) % (1 / f) - 0.5 / f


LAGS = np.array([0.0, 7.3, -4.6, 11.85, 2.2, -9.4, 5.05, -1.7])    # samples; 11.85 samples = 0.30 period


@pytest.fixture(scope="module")
def jittered():
    return _shots(LAGS)


def test_lags_are_recovered_within_a_twentieth_of_a_sample(jittered):
    lags, rho = shot_lags(jittered, "a", BAND)
    # the true lags behind shot 0 are known by construction; SNR 35 dB per record
    assert np.max(np.abs(lags - (LAGS - LAGS[0]))) < 0.05
    assert rho.min() > 0.95


def test_the_mean_loses_the_analytic_share_unaligned_and_keeps_the_packet_aligned(jittered):
    single = np.mean([_amp(s["a"]) for s in jittered])
    raw = _amp(np.mean([s["a"] for s in jittered], axis=0))
    # unaligned: |mean exp(-i w tau)| of the lags (0.61 here), within the noise's 1 %
    loss = abs(np.mean(np.exp(-2j * np.pi * F0 * LAGS / FS)))
    assert raw / single == pytest.approx(loss, abs=0.01)
    assert loss < 0.7
    aligned, lags = align_shots(jittered, "a", BAND)
    kept = _amp(np.mean([s["a"] for s in aligned], axis=0)) / single
    # aligned: lag errors < 0.05 samples cost < 1 - cos(2 pi 50e3 0.05 / 2e6) = 6e-5; noise 1 %
    assert kept == pytest.approx(1.0, abs=0.01)
    # the time base is the median shot's: the shifts are the lags less their median
    assert np.max(np.abs(lags - (LAGS - np.median(LAGS)))) < 0.05


def test_the_delay_between_channels_is_untouched(jittered):
    aligned, _ = align_shots(jittered, "a", BAND)
    mean = {ch: np.mean([s[ch] for s in aligned], axis=0) for ch in ("a", "b")}
    # b's delay after a in the aligned mean: the true 37.3 us within 4 sigma of the mean's noise
    # (sqrt 2 x sigma_t(NOISE / sqrt 8): 11 ns here, 1/45 sample); lag errors move a and b alike
    bound = 4 * np.sqrt(2) * _sigma_t(NOISE / np.sqrt(len(jittered)))
    assert bound < 50e-9
    assert abs(_wrap(_phase_delay(mean["a"], mean["b"]) - DELAY)) < bound
    # and its packet kept: b shifted by the lag measured on a
    single_b = np.mean([_amp(s["b"]) for s in jittered])
    assert _amp(mean["b"]) / single_b == pytest.approx(1.0, abs=0.01)


def test_stack_shots_aligns_every_group_on_one_time_base():
    rng = np.random.default_rng(3)
    lags = np.round(rng.uniform(-15, 15, 24), 2)
    shots = _shots(lags, seed=4)
    raw, _ = stack_shots(shots, ref=None)
    out, note = stack_shots(shots, ref="a", band=BAND)
    assert len(out) == 12 and "aligned on a, shifted" in note
    single = np.mean([_amp(s["a"]) for s in shots])
    for k, g in enumerate(out):
        pair = lags[2 * k:2 * k + 2]
        # raw pairs keep |cos(w (tau_1 - tau_2) / 2)|; aligned pairs all of it
        want = abs(np.mean(np.exp(-2j * np.pi * F0 * pair / FS)))
        assert _amp(raw[k]["a"]) / single == pytest.approx(want, abs=0.03)
        assert _amp(g["a"]) / single == pytest.approx(1.0, abs=0.03)
        # every group on one time base, the median shot's: its phase at F0 is that of the burst
        # at the median lag within 4 sigma of the pair's noise plus the lag errors (< 0.05 sample)
        t = np.arange(N) / FS
        base = _burst(t - T_A - np.median(lags) / FS)
        bound = 4 * _sigma_t(NOISE / np.sqrt(2)) + 25e-9
        assert abs(_wrap(_phase_delay(base, g["a"]))) < bound


def test_synchronous_shots_are_left_where_they_are():
    shots = _shots(np.zeros(8), seed=1)
    lags, _ = shot_lags(shots, "a", BAND)
    assert np.max(np.abs(lags)) < 0.05           # the noise's share only
    aligned, _ = align_shots(shots, "a", BAND)
    raw = np.mean([s["a"] for s in shots], axis=0)
    new = np.mean([s["a"] for s in aligned], axis=0)
    assert np.max(np.abs(new - raw)) < 0.01      # < half the noise std of one shot: the packet in place


def test_a_noise_only_reference_is_not_applied():
    rng = np.random.default_rng(2)
    shots = [{"a": NOISE * rng.standard_normal(N), "b": NOISE * rng.standard_normal(N)} for _ in range(6)]
    lags, rho = shot_lags(shots, "a", BAND)
    # noise alone: the normalised correlation peaks near sqrt(2 ln(2 L + 1) / N_eff) (N_eff: the
    # band's degrees of freedom, 2 x 4096 x 80 / 2000 = 328 here, +-1024 lags: 0.22), under the rule's bound
    assert rho[1:].max() < max(MIN_CORR, 2 * np.sqrt(2 * np.log(2 * 1024 + 1) / 328))
    assert np.all(np.isnan(lags[1:]))
    aligned, _ = align_shots(shots, "a", BAND)
    assert all(np.array_equal(x["a"], s["a"]) and np.array_equal(x["b"], s["b"]) for x, s in zip(aligned, shots))


def _setup(force=None, trigger=None):
    sensors = tuple(SimpleNamespace(channel=c, distance_m=r) for c, r in (("x2", 0.4), ("x1", 0.2), ("y1", 0.2)))
    return SimpleNamespace(sensors=sensors, force_channel=force, trigger_distance_m=trigger)


def test_the_reference_channel():
    assert align_channel(_setup(force="exc")) is None           # timed by a recorded drive: not aligned
    assert align_channel(None) is None
    assert align_channel(_setup(trigger=0.4)) == "x2"           # the trigger sensor's distance
    assert align_channel(_setup()) == "x1"                      # else the nearest sensor
    shots = _shots([0.0, 3.3, -2.0])
    aligned, lags = align_shots(shots, None)
    assert np.all(lags == 0) and all(np.array_equal(x["a"], s["a"]) for x, s in zip(aligned, shots))


def test_a_walked_first_shot_does_not_move_the_others():
    # shot 0's trigger walked 150 us (as 3 of 72 soft-plate face breaks did): the others keep
    # their time base (shifted by their lag less the median), shot 0 is moved onto theirs
    lags = np.array([300.0, 1.3, -0.8, 2.1, 0.4, -1.6])
    aligned, shifts = align_shots(_shots(lags, seed=5), "a", BAND)
    assert np.max(np.abs(shifts - (lags - np.median(lags)))) < 0.05
    assert np.max(np.abs(shifts[1:])) < 2.5
