"""Spectra of hammer hits (H1 FRF or auto-spectra), windows and the peak-picking indicator.

1. ``spectra(responses, fs, force=...)``: per-hit DFTs of every channel, the
   H1 FRF averaged over hits when the force is recorded, otherwise averaged
   auto-spectra (the paper's case). Optional force window (on the force
   channel) and exponential window (on every channel); the exponential
   window's added decay 1/tau is remembered and removed from the damping.
2. ``indicator(spec)``: one curve for all channels at once (sum of spectra
   each normalised by its median level, or a complex mode indicator
   function); a mode whose nodal line lies under one sensor still shows
   through the others.

Frequencies in Hz, time constants in s; units SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

__all__ = ["ModalError", "Spectra", "exponential_window", "force_window", "spectra", "indicator"]


class ModalError(ValueError):
    """Inconsistent input to the modal analysis (shapes, rates, bands)."""


@dataclass(frozen=True)
class Spectra:
    """Spectra of a set of hammer hits.

    frequencies_hz: (nf,) one-sided DFT bins, df = fs / n_samples.
    kind: 'frf' (H1, force recorded) or 'auto' (auto-spectra only).
    magnitude: (n_channels, nf) |H1| (unit/N) or averaged one-sided energy
        spectral density 2|X|^2 (unit^2 s / Hz).
    frf: (n_channels, nf) complex H1, or None.
    coherence: (n_channels, nf) ordinary coherence, or None (single hit or no force).
    dft: (n_hits, n_channels, nf) complex windowed per-hit DFTs (unit s).
    fs_hz, n_samples: sampling of the records.
    exp_tau_s: time constant of the exponential window (None if not used).
    channels: channel names.
    onset: sample index where the hits start (the trigger, i.e. the pretrigger length).
    """

    frequencies_hz: np.ndarray
    kind: Literal["frf", "auto"]
    magnitude: np.ndarray
    frf: np.ndarray | None
    coherence: np.ndarray | None
    dft: np.ndarray
    fs_hz: float
    n_samples: int
    exp_tau_s: float | None
    channels: tuple[str, ...]
    onset: int = 0

    @property
    def df(self) -> float:
        """Bin spacing, Hz."""
        return self.fs_hz / self.n_samples

    @property
    def n_hits(self) -> int:
        return int(self.dft.shape[0])

    def fit_data(self) -> np.ndarray:
        """(n_outputs, nf) complex data sharing the poles: H1 per channel, or every
        hit x channel DFT with its time origin moved to the onset."""
        if self.frf is not None:
            return self.frf
        shift = np.exp(2j * np.pi * self.frequencies_hz * self.onset / self.fs_hz)
        return self.dft.reshape(-1, self.dft.shape[-1]) * shift


# --------------------------------------------------------------------------- windows
def exponential_window(n: int, fs_hz: float, tau_s: float) -> np.ndarray:
    """w[k] = exp(-k / (tau fs)); adds exactly 1/tau (1/s) to every decay rate."""
    if not tau_s > 0:
        raise ModalError(f"exponential window time constant must be > 0 s, got {tau_s!r}")
    return np.exp(-np.arange(n) / (tau_s * fs_hz))


def force_window(n: int, fs_hz: float, start: int, width_s: float, taper_s: float | None = None) -> np.ndarray:
    """1 on [start, start + width], cosine taper of ``taper_s`` (default width/10) after, 0 elsewhere."""
    if not width_s > 0:
        raise ModalError(f"force window width must be > 0 s, got {width_s!r}")
    w = np.zeros(n)
    n1 = min(n, start + int(round(width_s * fs_hz)))
    w[max(start, 0):n1] = 1.0
    nt = max(1, int(round((taper_s if taper_s is not None else width_s / 10) * fs_hz)))
    k = np.arange(nt)
    seg = 0.5 * (1 + np.cos(np.pi * (k + 1) / (nt + 1)))
    m = min(nt, n - n1)
    if m > 0:
        w[n1:n1 + m] = seg[:m]
    return w


# --------------------------------------------------------------------------- spectra
def spectra(responses: np.ndarray, fs_hz: float, force: np.ndarray | None = None, *,
            exp_tau_s: float | None = None, force_window_s: float | None = None,
            pretrigger: int = 0, channels: Sequence[str] | None = None) -> Spectra:
    """Spectra of hammer hits.

    responses: (n_hits, n_channels, n_samples) or (n_channels, n_samples), physical units.
    force: (n_hits, n_samples) or (n_samples,) hammer force in N, or None (auto-spectra).
    exp_tau_s: exponential window time constant (applied to every channel, force too).
    force_window_s: keep the force only for this long after the trigger (``pretrigger``).
    """
    x = np.asarray(responses, dtype=float)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[-1] < 8:
        raise ModalError(f"responses must be (n_hits, n_channels, n_samples), got shape {np.shape(responses)}")
    if not fs_hz > 0:
        raise ModalError(f"sample rate must be > 0 Hz, got {fs_hz!r}")
    nh, nc, n = x.shape
    names = tuple(channels) if channels is not None else tuple(f"ch{i}" for i in range(nc))
    if len(names) != nc:
        raise ModalError(f"{len(names)} channel names for {nc} channels")
    w = exponential_window(n, fs_hz, exp_tau_s) if exp_tau_s is not None else np.ones(n)
    X = np.fft.rfft(x * w, axis=-1) / fs_hz
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    if force is None:
        mag = (2.0 * np.abs(X) ** 2).mean(axis=0)
        return Spectra(f, "auto", mag, None, None, X, float(fs_hz), n, exp_tau_s, names, int(pretrigger))
    F = np.asarray(force, dtype=float)
    if F.ndim == 1:
        F = F[None]
    if F.shape != (nh, n):
        raise ModalError(f"force must be (n_hits, n_samples) = {(nh, n)}, got {F.shape}")
    if force_window_s is not None:
        F = F * force_window(n, fs_hz, pretrigger, force_window_s)
    Ff = np.fft.rfft(F * w, axis=-1) / fs_hz
    Sff = (np.abs(Ff) ** 2).sum(axis=0)
    Sfx = (np.conj(Ff)[:, None, :] * X).sum(axis=0)
    Sxx = (np.abs(X) ** 2).sum(axis=0)
    tiny = np.finfo(float).tiny
    H1 = Sfx / np.maximum(Sff, tiny)
    coh = np.abs(Sfx) ** 2 / np.maximum(Sff * Sxx, tiny) if nh > 1 else None
    return Spectra(f, "frf", np.abs(H1), H1, coh, X, float(fs_hz), n, exp_tau_s, names, int(pretrigger))


def indicator(spec: Spectra, method: Literal["sum", "cmif"] = "sum") -> np.ndarray:
    """One peak-picking curve for all channels (power-like, dimensionless).

    'sum': sum over channels of |spectrum|^2 each divided by its median
    (power for the FRF, energy density for auto-spectra).
    'cmif': largest singular value squared of the channel-normalised complex
    data matrix (channels x hits for auto-spectra, channels x 1 for H1).
    """
    if method == "sum":
        p = spec.magnitude ** 2 if spec.kind == "frf" else spec.magnitude
        med = np.median(p[:, 1:], axis=1, keepdims=True)
        return (p / np.maximum(med, np.finfo(float).tiny)).sum(axis=0)
    if method == "cmif":
        A = spec.frf[None] if spec.frf is not None else spec.dft  # (m, nc, nf)
        norm = np.sqrt(np.median((np.abs(A) ** 2).mean(axis=0)[:, 1:], axis=1))
        A = A / np.maximum(norm, np.finfo(float).tiny)[None, :, None]
        s = np.linalg.svd(np.transpose(A, (2, 1, 0)), compute_uv=False)  # (nf, min(nc, m))
        return s[:, 0] ** 2
    raise ModalError(f"indicator method must be 'sum' or 'cmif', got {method!r}")
