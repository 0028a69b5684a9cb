"""Numpy-made guided-wave records for tests: no labid model is used to make them."""
from __future__ import annotations

from functools import partial

import numpy as np


def hann_burst(n: int, fs_hz: float, f0_hz: float, cycles: int, pre: int, delay_s: float = 0.0) -> np.ndarray:
    """``cycles`` cycles of f0_hz (Hz) under a Hann window, ``n`` samples at fs_hz (Hz),
    starting ``pre`` samples plus ``delay_s`` (s) into the record; 0 elsewhere."""
    t = (np.arange(n) - pre) / fs_hz - delay_s
    T = cycles / f0_hz
    return np.where((t >= 0) & (t <= T), np.sin(np.pi * t / T) ** 2 * np.sin(2 * np.pi * f0_hz * t), 0.0)


def burst_of(n: int, fs_hz: float, f0_hz: float, cycles: int, pre: int):
    """``hann_burst`` with the record's constants bound: ``f(delay_s=0.0)``."""
    return partial(hann_burst, n, fs_hz, f0_hz, cycles, pre)
