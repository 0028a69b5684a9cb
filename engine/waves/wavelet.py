"""The complex Morlet wavelet ``cmorB-C`` (PyWavelets' name) and the paper's two choices.

Wavelet: PyWavelets' complex Morlet ``cmorB-C``,
    psi(t) = (pi B)^(-1/2) exp(-t^2 / B) exp(2 i pi C t),
whose Fourier transform is the Gaussian exp(-B (w - 2 pi C)^2 / 4). At the
analysis frequency f (scale a = C fs / f samples) its energy has a time
standard deviation ``sigma_t = C sqrt(B) / (2 f)`` and a frequency standard
deviation ``sigma_f = f / (2 pi C sqrt(B))`` (sigma_t sigma_f = 1/(4 pi)).
Defaults are the paper's: B = 2, C = 1 (aluminium to 50 kHz); B = 2, C = 5
(CFRP to 200 kHz).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pywt

__all__ = ["WaveError", "Wavelet", "PAPER_ALUMINIUM", "PAPER_CFRP"]

_NAME = re.compile(r"cmor([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)-([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)")
_NO_DEFAULT = object()


class WaveError(ValueError):
    """Inconsistent input to the wave analysis (rates, grids, gates)."""


@dataclass(frozen=True)
class Wavelet:
    """Complex Morlet wavelet ``cmorB-C``: bandwidth B, centre frequency C (dimensionless)."""

    bandwidth: float = 2.0
    center: float = 1.0

    def __post_init__(self) -> None:
        if not (self.bandwidth > 0 and self.center > 0):
            raise WaveError(f"Morlet bandwidth and centre must be > 0, got B={self.bandwidth!r}, C={self.center!r}")

    @classmethod
    def from_name(cls, name, default: "Wavelet | object" = _NO_DEFAULT) -> "Wavelet":
        """The wavelet of a PyWavelets name ``cmorB-C`` (e.g. 'cmor2-1', 'cmor0.5-1').

        ``default``: returned instead of raising WaveError when ``name`` is not such a
        name (None, another wavelet family, a malformed string, B or C not > 0), e.g. for a name read
        back from a run file.
        """
        m = _NAME.fullmatch(name.strip()) if isinstance(name, str) else None
        try:
            if m is None:
                raise WaveError(f"wavelet {name!r}: expected a complex Morlet name 'cmorB-C', e.g. 'cmor2-1'")
            return cls(float(m.group(1)), float(m.group(2)))
        except WaveError:
            if default is _NO_DEFAULT:
                raise
            return default

    @property
    def name(self) -> str:
        """PyWavelets name, e.g. 'cmor2-1'."""
        return f"cmor{self.bandwidth:g}-{self.center:g}"

    def scales(self, freqs_hz: np.ndarray, fs_hz: float) -> np.ndarray:
        """Scales (samples) of the analysis frequencies, via ``pywt.frequency2scale``."""
        return np.asarray(pywt.frequency2scale(self.name, np.asarray(freqs_hz, float) / fs_hz))

    def time_std_s(self, f_hz):
        """Time standard deviation of the wavelet's energy at frequency f, s."""
        return self.center * np.sqrt(self.bandwidth) / (2.0 * np.asarray(f_hz, float))

    def freq_std_hz(self, f_hz):
        """Frequency standard deviation of the wavelet's energy at frequency f, Hz."""
        return np.asarray(f_hz, float) / (2.0 * np.pi * self.center * np.sqrt(self.bandwidth))


PAPER_ALUMINIUM = Wavelet(2.0, 1.0)
PAPER_CFRP = Wavelet(2.0, 5.0)
