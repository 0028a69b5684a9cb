"""engine.wavefeatures.shots.stack_shots on numpy-made records (a Hann burst plus white noise of
known std, no labid model): groups of one size, their noise falling as 1 / sqrt(size)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.wavefeatures.shots import stack_shots

N_SAMPLES = 4096
NOISE = 1e-3            # V, the white noise's std on every shot


def _shots(n: int, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    t = np.arange(N_SAMPLES) / 5e6
    burst = np.where(t < 50e-6, 5e-3 * np.sin(2 * np.pi * 100e3 * t) * np.sin(np.pi * t / 50e-6) ** 2, 0.0)
    return [{"x": burst + NOISE * rng.standard_normal(N_SAMPLES), "burst": burst} for _ in range(n)]


@pytest.mark.parametrize("n, size, groups, left", [(16, 2, 8, 0), (64, 8, 8, 0), (36, 3, 12, 0), (13, 2, 6, 1),
                                                   (100, 10, 10, 0)])
def test_groups_of_one_size_whose_noise_falls_as_one_over_sqrt_size(n, size, groups, left):
    shots = _shots(n)
    out, note = stack_shots(shots, max_curves=12)
    assert len(out) == groups
    # every group the mean of `size` consecutive shots: the burst kept exactly, the noise
    # std NOISE / sqrt(size) for every group alike (4096 samples: the std known to ~1.1 %)
    for i, g in enumerate(out):
        assert np.allclose(g["x"], np.mean([s["x"] for s in shots[i * size:(i + 1) * size]], axis=0), atol=1e-15)
        assert np.allclose(g["burst"], shots[0]["burst"], atol=1e-15)
        assert np.std(g["x"] - g["burst"]) == pytest.approx(NOISE / np.sqrt(size), rel=0.05)
    assert f"{groups} groups of {size}" in note
    # the shots left over (fewer than a group) are said, not silently lost
    assert (f"last {left} shot" in note) == bool(left)


def test_no_averaging_up_to_max_curves():
    shots = _shots(12)
    out, note = stack_shots(shots, max_curves=12)
    assert note == "" and len(out) == 12 and all(o is s for o, s in zip(out, shots))


def test_more_shots_note_scales_the_sigma_as_one_over_sqrt_shots():
    from engine.wavefeatures.shots import more_shots_note
    # 1.41 % from 2 shots: 1.41 sqrt(2 / N) <= 0.5 % needs N >= 15.9 -> 16 (sweep_far, S0 0 deg, 99 kHz)
    note = more_shots_note("S0 along 0 deg", [(99e3, 0.0141, 2, [100e3]), (208e3, 0.0069, 2, [200e3]),
                                              (164e3, 0.012, 6, [150e3, 200e3])])
    assert note.startswith("more shots: S0 along 0 deg, 99 kHz: sigma 1.4 % from 2 shots of the 100 kHz burst; 0.5 % needs 16 or more")
    assert "208 kHz" not in note                                  # under the 1 % the features are held to
    # two bursts combined: each burst's shots, 1.2 % sqrt(6 / 35) = 0.497 %
    assert "164 kHz: sigma 1.2 % from 6 shots of the 150 and 200 kHz bursts; 0.5 % needs 35 or more" in note
    assert more_shots_note("A0 along 90 deg", [(50e3, 0.004, 2, [60e3])]) == ""
