"""Force histories of the SAFE transient: hammer tap, pencil-lead break, tone burst.

Units: SI (N, s, Hz). Spectra use the exp(-i 2 pi f t) convention; F(t) = 0 before t = 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import TWO_PI, SafeError

__all__ = ["ForceHistory", "hammer_force", "pencil_lead_break", "tone_burst"]


def _half_sine_spectrum(amp: float, T: float, w: np.ndarray) -> np.ndarray:
    """FT (exp(-i w t) convention) of amp*sin(pi t/T) on [0, T], N s."""
    a = np.pi / T
    den = a * a - w * w
    near = np.abs(den) < 1e-9 * a * a
    with np.errstate(invalid="ignore", divide="ignore"):
        g = amp * a * (1.0 + np.exp(-1j * w * T)) / np.where(near, 1.0, den)
    return np.where(near, -0.5j * amp * T * np.sign(w), g)     # limit at w = +-pi/T


@dataclass(frozen=True, eq=False)
class ForceHistory:
    """A force history F(t) (N), zero before t = 0, held after its end.

    ``kind``: 'half_sine' (amplitude, duration), 'step' (amplitude, raised-cosine
    rise of ``duration``) or 'samples' (piecewise linear through ``t``, ``f``).
    """

    kind: str
    amplitude_n: float = 1.0
    duration_s: float = 0.0
    t: np.ndarray | None = None
    f: np.ndarray | None = None

    @classmethod
    def from_samples(cls, t, f) -> "ForceHistory":
        """Piecewise-linear force through (t_i, f_i); 0 before t_0, f_last after the end."""
        t = np.asarray(t, float).ravel(); f = np.asarray(f, float).ravel()
        if t.size < 2 or t.size != f.size or np.any(np.diff(t) <= 0) or t[0] < 0:
            raise SafeError("force samples: expected increasing times >= 0 s and equal lengths")
        return cls("samples", 1.0, float(t[-1]), t, f)

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        A, T = self.amplitude_n, self.duration_s
        if self.kind == "half_sine":
            return np.where((t >= 0) & (t <= T), A * np.sin(np.pi * np.clip(t, 0, T) / T), 0.0)
        if self.kind == "step":
            r = np.clip(t / T, 0.0, 1.0)
            return np.where(t >= 0, A * 0.5 * (1.0 - np.cos(np.pi * r)), 0.0)
        return np.where(t < self.t[0], 0.0, np.interp(t, self.t, self.f))

    def derivative_spectrum(self, frequency_hz) -> np.ndarray:
        """FT of dF/dt, exp(-i 2 pi f t) convention, N."""
        w = TWO_PI * np.asarray(frequency_hz, float)
        A, T = self.amplitude_n, self.duration_s
        if self.kind == "half_sine":
            return 1j * w * _half_sine_spectrum(A, T, w)
        if self.kind == "step":     # dF/dt = A pi/(2T) sin(pi t/T) on [0, T]
            return _half_sine_spectrum(A * np.pi / (2 * T), T, w)
        # piecewise linear: jump f0 at t0, then constant slopes
        t, f = self.t, self.f
        s = np.diff(f) / np.diff(t)
        out = np.empty(w.shape, complex)
        wf = w.ravel()
        res = np.empty(wf.shape, complex)
        for i0 in range(0, wf.size, 512):
            ww = wf[i0:i0 + 512, None]
            e = np.exp(-1j * ww * t[None, :])
            with np.errstate(invalid="ignore", divide="ignore"):
                seg = np.where(ww == 0, np.diff(t)[None, :], (e[:, :-1] - e[:, 1:]) / (1j * ww))
            res[i0:i0 + 512] = f[0] * e[:, 0] + seg @ s
        out[...] = res.reshape(w.shape)
        return out

    def spectrum(self, frequency_hz) -> np.ndarray:
        """FT of F (N s), exp(-i 2 pi f t) convention; 0 at f = 0 (DC dropped)."""
        f = np.asarray(frequency_hz, float)
        w = TWO_PI * f
        g = self.derivative_spectrum(f)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(w == 0, 0.0, g / (1j * np.where(w == 0, 1.0, w)))

    def bandwidth_hz(self, rel: float = 1e-2) -> float:
        """Highest frequency where |FT(dF/dt)| still exceeds rel * its maximum."""
        span = self.duration_s if self.duration_s > 0 else 1e-6
        f = np.linspace(0.0, 200.0 / span, 4001)
        g = np.abs(self.derivative_spectrum(f))
        above = np.nonzero(g >= rel * g.max())[0]
        return float(f[above[-1]]) if above.size else float(f[-1])


def hammer_force(duration_s: float, amplitude_n: float = 1.0) -> ForceHistory:
    """Instrumented-hammer tap: half-sine pulse of the given duration (s) and peak (N)."""
    if not duration_s > 0:
        raise SafeError(f"hammer duration {duration_s!r} s: expected a positive value")
    return ForceHistory("half_sine", float(amplitude_n), float(duration_s))


def pencil_lead_break(rise_s: float = 1e-6, amplitude_n: float = 1.0) -> ForceHistory:
    """Pencil-lead break (Hsu-Nielsen): the lead's downward push is released, i.e. a
    +z step of ``amplitude_n`` with a raised-cosine rise of ``rise_s`` (~1 us)."""
    if not rise_s > 0:
        raise SafeError(f"pencil-lead rise time {rise_s!r} s: expected a positive value")
    return ForceHistory("step", float(amplitude_n), float(rise_s))


#: tone-burst windows w(t / T) on [0, 1]
WINDOWS = {
    "hann": lambda x: np.sin(np.pi * x) ** 2,
    "hamming": lambda x: 0.54 - 0.46 * np.cos(2 * np.pi * x),
    "rect": lambda x: np.ones_like(x),
}


def tone_burst(fc_hz: float, cycles: float = 5.0, amplitude_n: float = 1.0,
               points_per_cycle: int = 64, window: str = "hann") -> ForceHistory:
    """Windowed sine burst ``amplitude w(t/T) sin(2 pi fc t)`` of ``cycles`` cycles at
    ``fc_hz`` (T = cycles / fc; sampled, piecewise linear); ``window`` one of WINDOWS
    ('hann', the usual choice; 'hamming'; 'rect')."""
    if not (fc_hz > 0 and cycles > 0):
        raise SafeError(f"tone burst fc={fc_hz!r} Hz, cycles={cycles!r}: expected positive values")
    if window not in WINDOWS:
        raise SafeError(f"tone burst window {window!r}: expected one of {sorted(WINDOWS)}")
    T = cycles / fc_hz
    t = np.linspace(0.0, T, int(np.ceil(cycles * points_per_cycle)) + 1)
    f = amplitude_n * WINDOWS[window](t / T) * np.sin(TWO_PI * fc_hz * t)
    return ForceHistory.from_samples(t, f)
