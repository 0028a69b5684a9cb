"""The analysis band of a wave run: from the source and from the recorded spectrum.

``analysis_band``: ``band_hz`` if set, else the source's band (a tone burst's -20 dB band;
for a pencil or a hammer the paper's fmax/20..fmax, fmax = 50 kHz isotropic, 200 kHz
laminate, stopped where a recorded hammer force falls 10 dB) intersected with the band
the far sensor's record holds: the -20 dB band of a tone burst's direct packets, or where a
broadband record stands 20 dB above the noise (``snr_band``: the test every pick passes).
An empty intersection is an empty ``Band`` whose ``empty`` says why and which option to
change. Units: Hz, s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import waves
from ..laminate import Laminate
from .picks import WaveSettings
from .predict import SourceModel

__all__ = ["Band", "default_wavelet", "wavelet_candidates", "signal_band", "snr_band", "source_band", "analysis_band"]


@dataclass(frozen=True)
class Band:
    """The analysis grid (Hz; empty when nothing can be measured), how it was chosen, and
    why it is empty (with what to change), '' otherwise."""

    freqs: np.ndarray
    notes: tuple[str, ...]
    empty: str = ""


def default_wavelet(laminate: Laminate) -> waves.Wavelet:
    """The paper's wavelet: cmor2-1 for an isotropic plate, cmor2-5 for a laminate."""
    iso = all(m.isotropic for m in laminate.materials.values()) and len(laminate.plies) == 1
    return waves.PAPER_ALUMINIUM if iso else waves.PAPER_CFRP


def wavelet_candidates(f: np.ndarray, laminate: Laminate, wavelet: tuple[float, float] | None = None
                       ) -> list[waves.Wavelet]:
    """The candidate wavelets over the grid ``f`` (Hz), in the order tried (pipeline step 6);
    ``wavelet`` (B, C): that one alone."""
    if wavelet:
        return [waves.Wavelet(*wavelet)]
    cands = [default_wavelet(laminate)]
    if f.size > 1 and f[-1] > f[0]:
        # the centre C giving ~5 independent points over the band (spacing f / (pi C) at B = 2)
        c_band = round(min(max(4 * float(np.mean(f)) / (math.pi * (f[-1] - f[0])), 1.0), 5.0) * 2) / 2
        cands.append(waves.Wavelet(2.0, c_band))
    cands += [waves.Wavelet(2.0, 3.0), waves.Wavelet(2.0, 2.0), waves.Wavelet(2.0, 1.5), waves.PAPER_ALUMINIUM,
              waves.Wavelet(1.0, 1.0), waves.Wavelet(0.5, 1.0)]
    out = []
    for c in cands:
        if c not in out:
            out.append(c)
    return out


def _fmt_band(lo: float, hi: float) -> str:
    return f"{lo / 1e3:.3g}-{hi / 1e3:.3g} kHz"


def signal_band(x: np.ndarray, fs_hz: float, level_db: float = -20.0,
                fmin_hz: float = 0.0) -> tuple[float, float] | None:
    """The contiguous band around the spectral peak of ``x`` (above ``fmin_hz``) where
    its power stays within ``level_db`` of the peak (Hz), None for a silent record.
    The spectrum is smoothed over 1 % of the peak frequency (the fine structure of a
    few packets' interference is not the band)."""
    x = np.asarray(x, float)
    x = (x - x.mean()) * np.hanning(x.size)
    n = 1 << int(np.ceil(np.log2(max(8 * x.size, 1 << 14))))
    P = np.abs(np.fft.rfft(x, n)) ** 2
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    P[f < fmin_hz] = 0.0
    if not P.max() > 0:
        return None
    k = int(np.argmax(P))
    m = max(1, int(0.01 * f[k] / (f[1] - f[0])))
    P = np.convolve(P, np.ones(2 * m + 1) / (2 * m + 1), mode="same")
    P[f < fmin_hz] = 0.0
    k = int(np.argmax(P))
    above = P >= P[k] * 10 ** (level_db / 10)
    lo = k
    while lo > 0 and above[lo - 1]:
        lo -= 1
    hi = k
    while hi < f.size - 1 and above[hi + 1]:
        hi += 1
    return float(f[lo]), float(f[hi])


def source_band(laminate: Laminate, fs: float, source: SourceModel, level_db: float,
                 force: np.ndarray | None, pre: int) -> tuple[float, float, list[str]]:
    notes: list[str] = []
    if source.kind in ("tone_burst", "pzt"):
        fc = source.frequency_hz
        ff = np.linspace(fc / 50, 3 * fc, 3000)
        g = np.abs(source.force().spectrum(ff))
        above = np.flatnonzero(g >= g.max() * 10 ** (level_db / 20))
        k = int(np.argmax(g))
        lo, hi = k, k
        while lo - 1 in above:
            lo -= 1
        while hi + 1 in above:
            hi += 1
        return float(ff[lo]), float(ff[hi]), notes
    fmax = min(50e3 if default_wavelet(laminate) == waves.PAPER_ALUMINIUM else 200e3, 0.4 * fs)
    fmin = fmax / 20
    if force is not None:
        # a hammer's spectrum has zeros (half-sine: 1.5 / contact time): near and above the
        # first one the ridges are biased (the window straddles the zero; beyond it the
        # scalograms show the pulse's two edges, not its centre): docs/wavelet-bias.md
        fr = force
        spec_f = np.abs(np.fft.rfft(fr - np.median(fr[:max(pre, 1)]), 1 << 16))
        ff = np.fft.rfftfreq(1 << 16, 1.0 / fs)
        low = np.flatnonzero((spec_f < 10 ** (-10 / 20) * spec_f.max()) & (ff > ff[np.argmax(spec_f)]))
        if low.size and ff[low[0]] < fmax:
            fmax = max(float(ff[low[0]]), 2 * fmin)
            notes.append(f"wave band limited to {fmax / 1e3:.3g} kHz, where the source force spectrum "
                         "falls 10 dB below its peak (closer to its first zero the ridge is biased)")
    return fmin, fmax, notes


def snr_band(x: np.ndarray, noise: np.ndarray | float, fs_hz: float, snr_db: float = 20.0,
             fmin_hz: float = 0.0, within: tuple[float, float] | None = None) -> tuple[float, float] | None:
    """The contiguous band around the best signal-to-noise frequency where the scalogram
    peak of ``x`` (cmor2-1, 80 log-spaced frequencies) stands ``snr_db`` above the
    white-noise level of ``noise`` (its std: a number, ``noise.noise_level``'s, or noise-only
    samples): the test ``arrival_times``
    applies to every pick, Hz; None when nothing is that far above the noise. ``within``:
    the band asked for (Hz); the best frequency is sought inside it (when the grid has
    any there), so a stronger but separate low-frequency swell does not take the band away
    (issue 24, session 28: a pencil's record at 60 cm peaked at 10-15 kHz, below a 20-350 kHz
    band that also stood 20 dB clear)."""
    x = np.asarray(x, float)
    std = _std(noise)
    if not std > 0:
        return None
    f = np.geomspace(max(fmin_hz, 8.0 * fs_hz / x.size), 0.45 * fs_hz, 80)
    wl = waves.PAPER_ALUMINIUM
    peak = np.abs(waves.cwt(x - x[0], fs_hz, f, wl)).max(axis=1)
    snr = 20 * np.log10(np.maximum(peak, 1e-300) / waves.white_noise_level(std, fs_hz, f, wl))
    inside = (f >= within[0]) & (f <= within[1]) if within else np.zeros(f.size, bool)
    k = int(np.flatnonzero(inside)[np.argmax(snr[inside])]) if inside.any() else int(np.argmax(snr))
    if snr[k] < snr_db:
        return None
    lo = hi = k
    while lo > 0 and snr[lo - 1] >= snr_db:
        lo -= 1
    while hi < f.size - 1 and snr[hi + 1] >= snr_db:
        hi += 1
    return float(f[lo]), float(f[hi])


def _std(noise: np.ndarray | float | None) -> float:
    """A noise std given as a number, or as noise-only samples (their std); 0 when unknown."""
    if noise is None:
        return 0.0
    if np.ndim(noise) == 0:
        return float(noise)
    return float(np.std(np.asarray(noise, float))) if np.size(noise) >= 16 else 0.0


def analysis_band(laminate: Laminate, fs_hz: float, settings: WaveSettings = WaveSettings(),
                  force: np.ndarray | None = None, pretrigger: int = 0, *,
                  source: SourceModel | None = None, record: np.ndarray | None = None,
                  noise: np.ndarray | float | None = None) -> Band:
    """The analysis frequencies (Hz) and how they were chosen (module docstring, step 1).

    ``force``: the source force record (any unit) of the first shot, if recorded (a
    hammer's band stops where it falls 10 dB). ``record``: the direct packets of the far
    sensor (its record from the first possible arrival on); ``noise``: its noise std
    (``noise.noise_level``; the pre-trigger's plain std, used before session 30, read the quasi-
    static strain and coda of a pencil break that precede a sensor's trigger: 2.1-2.8 mV for
    0.2 mV of noise per shot on bench rig cfrp_pencil_2dir_s0) or noise-only samples. The grid
    must lie in the band the record holds: for a tone burst its
    -``band_db`` band; for a broadband source (pencil, hammer: a red spectrum) where it
    stays -``band_db`` above the noise (unchecked without noise). Raises WaveError when
    the band does not lie within (0, fs/2).
    """
    fs = fs_hz
    source = source or SourceModel()
    notes: list[str] = []
    if settings.band_hz:
        fmin, fmax = settings.band_hz
        how = "set by --wave-band"
    else:
        fmin, fmax, notes = source_band(laminate, fs, source, settings.band_db, force, pretrigger)
        fmax = min(fmax, 0.4 * fs)
        how = (f"the {source.kind.replace('_', ' ')}'s {settings.band_db:g} dB band"
               if source.kind in ("tone_burst", "pzt") else "the default for the material")
    if not 0 < fmin < fmax < fs / 2:
        raise waves.WaveError(f"wave band {fmin:g}..{fmax:g} Hz: expected 0 < fmin < fmax < rate/2 = {fs / 2:g} Hz")
    narrow = source.kind in ("tone_burst", "pzt")
    noisy = _std(noise) > 0
    if record is not None and (narrow or noisy):
        floor = min(fmin, 0.1 * fmax) / 2
        energy = signal_band(record, fs, settings.band_db, fmin_hz=floor)
        if energy is None:
            return Band(np.zeros(0), tuple(notes), "no velocity: the wave records are silent")
        if narrow:
            got, what = energy, f"the {settings.band_db:g} dB band of the direct packets"
        else:
            got = snr_band(record, noise, fs, -settings.band_db, fmin_hz=floor, within=(fmin, fmax))
            what = f"where the direct packets stand {-settings.band_db:g} dB above the noise"
        lo, hi = (max(fmin, got[0]), min(fmax, got[1])) if got else (0.0, 0.0)
        if not hi > lo * 1.02:
            fix = f"set --wave-band {energy[0] / 1e3:.3g}e3,{energy[1] / 1e3:.3g}e3"
            if not narrow:
                fix += " or describe the source as a tone_burst (or pzt) in the rig file"
            return Band(np.zeros(0), tuple(notes),
                        f"no velocity: band {_fmt_band(fmin, fmax)} ({how}) has no signal "
                        f"{'above ' + format(settings.band_db, 'g') + ' dB' if narrow else 'above the noise'}; "
                        f"the record's energy is at {_fmt_band(*energy)}; {fix}")
        if (lo, hi) != (fmin, fmax):
            notes.append(f"wave band {_fmt_band(lo, hi)}: {how} ({_fmt_band(fmin, fmax)}) within {what} "
                         f"({_fmt_band(*got)})")
        fmin, fmax = lo, hi
    return Band(np.linspace(fmin, fmax, settings.n_freqs), tuple(notes))
