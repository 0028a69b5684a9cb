"""What a wave sensor should see: the packets of every mode along every ray path.

From the plate outline, the source and sensor positions and the nominal specimen,
``predict_packets`` lists, per analysis frequency, the packet of each mode (A0, S0,
SH0 and whatever else SAFE finds below the band's top) along the direct path and
along the edge reflections (image sources, ``engine.waves.ray_paths``):

* travel time r / c_g(f) with the SAFE group velocity along the path's direction
  (the image's ray; for an anisotropic plate this is the velocity along the wave
  vector, not the ray's: beam skew is neglected);
* relative amplitude |H(f)| of ``engine.safe.mode_transfer`` (surface strain, the
  source's load and faces, the sensor's face; every edge taken as a perfect reflector
  without mode conversion: the worst case for a foreign packet);
* width: the time std of the packet's scalogram amplitude |W| at f, from the source's
  own scalogram through the wavelet (``source_signature``) broadened by dispersion
  over the path: sigma^2 = sigma_0^2 + (beta / sigma_0)^2, beta = r d(1/c_g)/d omega
  (a Gaussian packet of amplitude std sigma_0 has a spectral amplitude std 1/sigma_0);
  the peak drops by sqrt(sigma_0 / sigma) (energy kept).

``SourceModel`` is what the analysis knows of the source (kind, duration, burst,
load, faces). Pure: arrays and frozen dataclasses. Units: s, Hz, m, m/s.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.fft import next_fast_len

from .. import safe, waves
from ..laminate import Laminate

__all__ = ["SourceModel", "Packet", "source_signature", "predict_packets", "isotropic", "model_maxima"]


@dataclass(frozen=True)
class SourceModel:
    """What the analysis knows of a wave source.

    kind: 'pencil' (duration = rise time), 'hammer' (contact time), 'tone_burst' or
    'pzt' (a burst of ``cycles`` at ``frequency_hz`` with ``window``). load: 'normal'
    (a force along +z), 'pin' (a piezo disc of ``radius_m``) or 'inplane' (a point force along
    the path: a lead broken on the edge, its directivity not modelled); faces: ((face, sign), ...)
    of the loaded faces (a collocated top/bottom pair driven in phase: S modes only,
    in anti-phase: A modes only). electrical: its excitation may leak into the sensor
    channels at the source time (crosstalk).
    """

    kind: str = "pencil"
    duration_s: float = 1.0e-6
    frequency_hz: float | None = None
    cycles: float | None = None
    window: str = "hann"
    load: str = "normal"
    radius_m: float = 0.0
    faces: tuple[tuple[str, float], ...] = (("top", 1.0),)
    electrical: bool = False

    def force(self) -> safe.ForceHistory:
        """Unit-amplitude force history."""
        if self.kind == "pencil":
            return safe.pencil_lead_break(self.duration_s)
        if self.kind == "hammer":
            return safe.hammer_force(self.duration_s)
        return safe.tone_burst(self.frequency_hz, self.cycles, window=self.window)

    @property
    def families(self) -> frozenset[str]:
        """Mode families it excites: 'S' (symmetric, incl. SH) and/or 'A'."""
        if len(self.faces) == 2:
            same = self.faces[0][1] == self.faces[1][1]
            # a pin force acts along u: in phase, u adds for S modes; a normal force
            # acts along w: in phase, w adds for A modes
            sym = same if self.load in ("pin", "inplane") else not same
            return frozenset({"S"} if sym else {"A"})
        return frozenset({"S", "A"})


@dataclass(frozen=True)
class Packet:
    """One predicted packet at a sensor over the analysis grid (NaN where the mode does
    not exist): its mode ('A0', ...), path ('direct', 'x=0', ...), length (m), travel
    time (s), relative scalogram peak and scalogram amplitude time std (s); with
    ``predict_packets(..., fs_hz=...)`` also the packet's own model scalogram |W|, from
    the onset on (the same scale for every packet of a sensor)."""

    mode: str
    path: str
    length_m: float
    delay_s: np.ndarray
    amplitude: np.ndarray
    spread_s: np.ndarray
    model_step_s: float = 0.0                 # the model scalogram's time step (0: none)
    model_w: np.ndarray | None = None         # |W| of the packet alone (nf, m), t = k step from onset
    model_dw: np.ndarray | None = None        # |d|W|/dt| of it (1/s)


def _half_turn(direction_deg: float) -> float:
    """The same direction in [-90, 90): a plate's guided waves along theta and theta + 180
    deg are the same (k -> -k)."""
    return (direction_deg + 90.0) % 180.0 - 90.0


def isotropic(lam: Laminate) -> bool:
    """One isotropic ply: every direction is the same."""
    return len(lam.plies) == 1 and all(m.isotropic for m in lam.materials.values())


def family(mode: str) -> str:
    """'A' for A0, A1, ...; 'S' for S0, SH0, S1, ..."""
    return "A" if mode.startswith("A") else "S"


@functools.lru_cache(maxsize=32)
def _signature(source: SourceModel, freqs: tuple, bandwidth: float, center: float):
    f = np.asarray(freqs)
    wl = waves.Wavelet(bandwidth, center)
    fs = 20.0 * f.max()
    span = source.force().duration_s + 12 * float(wl.time_std_s(f.min()))
    n = int(np.ceil(2 * span * fs)) + 64
    t = (np.arange(n) - 32) / fs
    x = source.force()(t)
    x = np.gradient(x, t) if source.kind in ("pencil",) else x   # a step: its derivative's packet
    A = np.abs(waves.cwt(x, fs, f, wl, precision="double"))
    centre, spread, level = np.empty(f.size), np.empty(f.size), A.max(axis=1)
    for i in range(f.size):
        a2 = A[i] ** 2
        centre[i] = float(np.sum(t * a2) / np.sum(a2))
        # energy std of |W|^2; the amplitude |W| of a Gaussian has sqrt(2) x that std
        spread[i] = math.sqrt(2.0 * float(np.sum((t - centre[i]) ** 2 * a2) / np.sum(a2)))
    return centre, spread, level


def source_signature(source: SourceModel, freqs_hz, wavelet: waves.Wavelet):
    """(centre, spread, level) of the source's scalogram over ``freqs_hz``: the centre
    time after onset (s) and the amplitude time std (s) of |W| of the force history
    (a step's: of its derivative, whose packet the waves carry), and its peak level."""
    return _signature(source, tuple(float(f) for f in np.atleast_1d(freqs_hz)), float(wavelet.bandwidth),
                      float(wavelet.center))


def _transfer(lam, direction, f, length_m, source, sensor_face, sensor_length_m, top) -> dict:
    """{mode: complex strain transfer} of the source (its faces summed) along a path."""
    H = {}
    for face, sign in source.faces:
        h = safe.mode_transfer(lam, length_m, f, direction_deg=direction, quantity="strain",
                               sensor_length_m=min(sensor_length_m, 1.9 * length_m), source="point",
                               load=source.load, actuator_radius_m=source.radius_m, source_face=face,
                               sensor_face=sensor_face, fmax_hz=top)
        for k, v in h.items():
            H[k] = H.get(k, 0.0) + sign * v
    return H


@functools.lru_cache(maxsize=64)
def _along(lam: Laminate, direction: float, freqs: tuple, length_m: float, source: SourceModel,
           sensor_face: str, sensor_length_m: float, top: float):
    """{mode: (c_g, |H|)} along one direction and path length."""
    f = np.asarray(freqs)
    H = _transfer(lam, direction, f, length_m, source, sensor_face, sensor_length_m, top)
    vel = safe.mode_velocities(lam, f, direction_deg=direction, fmax_hz=top)
    return {mode: (vel[mode][1], np.abs(h)) for mode, h in H.items() if mode in vel}


@functools.lru_cache(maxsize=8)
def _model_grid(source: SourceModel, top: float, fs_hz: float, n: int):
    """(FFT length, band mask, band frequencies, tapered source spectrum) of the model records."""
    n_fft = next_fast_len(8 * n, real=True)
    fg = np.fft.rfftfreq(n_fft, 1.0 / fs_hz)
    band = (fg > 0) & (fg <= top)
    fb = fg[band]
    taper = np.where(fb <= 0.9 * top, 1.0, 0.5 * (1 + np.cos(np.pi * (fb - 0.9 * top) / (0.1 * top))))
    return n_fft, band, fb, source.force().spectrum(fb) * taper


@functools.lru_cache(maxsize=128)
def _model_records(lam, direction, length_m, source, sensor_face, sensor_length_m, top, fs_hz, n):
    """{mode: strain record of that mode alone along the path} (n samples at fs_hz, t = 0 at
    the onset; unit force; the source spectrum tapered over the top 10 % below ``top``).
    Cached: the wavelet candidates of a run share them (profiled: 3.5 of 8.9 s of the
    built-in CFRP rig's wave analysis went to recomputing them per wavelet)."""
    n_fft, band, fb, F = _model_grid(source, float(top), float(fs_hz), int(n))
    fg_size = n_fft // 2 + 1
    out = {}
    for mode, h in _transfer(lam, direction, fb, length_m, source, sensor_face, sensor_length_m, top).items():
        Y = np.zeros(fg_size, complex)
        Y[band] = np.conj(h) * F
        out[mode] = np.fft.irfft(Y, n_fft)[:n] * fs_hz
    return out


def predict_packets(lam: Laminate, source: SourceModel, source_xy, sensor_xy, plate_size_m, freqs_hz,
                    wavelet: waves.Wavelet, *, sensor_face: str = "top", sensor_length_m: float = 0.0,
                    order: int = 1, min_level: float = 1e-3, fs_hz: float | None = None,
                    duration_s: float = 0.0) -> list[Packet]:
    """Every packet at the sensor (direct path first), over ``freqs_hz``.

    Modes whose amplitude stays below ``min_level`` of the strongest packet at every
    frequency are left out (not excited: SH0 in an isotropic plate). With ``fs_hz``, each
    packet also carries its own model scalogram over ``duration_s`` from the onset: the
    record that mode alone would leave along that path (SAFE transfer times the source
    spectrum), through the wavelet (``cwt_decimated``): its tails, however far from a
    Gaussian, are what a foreign packet leaves at a pick.
    """
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    key = tuple(float(x) for x in f)
    iso = isotropic(lam)
    _, spread0, _ = source_signature(source, f, wavelet)
    w = 2 * np.pi * f
    top = 2.0 * float(f.max()) if not fs_hz else min(2.0 * float(f.max()), 0.45 * fs_hz)
    n = int(np.ceil(duration_s * fs_hz)) if fs_hz else 0
    out: list[Packet] = []
    paths = waves.ray_paths(source_xy, sensor_xy, *plate_size_m, order=order)
    direct = paths[0].length_m if paths else 0.0
    for p in paths:
        if p.order and abs(p.length_m - direct) <= 1e-6 * direct:
            continue      # a source on an edge: its image in that edge is the direct ray itself
        direction = 0.0 if iso else _half_turn(round(p.direction_deg, 1) if p.order else p.direction_deg)
        models = {}
        if n >= 16:
            for mode, y in _model_records(lam, float(direction), float(p.length_m), source, sensor_face,
                                          float(sensor_length_m), top, fs_hz, n).items():
                W, step = waves.cwt_decimated(y, fs_hz, f, wavelet)
                A = np.abs(W)
                models[mode] = (step / fs_hz, A.astype(np.float32),
                                np.abs(np.gradient(A, step / fs_hz, axis=1)).astype(np.float32))
        for mode, (cg, h) in _along(lam, float(direction), key, float(p.length_m), source, sensor_face,
                                    float(sensor_length_m), top).items():
            ok = np.isfinite(cg) & (cg > 0)
            if ok.sum() < 2:
                continue
            delay = np.where(ok, p.length_m / np.where(ok, cg, 1.0), np.nan)
            slow = np.interp(w, w[ok], 1.0 / cg[ok])
            beta = p.length_m * np.gradient(slow, w) if f.size > 1 else np.zeros(f.size)
            spread = np.sqrt(spread0 ** 2 + (beta / spread0) ** 2)
            amp = np.where(ok, h * np.sqrt(spread0 / spread), np.nan)
            step, mw, mdw = models.get(mode, (0.0, None, None))
            out.append(Packet(mode, p.name, p.length_m, delay, amp, spread, step, mw, mdw))
    if out:
        top = np.nanmax([np.nanmax(pk.amplitude) for pk in out])
        out = [pk for pk in out if np.nanmax(pk.amplitude) >= min_level * top]
    return out


def model_maxima(p: Packet, rows: np.ndarray, tau: np.ndarray, lo: np.ndarray, hi: np.ndarray, mid: np.ndarray):
    """The largest |W| and |d|W|/dt| of ``p``'s model scalogram where it may lie at each of
    ``rows`` (frequency indices): the samples k0-1 .. k1 (clipped to the model) with k0 =
    floor((tau - (hi - mid)) / step), k1 = ceil((tau - (lo - mid)) / step) + 1, all arrays over
    ``rows`` (s). Returns (computed, empty, |W| max, |dW| max) over the rows: ``computed`` False
    where an input is not finite (the caller's own path then), ``empty`` where no sample is left.
    One ``reduceat`` per array instead of two slices per frequency (issue 29); the maxima are
    the same numbers."""
    n, m = p.model_w.shape
    with np.errstate(invalid="ignore"):
        f0 = np.floor((tau - (hi - mid)) / p.model_step_s)
        f1 = np.ceil((tau - (lo - mid)) / p.model_step_s)
    ok = np.isfinite(f0) & np.isfinite(f1) & (np.abs(f0) < 2 ** 52) & (np.abs(f1) < 2 ** 52)
    k0 = np.maximum(np.where(ok, f0, 0).astype(np.int64) - 1, 0)
    k1 = np.minimum(np.where(ok, f1, 0).astype(np.int64) + 2, m)
    empty = k1 - k0 < 1
    take = np.flatnonzero(ok & ~empty)
    amax = np.zeros(rows.size, p.model_w.dtype)
    damax = np.zeros(rows.size, p.model_dw.dtype)
    if take.size:
        r = rows[take]
        idx = np.stack([r * m + k0[take], r * m + k1[take]], axis=1).ravel()
        if idx[-1] >= n * m:          # the last segment runs to the end by itself
            idx = idx[:-1]
        amax[take] = np.maximum.reduceat(p.model_w.reshape(-1), idx)[::2]
        damax[take] = np.maximum.reduceat(p.model_dw.reshape(-1), idx)[::2]
    return ok, empty, amax, damax
