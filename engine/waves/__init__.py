"""High-frequency analysis: complex Morlet CWT, arrival times, group velocity.

Paper section 3 (Figs. 5-9): the scalogram |W(f, t)| of a guided-wave record
peaks, at each frequency, at the arrival time of the wave packet of that
frequency; distance / delay is the group velocity. Units: s, Hz, m, m/s.

Modules (each readable alone):

* :mod:`.wavelet` -- the complex Morlet ``Wavelet`` (B, C; ``from_name('cmor2-1')``,
  ``.name``, time and frequency std) and the paper's two choices;
* :mod:`.bank` -- the transform as an analytic Morlet filter bank in the Fourier
  domain (the measured reason for keeping it is in its docstring), its decimated
  form and the white-noise level of |W|;
* :mod:`.arrivals` -- arrival time per frequency from |W|, the dispersion-bias
  correction, time gates;
* :mod:`.velocity` -- group velocity from arrivals, independent points;
* :mod:`.paths` -- ray paths on a rectangular plate: direct and edge reflections (image sources).
* :mod:`.pair` -- a collocated actuator pair's copy of the other mode in a mode-separated
  record, measured where it arrives alone and removed (``residue_ratio``, ``cancel_residue``).

The whole measurement of a wave run (band, gates, wavelet choice, S0 separation,
shots, independent points) is :mod:`engine.wavefeatures.pipeline`.

Public API (re-exported here): ``WaveError``, ``Wavelet``, ``PAPER_ALUMINIUM``,
``PAPER_CFRP``, ``cwt``, ``cwt_decimated``, ``white_noise_level``, ``Arrivals``,
``arrival_times``, ``correct_dispersion_bias``, ``ridge_points``, ``velocity_gate``,
``expected_gate``, ``GroupVelocity``, ``group_velocity``, ``independent_points``, ``RayPath``,
``ray_paths``.
"""
from .arrivals import Arrivals, arrival_times, correct_dispersion_bias, expected_gate, ridge_points, velocity_gate
from .bank import cwt, cwt_decimated, white_noise_level
from .paths import RayPath, ray_paths
from .velocity import GroupVelocity, group_velocity, independent_points
from .wavelet import PAPER_ALUMINIUM, PAPER_CFRP, Wavelet, WaveError

__all__ = [
    "WaveError", "Wavelet", "PAPER_ALUMINIUM", "PAPER_CFRP", "cwt", "cwt_decimated", "white_noise_level",
    "Arrivals", "arrival_times", "velocity_gate", "expected_gate", "GroupVelocity",
    "group_velocity", "correct_dispersion_bias", "ridge_points", "independent_points", "RayPath", "ray_paths",
]
