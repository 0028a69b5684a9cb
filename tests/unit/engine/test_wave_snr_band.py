"""engine.wavefeatures.band.snr_band on numpy-made records: the band the record holds above the
noise is sought inside the band asked for, not around a stronger, separate low-frequency swell
(issue 24, session 28: a pencil break's record at 60 cm peaked at 10-15 kHz, below the 20-350 kHz
band that also stood 20 dB clear, and the analysis said "no velocity")."""
from __future__ import annotations

import numpy as np

from engine.wavefeatures.band import snr_band
from tests.wave_signals import hann_burst

FS, N, PRE = 5e6, 8192, 400


def _record(seed: int):
    """A 3-cycle 12 kHz swell 40 x stronger than a 5-cycle 200 kHz packet, white noise."""
    rng = np.random.default_rng(seed)
    swell = 40.0 * hann_burst(N, FS, 12e3, 3, PRE)
    packet = hann_burst(N, FS, 200e3, 5, PRE, delay_s=100e-6)
    noise = 0.01 * rng.normal(size=N)
    return swell + packet + noise, noise[:PRE]


def test_the_band_asked_for_keeps_its_packet_beside_a_stronger_swell():
    for seed in range(3):
        x, noise = _record(seed)
        whole = snr_band(x, noise, FS, 20.0, fmin_hz=5e3)
        asked = snr_band(x, noise, FS, 20.0, fmin_hz=5e3, within=(100e3, 350e3))
        # without the band asked for, the swell's band wins; it does not reach 100 kHz
        assert whole is not None and whole[1] < 100e3
        # inside 100-350 kHz the 200 kHz packet's band: the 5-cycle burst's main lobe (120-280 kHz)
        # stands 20 dB over the noise
        assert asked is not None and asked[0] < 150e3 and asked[1] > 250e3


def test_nothing_above_the_noise_in_the_band_asked_for_is_none():
    rng = np.random.default_rng(7)
    swell = 40.0 * hann_burst(N, FS, 12e3, 3, PRE)
    noise = 0.01 * rng.normal(size=N)
    assert snr_band(swell + noise, noise[:PRE], FS, 20.0, fmin_hz=5e3, within=(150e3, 350e3)) is None
