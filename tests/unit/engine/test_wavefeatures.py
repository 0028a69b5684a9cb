"""engine.wavefeatures.pipeline: the wave-feature method on arrays (geometry, shot averaging,
band choice, and a hammer record synthesised by SAFE against SAFE's own A0 curve)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from engine import safe, waves
from engine.laminate import Laminate, Material, Ply
from engine.wavefeatures.pipeline import (Sensor, WaveSettings, WaveSetup, analysis_band, combine_shots,
                                          default_wavelet, echo_path, measure_waves)
from engine.wavefeatures.predict import SourceModel
from tests.wave_reference import independent_group_velocity

AL = Material.isotropic_from(71.04e9, 2700.0, nu=71.04 / (2 * 25.32) - 1, name="Al")
AL_PLATE = Laminate((Ply(AL, 0.0, 3.175e-3),))


def test_echo_path_is_the_shortest_mirror_image():
    # source (0.1, 0.1), sensor (0.3, 0.1) on 0.5 x 0.4 m: the edge y = 0 gives
    # the image (0.3, -0.1), at sqrt(0.2^2 + 0.2^2) from the source
    assert echo_path((0.1, 0.1), (0.3, 0.1), 0.5, 0.4) == pytest.approx(math.sqrt(0.08), rel=1e-12)
    # sensor near the far edge x = length: source -> that edge -> sensor is closest
    assert echo_path((0.1, 0.2), (0.45, 0.2), 0.5, 0.4) == pytest.approx((0.5 - 0.1) + (0.5 - 0.45), rel=1e-12)


def test_combine_shots_is_the_mean_with_a_scatter_based_sigma_and_a_bias_floor():
    f = np.array([1e4, 2e4, 3e4])
    a = waves.GroupVelocity(f, np.array([100.0, 50.0, 70.0]), np.array([1.0, 1.0, 4.0]),
                            np.array([True, True, True]))
    b = waves.GroupVelocity(f, np.array([110.0, np.nan, 71.0]), np.array([2.0, np.nan, 4.0]),
                            np.array([True, False, True]))
    g = combine_shots([a, b])
    # the mean of 100 and 110; the scatter std (ddof 1) sqrt(50) over sqrt(2) = 5
    assert g.velocity_m_s[0] == pytest.approx(105.0, rel=1e-12)
    assert g.sigma_m_s[0] == pytest.approx(5.0, rel=1e-12)
    # one shot of two only: not a point (more than half the shots must measure it; session 27)
    assert np.isnan(g.velocity_m_s[1])
    # a single shot: its own value and sigma
    one = combine_shots([a])
    assert (one.velocity_m_s[1], one.sigma_m_s[1]) == (50.0, 1.0)
    # shots agreeing better than their noise: the noise sigma over sqrt(n), 4 / sqrt(2)
    assert g.sigma_m_s[2] == pytest.approx(4.0 / np.sqrt(2.0), rel=1e-12)
    assert g.valid.tolist() == [True, False, True]
    # the wavelet-bias term joins in quadrature: hypot(5, 12) = 13
    h = combine_shots([a, b], floor=np.array([12.0, 0.0, 0.0]))
    assert h.sigma_m_s[0] == pytest.approx(13.0, rel=1e-12)


def test_band_stops_where_the_half_sine_force_spectrum_falls_10_db():
    fs, T = 1e6, 60e-6
    t = np.arange(4000) / fs
    force = np.where(t < T, np.sin(np.pi * np.clip(t, 0, T) / T), 0.0)
    band = analysis_band(AL_PLATE, fs, WaveSettings(), force, pretrigger=0, source=SourceModel("hammer", T))
    freqs, notes = band.freqs, band.notes
    # |FT| of a half-sine pulse of duration T: |cos(pi f T) / (1 - (2 f T)^2)|, 1 at f = 0
    x10 = brentq(lambda x: math.cos(math.pi * x) / (1 - 4 * x * x) - 10 ** -0.5, 0.1, 1.4)
    assert freqs[-1] == pytest.approx(x10 / T, abs=2 * fs / (1 << 16))
    assert freqs[0] == pytest.approx(50e3 / 20)       # isotropic plate: the paper's 50 kHz band
    assert len(freqs) == WaveSettings().n_freqs and "10 dB" in notes[0]
    # an explicit band is kept, and one beyond fs/2 is refused
    band = analysis_band(AL_PLATE, fs, WaveSettings(band_hz=(1e3, 20e3)), force)
    assert (band.freqs[0], band.freqs[-1], band.notes, band.empty) == (1e3, 20e3, (), "")
    with pytest.raises(waves.WaveError):
        analysis_band(AL_PLATE, fs, WaveSettings(band_hz=(1e3, 600e3)))


def test_default_wavelet_is_the_papers():
    assert default_wavelet(AL_PLATE) == waves.PAPER_ALUMINIUM
    cross = Laminate(tuple(Ply(AL, a, 1e-3) for a in (0.0, 90.0)))
    assert default_wavelet(cross) == waves.PAPER_CFRP


def test_hammer_record_source_to_sensor_matches_safe_a0():
    """The paper's aluminium hammer test on arrays: the force and the strain 0.375 m away,
    synthesised by SAFE (engine.safe.transient_response, infinite plate); the method's A0
    curve (source to sensor, reassigned and bias-corrected) is within 1 % of the independent
    model's (tests/wave_reference.py; SAFE made both the record and the windows)."""
    fs, n, d = 1e6, 2000, 0.375
    hammer = safe.hammer_force(20e-6, 20.0)
    strain = safe.transient_response(AL_PLATE, d, hammer, fs, n, quantity="strain")
    shot = {"force": hammer(np.arange(n) / fs), "strain": strain}
    # an infinite plate: edges far beyond the record's reach
    setup = WaveSetup(AL_PLATE, (20.0, 20.0), (10.0, 10.0), fs, 0,
                      (Sensor("strain", d, 0.0, 0.0, (10.0 + d, 10.0)),), force_channel="force",
                      source=SourceModel("hammer", 20e-6))
    freqs = analysis_band(AL_PLATE, fs, WaveSettings(), shot["force"]).freqs
    res = measure_waves(setup, [shot, shot], freqs)
    (a0,) = [c for c in res.features if c.mode == "A0"]
    assert a0.frequency_hz.size >= 6
    cg = independent_group_velocity(AL_PLATE, a0.frequency_hz, "A0")
    assert np.abs(a0.group_velocity_m_s / cg - 1).max() < 0.01
    assert res.wave_path_m == d and "A0_0" in res.curves
    assert any("source to sensor" in s for s in res.notes)
