"""The other mode left in a record separated by a collocated actuator pair, measured and removed.

Two actuators at one spot on opposite faces separate the modes (Kim & Sohn 2007; Yeum et al.
2011): S = (X_top + X_bottom) / 2 holds S0, A = (X_top - X_bottom) / 2 holds A0. Real actuators
differ, so S keeps a copy of A0 (and A one of S0). With the actuators' A0 responses a_t, a_b
along a ray, the copy in S is r times the A0 of A, r = (a_t - a_b) / (a_t + a_b): a property of
the two actuators in that direction, the same for every sensor on that ray (each sensor's own
response cancels in the ratio). So r is measured on a far sensor, where the foreign packet
arrives alone, and the copy removed on a near sensor on the same ray, where it lies inside the
wanted packet: S' = S - Re(r H[A]), H the analytic signal. One complex r for the band: on
Yeum's plate (bench/RESULTS.md, issue 24, session 26) the per-frequency ratio over 140-220 kHz
scatters 0.18-0.28 at 55-82 deg about the band's 0.204 at 68 deg, and the time-domain estimate
below moves by < 2 % between gates at 30 and 90 % of the packet's peak. r depends on the
direction (unequal or offset actuators): edge echoes, which leave the pair in other directions,
keep their copies (measured there: 0.05-0.15, other phases). What is removed is measured on the
records, not predicted by a model of the plate.

Units: records in any unit (both the same), fs in Hz, times in s from the record's first sample.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from scipy import signal

from .wavelet import WaveError

__all__ = ["PairResidue", "residue_ratio", "cancel_residue", "clean_shots"]


@dataclass(frozen=True)
class PairResidue:
    """The measured share of the other mode in a mode-separated record.

    ratio: complex r (residue in the record / the packet in the other record).
    gate_s: (start, end) of the gate at half the packet's peak, s from the first sample.
    spread: max |r_level / r - 1| over the gates at 30, 50, 70, 90 % of the peak: a packet
        that is not alone in the gate (the record's own mode, an echo) makes r depend on the
        gate; the caller refuses r above its tolerance.
    """

    ratio: complex
    gate_s: tuple[float, float]
    spread: float

    @property
    def level_db(self) -> float:
        """20 log10 |r|: the residue's level against the packet it copies (dB)."""
        return float(20 * np.log10(max(abs(self.ratio), 1e-300)))


def _analytic(x: np.ndarray, fs: float, band_hz: tuple[float, float]) -> np.ndarray:
    sos = signal.butter(4, band_hz, "bandpass", fs=fs, output="sos")
    return signal.hilbert(signal.sosfiltfilt(sos, x - np.mean(x)))


def residue_ratio(record: np.ndarray, other: np.ndarray, fs: float, band_hz: tuple[float, float],
                  after_s: float = 0.0, threshold: float = 0.5) -> PairResidue:
    """Measure r where the other record's packet arrives alone (a far sensor).

    record: the mode-separated record holding the residue (e.g. S at the far sensor);
    other: the record of the mode the residue copies (A at the same sensor);
    band_hz: the burst's band (both band-passed, 4th-order Butterworth, zero phase);
    after_s: the packet is the first envelope peak of ``other`` after this time above
        ``threshold`` of its maximum there (the direct packet, not an echo).
    Least squares on the analytic signals over the gate where the envelope exceeds a level of
    the peak: r = <A, S> / <A, A>.
    """
    x, y = np.asarray(record, float), np.asarray(other, float)
    if x.shape != y.shape or x.ndim != 1:
        raise WaveError(f"the two records must be 1-D and of one length, got {x.shape} and {y.shape}")
    s, a = _analytic(x, fs, band_hz), _analytic(y, fs, band_hz)
    env = np.abs(a)
    i0 = max(int(np.ceil(after_s * fs)), 1)
    peaks, _ = signal.find_peaks(env[i0:], height=threshold * env[i0:].max())
    if not len(peaks):
        raise WaveError("no packet in the other record after the given time")
    k = i0 + int(peaks[0])

    def gate(level: float) -> slice:
        lo, hi = k, k
        while lo > 0 and env[lo - 1] > level * env[k]:
            lo -= 1
        while hi < len(env) - 1 and env[hi + 1] > level * env[k]:
            hi += 1
        return slice(lo, hi + 1)

    def ls(g: slice) -> complex:
        return complex(np.vdot(a[g], s[g]) / np.vdot(a[g], a[g]))

    g = gate(0.5)
    r = ls(g)
    spread = max(abs(ls(gate(lv)) / r - 1) for lv in (0.3, 0.5, 0.7, 0.9))
    return PairResidue(r, (g.start / fs, (g.stop - 1) / fs), float(spread))


def cancel_residue(record: np.ndarray, other: np.ndarray, ratio: complex) -> np.ndarray:
    """record - Re(ratio H[other]): the copy of the other mode removed (H: analytic signal)."""
    y = np.asarray(other, float)
    return np.asarray(record, float) - np.real(ratio * signal.hilbert(y - np.mean(y)))


def clean_shots(shots: Sequence[Mapping[str, np.ndarray]], others: Sequence[Mapping[str, np.ndarray]],
                rays: Sequence[Sequence[str]], fs: float, band_hz: tuple[float, float], after_s: float = 0.0,
                max_spread: float = 0.05) -> tuple[list[dict], list[str]]:
    """The shots of a mode-separated run with the other mode's copy removed (module docstring).

    shots / others: per shot {channel: record} of this run and of the other mode's run (the
    same channels; shot k of ``others`` pairs with shot k, the mean of ``others`` when their
    counts differ); rays: the channels of each direction from the pair, the farthest last
    (one r per ray, measured there, where the other packet arrives alone); after_s: the
    trigger on the record axis (s from the first sample). A ray whose r moves by more than
    ``max_spread`` with its gate (the other packet not alone at its far sensor) is left as
    recorded. Returns (the shots, one note per ray)."""
    out = [dict(s) for s in shots]
    same = len(others) == len(shots)
    mean = {ch: np.mean([o[ch] for o in others], axis=0) for ch in others[0]} if others else {}
    notes = []
    for ray in rays:
        far = ray[-1]
        if not others or any(ch not in others[0] for ch in ray):
            notes.append(f"pair residue: the other run has no record of {', '.join(ray)}; left as recorded")
            continue
        s_far = np.mean([s[far] for s in shots], axis=0)
        try:
            res = residue_ratio(s_far, mean[far], fs, band_hz, after_s=after_s)
        except WaveError as e:
            notes.append(f"pair residue on {far}: {e}; left as recorded")
            continue
        if res.spread > max_spread:
            notes.append(f"pair residue on {far}: r moves {100 * res.spread:.0f} % with its gate (the other "
                         f"mode's packet is not alone there); {', '.join(ray)} left as recorded")
            continue
        for k, s in enumerate(out):
            o = others[k] if same else mean
            for ch in ray:
                s[ch] = cancel_residue(s[ch], o[ch], res.ratio)
        notes.append(f"pair residue: r = {abs(res.ratio):.3f} at {np.degrees(np.angle(res.ratio)):.0f} deg "
                     f"({res.level_db:.1f} dB) measured on {far} (moves {100 * res.spread:.1f} % with the gate); "
                     f"removed from {', '.join(ray)}")
    return out, notes
