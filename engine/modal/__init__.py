"""Low-frequency modal analysis of hammer tests: spectra, peak picking, damping.

Paper section 2 (Fig. 2): the plate rings after a hammer tap; the resonance
peaks of the spectra of several accelerometers are the natural frequencies.

Pipeline
--------
1. ``spectra(responses, fs, force=...)``: per-hit DFTs, H1 FRF or averaged
   auto-spectra, force and exponential windows (:mod:`.spectral`);
2. ``indicator(spec)``: one peak-picking curve for all channels (:mod:`.spectral`);
3. ``pick_peaks(spec)``: candidates of the indicator and an exact-DFT fit of
   common poles to all channels and hits (:mod:`.peaks`);
4. ``add_peak`` / ``remove_peak``: pure functions for manual
   editing (:mod:`.peaks`).

Frequencies are undamped natural frequencies f_n = |p| / 2 pi in Hz; damping
is the viscous ratio zeta = sigma / |p|. Units SI throughout.

Public API (re-exported here): ``ModalError``, ``Spectra``, ``Peak``,
``exponential_window``, ``force_window``, ``spectra``, ``indicator``,
``pick_peaks``, ``fit_peaks``, ``add_peak``, ``remove_peak``.
"""
from .peaks import Peak, add_peak, fit_peaks, pick_peaks, remove_peak
from .spectral import ModalError, Spectra, exponential_window, force_window, indicator, spectra

__all__ = [
    "ModalError", "Spectra", "Peak", "exponential_window", "force_window",
    "spectra", "indicator", "pick_peaks", "fit_peaks", "add_peak", "remove_peak",
]
