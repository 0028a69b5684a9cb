"""The wave-feature method: group-velocity curves of a wave run from its records.

Over 500 lines on purpose: it is one method (band, packets, picks, checks, shots)
whose steps share the same per-direction state; the physics it relies on lives in
``engine.waves`` (transform, arrivals), ``engine.waves_predict`` (packets) and
``engine.safe``.

For each propagation direction of the wave sensors (``measure_waves``):

1. band (``analysis_band``): ``band_hz``, else the source's band (a tone burst's -20 dB
   band; for a pencil or a hammer the paper's fmax/20..fmax, fmax = 50 kHz isotropic,
   200 kHz laminate, stopped where a recorded hammer force falls 10 dB) intersected
   with the -20 dB band of the direct packets in the far sensor's record; an empty
   intersection is an empty result that says why and which option to change;
2. path: source to sensor when the source is recorded (its scalogram gives the source
   time per frequency), else between the nearest and the farthest sensor of the
   direction (differential delays only: the source time is unknown when the record is
   triggered on a sensor), else (one sensor) from the trigger time;
3. packets (``engine.waves_predict``): every mode's direct path and edge reflections,
   with the SAFE group velocities of the nominal specimen; a pick is a scalogram
   maximum inside the target's predicted window (nominal velocity +- ``gate_margin``)
   that lies nearer the target's prediction than any foreign packet's; the frequency is
   dropped (and counted) where foreign packets (another mode, any reflection, the
   excitation's crosstalk) reach ``leak_db`` of the pick's level at its time, or could
   shift it by more than ``max_bias`` of the travel time (a first-order bound, which
   otherwise joins the pick's sigma); with the source time unknown the window also spans
   its possible range;
4. checks: every velocity is compared with the predicted direct-path velocities of all
   modes; nearer another mode's: relabelled (if that mode has no point there) or
   rejected; farther than ``gate_margin`` from every mode: rejected;
5. refinement: the predictions are rescaled by what stage 1 measured (a smooth ratio
   per mode, its scatter as the new margin; the source time fitted when unknown) and
   the picks are redone (stage 2);
6. wavelet: ``wavelet``, else the one of a few candidates (the paper's for the
   material, a tone burst's band resolution, cmor2-2, cmor2-1, cmor1-1, cmor0.5-1) that
   yields the most independent points; S0 and A0 use the same one;
7. shots: per shot a curve; across shots the mean, with the scatter-based sigma (not
   below the per-shot noise sigma over sqrt(n)) and the wavelet-bias term of a
   centre-frequency sweep (docs/wavelet-bias.md) in quadrature;
8. the features keep only points a wavelet resolution apart (``independent_points``).

Pure: arrays and small frozen dataclasses in, a ``WaveResult`` out (its notes and the
per-curve ``dropped`` counts included); no files, no run store. Units: s, Hz, m, m/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from . import waves
from .laminate import Laminate
from .safe import mode_velocities
from .waves_predict import Packet, SourceModel, family, predict_packets, source_signature

__all__ = ["WaveSettings", "Sensor", "WaveSetup", "WaveCurve", "WaveResult", "Band", "default_wavelet",
           "analysis_band", "echo_path", "noise_rms", "combine_shots", "measure_waves", "sensor_delay",
           "signal_band", "snr_band"]

MODES = ("A0", "S0")


@dataclass(frozen=True)
class WaveSettings:
    """Choices of the wave measurement (None: automatic).

    wavelet: (B, C) of the complex Morlet; default: the candidate giving the most
        independent points (module docstring, step 6).
    band_hz: (fmin, fmax) of the CWT grid; default from the source and the records (step 1).
    n_freqs: points of the CWT grid.
    assign: 'instantaneous' (reassigned, bias-corrected) or 'nominal' (the paper).
    min_snr_db: reject arrivals weaker than this over the pre-trigger noise.
    gate_margin: relative uncertainty of the nominal SAFE group velocities (the picking
        window's half-width, and the largest deviation a pick may have from its mode).
    leak_db, max_bias: drop a frequency where foreign packets may reach this level (dB) of
        the pick, or shift it by more than this fraction of the path's travel time (the
        shift bound of the ones kept joins the pick's sigma).
    band_db: the band of the direct packets: where their spectrum is within this of its peak.
    reflections: edge reflections predicted: image-source order 0, 1 or 2.
    min_points: fewest valid frequencies for a curve to be reported.
    report_s0: put the S0 curve in the features (it is always measured).
    """

    wavelet: tuple[float, float] | None = None
    band_hz: tuple[float, float] | None = None
    n_freqs: int = 100
    assign: str = "instantaneous"
    min_snr_db: float = 20.0
    gate_margin: float = 0.10
    leak_db: float = -20.0
    max_bias: float = 0.005
    band_db: float = -20.0
    reflections: int = 1
    min_points: int = 5
    report_s0: bool = True


@dataclass(frozen=True)
class Sensor:
    """A wave sensor: its channel, distance (m) and direction (deg) from the source, its
    length along the path (m), its (x, y) on the plate (m; None: unknown, no reflections
    predicted), face ('top', 'bottom'), declared response (first-order high-pass corner,
    resonance frequency (Hz) and Q; None: flat) and the mode families its record holds
    ('AS'; 'S' or 'A' for the sum or difference of a top/bottom pair)."""

    channel: str
    distance_m: float
    direction_deg: float = 0.0
    length_m: float = 0.0
    xy: tuple[float, float] | None = None
    face: str = "top"
    highpass_hz: float | None = None
    resonance_hz: float | None = None
    resonance_q: float = 5.0
    families: str = "AS"


@dataclass(frozen=True)
class WaveSetup:
    """What the method needs of a wave run besides its signals.

    plate_size_m: (length, width) of the plate, m. source_xy: the wave source, m.
    pretrigger: samples before the trigger (t = 0). sensors: the wave sensors, in
    channel order. force_channel: the channel recording the source (force or
    excitation voltage), if any. trigger_distance_m: distance of the trigger sensor from
    the source when the record is triggered on a wave sensor (the source time is then
    unknown), else None. source: what is known of the source.
    """

    laminate: Laminate
    plate_size_m: tuple[float, float]
    source_xy: tuple[float, float]
    fs_hz: float
    pretrigger: int
    sensors: tuple[Sensor, ...]
    force_channel: str | None = None
    trigger_distance_m: float | None = None
    source: SourceModel = SourceModel()


@dataclass(frozen=True)
class WaveCurve:
    """One measured curve of the features: its independent points (Hz, m/s, m/s) and
    why the other frequencies of the band were dropped ({reason: count})."""

    mode: str
    direction_deg: float
    frequency_hz: np.ndarray
    group_velocity_m_s: np.ndarray
    sigma_m_s: np.ndarray
    dropped: Mapping[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class WaveResult:
    """What ``measure_waves`` found.

    features: the curves for the features document, in order. curves / arrivals: every
    measured curve on the full grid and the first shot's far-sensor arrivals, by key
    '<mode>_<direction>' (e.g. 'A0_0'). wave_path_m / sensor_length_m: path and sensor
    length of the first direction (None without one). dropped: per key, why frequencies
    were dropped ({reason: count}). notes: what was done, in order.
    """

    features: tuple[WaveCurve, ...]
    curves: Mapping[str, waves.GroupVelocity]
    arrivals: Mapping[str, waves.Arrivals]
    wave_path_m: float | None
    sensor_length_m: float | None
    notes: tuple[str, ...]
    dropped: Mapping[str, Mapping[str, int]] = field(default_factory=dict)


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


def _source_band(laminate: Laminate, fs: float, source: SourceModel, level_db: float,
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


def snr_band(x: np.ndarray, noise: np.ndarray, fs_hz: float, snr_db: float = 20.0,
             fmin_hz: float = 0.0) -> tuple[float, float] | None:
    """The contiguous band around the best signal-to-noise frequency where the scalogram
    peak of ``x`` (cmor2-1, 80 log-spaced frequencies) stands ``snr_db`` above the
    white-noise level of ``noise`` (the pre-trigger samples): the test ``arrival_times``
    applies to every pick, Hz; None when nothing is that far above the noise."""
    x = np.asarray(x, float)
    std = float(np.std(np.asarray(noise, float)))
    if not std > 0:
        return None
    f = np.geomspace(max(fmin_hz, 8.0 * fs_hz / x.size), 0.45 * fs_hz, 80)
    wl = waves.PAPER_ALUMINIUM
    peak = np.abs(waves.cwt(x - x[0], fs_hz, f, wl)).max(axis=1)
    snr = 20 * np.log10(np.maximum(peak, 1e-300) / waves.white_noise_level(std, fs_hz, f, wl))
    k = int(np.argmax(snr))
    if snr[k] < snr_db:
        return None
    lo = hi = k
    while lo > 0 and snr[lo - 1] >= snr_db:
        lo -= 1
    while hi < f.size - 1 and snr[hi + 1] >= snr_db:
        hi += 1
    return float(f[lo]), float(f[hi])


def analysis_band(laminate: Laminate, fs_hz: float, settings: WaveSettings = WaveSettings(),
                  force: np.ndarray | None = None, pretrigger: int = 0, *,
                  source: SourceModel | None = None, record: np.ndarray | None = None,
                  noise: np.ndarray | None = None) -> Band:
    """The analysis frequencies (Hz) and how they were chosen (module docstring, step 1).

    ``force``: the source force record (any unit) of the first shot, if recorded (a
    hammer's band stops where it falls 10 dB). ``record``: the direct packets of the far
    sensor (its record from the first possible arrival on); ``noise``: its pre-trigger
    samples. The grid must lie in the band the record holds: for a tone burst its
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
        fmin, fmax, notes = _source_band(laminate, fs, source, settings.band_db, force, pretrigger)
        fmax = min(fmax, 0.4 * fs)
        how = (f"the {source.kind.replace('_', ' ')}'s {settings.band_db:g} dB band"
               if source.kind in ("tone_burst", "pzt") else "the default for the material")
    if not 0 < fmin < fmax < fs / 2:
        raise waves.WaveError(f"wave band {fmin:g}..{fmax:g} Hz: expected 0 < fmin < fmax < rate/2 = {fs / 2:g} Hz")
    narrow = source.kind in ("tone_burst", "pzt")
    noisy = noise is not None and np.size(noise) >= 16 and float(np.std(noise)) > 0
    if record is not None and (narrow or noisy):
        floor = min(fmin, 0.1 * fmax) / 2
        energy = signal_band(record, fs, settings.band_db, fmin_hz=floor)
        if energy is None:
            return Band(np.zeros(0), tuple(notes), "no velocity: the wave records are silent")
        if narrow:
            got, what = energy, f"the {settings.band_db:g} dB band of the direct packets"
        else:
            got = snr_band(record, noise, fs, -settings.band_db, fmin_hz=floor)
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


def echo_path(src: tuple[float, float], dst: tuple[float, float], length: float, width: float) -> float:
    """Shortest source -> edge -> sensor path on a length x width plate (mirror images), m."""
    return min(p.length_m for p in waves.ray_paths(src, dst, length, width, 1) if p.order == 1)


def noise_rms(x: np.ndarray, pre: int, fs: float, freqs: np.ndarray, wl: waves.Wavelet) -> np.ndarray | None:
    """RMS of |W| per frequency of the record's noise (None: too short or noiseless).

    The noise std is the smallest std of the 64-sample blocks of the pre-trigger samples
    and of the last quarter of the record: a record triggered on a sensor holds a packet
    (or the source) before its trigger, and one whose source is recorded ends quiet.
    """
    m = int(0.8 * pre)
    tail = np.asarray(x[-(len(x) // 4):], float)
    blocks = [b for seg in (np.asarray(x[:m], float), tail)
              for b in np.array_split(seg, max(len(seg) // 64, 1)) if b.size >= 64]
    if m < 64 or not blocks:
        return None
    std = float(min(np.std(b - b.mean()) for b in blocks))
    if not std > 0:  # a noiseless (simulated) record: nothing to compare with
        return None
    return waves.white_noise_level(std, fs, freqs, wl)


def sensor_delay(sensor: Sensor, freqs_hz) -> np.ndarray:
    """Group delay (s) of the sensor's declared response at ``freqs_hz``: first-order
    high-pass w_c / (w^2 + w_c^2) plus the resonance w0^2 / (w0^2 - w^2 + i w w0 / Q)."""
    w = 2 * np.pi * np.asarray(freqs_hz, float)
    tau = np.zeros(w.shape)
    if sensor.highpass_hz:
        wc = 2 * np.pi * sensor.highpass_hz
        tau += wc / (w * w + wc * wc)
    if sensor.resonance_hz:
        w0, q = 2 * np.pi * sensor.resonance_hz, sensor.resonance_q
        # phase -atan2(w w0 / Q, w0^2 - w^2); tau = -d phase / d w
        num = (w0 / q) * (w0 * w0 + w * w)
        den = (w0 * w0 - w * w) ** 2 + (w * w0 / q) ** 2
        tau += num / den
    return tau


def combine_shots(curves: list[waves.GroupVelocity], floor: np.ndarray | None = None) -> waves.GroupVelocity:
    """Mean over shots; sigma: the scatter over shots / sqrt(n), not below the mean
    per-shot sigma / sqrt(n) (a single shot: its own sigma), with ``floor`` (a bias
    term, m/s) added in quadrature."""
    f = curves[0].frequencies_hz
    V = np.array([c.velocity_m_s for c in curves])
    S = np.array([c.sigma_m_s for c in curves])
    ok = np.isfinite(V) & np.isfinite(S) & (S > 0)
    n = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(n > 0, np.where(ok, V, 0.0).sum(axis=0) / np.maximum(n, 1), np.nan)
        scatter = np.sqrt(np.where(ok, (V - v) ** 2, 0.0).sum(axis=0) / np.maximum(n - 1, 1))
        noise = np.where(ok, S, 0.0).sum(axis=0) / np.maximum(n, 1)
        s = np.where(n > 1, np.maximum(scatter, noise), noise) / np.sqrt(np.maximum(n, 1))
    if floor is not None:
        s = np.hypot(s, np.where(np.isfinite(floor), floor, 0.0))
    valid = n > 0
    return waves.GroupVelocity(f, np.where(valid, v, np.nan), np.where(valid, s, np.nan), valid)


# --------------------------------------------------------------------------- one direction
@dataclass
class _Direction:
    """One propagation direction: its sensors, predictions and source-time window."""

    setup: WaveSetup
    settings: WaveSettings
    freqs: np.ndarray
    direction: float
    sensors: list[Sensor]                 # by distance
    t_src0: np.ndarray | None = None      # source scalogram centre after onset, per frequency
    t0: tuple[float, float] = (0.0, 0.0)  # source onset on the record axis: known, or its range
    t0_prior: tuple[float, float] | None = None   # its range from the trigger (source time unknown)
    scale: dict = field(default_factory=dict)    # mode -> ratio measured / nominal (per frequency)
    margin: dict = field(default_factory=dict)   # mode -> relative velocity uncertainty
    packets: dict = field(default_factory=dict)  # (channel, wavelet) -> [Packet]
    nominal_cg: dict = field(default_factory=dict)  # mode -> direct-path nominal c_g
    strict: bool = True        # stage 1 (False): overlaps are not dropped, the picks only rescale
    record_s: float = 0.0      # how long after the earliest onset the records reach (s)

    @property
    def known_source(self) -> bool:
        return self.setup.force_channel is not None

    def pair(self, mode: str) -> tuple[Sensor, Sensor | None]:
        """(far, near) sensors holding ``mode``; near is None when the source is recorded."""
        ss = [s for s in self.sensors if family(mode) in s.families]
        if not ss:
            return None, None
        far = ss[-1]
        near = None if self.known_source or len(ss) < 2 else ss[0]
        return far, near


def _direction(setup: WaveSetup, settings: WaveSettings, freqs: np.ndarray, direction: float,
               wss: list[Sensor]) -> _Direction:
    d = _Direction(setup, settings, freqs, direction, sorted(wss, key=lambda w: w.distance_m))
    if setup.trigger_distance_m is not None and not d.known_source:
        # triggered on a sensor: the onset lies before the first packet reaching it
        fast = max(float(np.nanmax(_nominal(d, m))) for m in MODES)
        slow = min(float(np.nanmin(_nominal(d, m))) for m in MODES)
        dur = setup.source.force().duration_s
        d.t0_prior = (-setup.trigger_distance_m / (slow * (1 - settings.gate_margin)) - dur,
                      -setup.trigger_distance_m / (fast * (1 + settings.gate_margin)))
        d.t0 = d.t0_prior
    return d


def _locate_onset(d: _Direction, wl: waves.Wavelet, rec: Mapping[str, np.ndarray], cache: dict) -> None:
    """The source onset of one shot when its time is unknown (triggered on a sensor): the
    onset within the trigger's range that best lays the predicted direct packets of the
    nearest sensor (the least blurred by the velocity uncertainty) on its scalogram
    (amplitude-weighted sum of |W| at the predicted centres); the range kept is the
    uncertainty those velocities leave, r gate_margin / c_g, plus two samples."""
    if d.t0_prior is None:
        return
    fs, pre, freqs = d.setup.fs_hz, d.setup.pretrigger, d.freqs
    s = d.sensors[0]
    key = (s.channel, wl)
    if key not in cache:
        cache[key] = waves.cwt(rec[s.channel], fs, freqs, wl)
    A = np.abs(cache[key])
    A = A / np.maximum(A.max(axis=1, keepdims=True), 1e-300)
    lo, hi = d.t0_prior
    grid = np.arange(lo, hi + 0.5 / fs, 1.0 / fs)
    c = source_signature(d.setup.source, freqs, wl)[0] + sensor_delay(s, freqs)
    direct = [p for p in _packets(d, s, wl) if p.path == "direct"]
    if not direct:
        return
    amax = np.nanmax([p.amplitude for p in direct], axis=0)
    score = np.zeros(grid.size)
    slowest = np.inf
    for p in direct:
        sc = d.scale.get(p.mode)
        delay = p.delay_s / (sc if sc is not None else 1.0)
        ok = np.isfinite(delay) & np.isfinite(p.amplitude)
        if not ok.any():
            continue
        slowest = min(slowest, float(np.nanmin(p.length_m / delay[ok])))
        idx = np.rint((grid[None, :] + (c + delay)[ok, None]) * fs).astype(int) + pre
        idx = np.clip(idx, 0, A.shape[1] - 1)
        rows = np.flatnonzero(ok)
        score += ((p.amplitude[ok] / amax[ok])[:, None] * A[rows[:, None], idx]).sum(axis=0)
    t0 = float(grid[int(np.argmax(score))])
    mu = max(d.margin.values(), default=d.settings.gate_margin) if d.margin else d.settings.gate_margin
    half = s.distance_m * mu / slowest + 2.0 / fs
    d.t0 = (t0 - half, t0 + half)


def _packets(d: _Direction, s: Sensor, wl: waves.Wavelet) -> list[Packet]:
    key = (s.channel, wl)
    if key not in d.packets:
        setup = d.setup
        if s.xy is None:
            xy = (setup.source_xy[0] + s.distance_m * math.cos(math.radians(s.direction_deg)),
                  setup.source_xy[1] + s.distance_m * math.sin(math.radians(s.direction_deg)))
            order = 0
        else:
            xy, order = s.xy, d.settings.reflections
        pk = predict_packets(setup.laminate, setup.source, setup.source_xy, xy, setup.plate_size_m, d.freqs,
                             wl, sensor_face=s.face if s.families == "AS" else "top",
                             sensor_length_m=s.length_m, order=order, fs_hz=setup.fs_hz,
                             duration_s=d.record_s)
        d.packets[key] = [p for p in pk if family(p.mode) in s.families]
    return d.packets[key]


def _src_time(d: _Direction, wl: waves.Wavelet, src_arr: waves.Arrivals | None) -> tuple[np.ndarray, np.ndarray]:
    """Source reference time per frequency on the record axis: (earliest, latest)."""
    if src_arr is not None:
        t = np.where(src_arr.valid, src_arr.times_s, np.nan)
        return t, t
    c, _, _ = source_signature(d.setup.source, d.freqs, wl)
    return c + d.t0[0], c + d.t0[1]


def _arrivals(d: _Direction, x: np.ndarray, s: Sensor | None, mode: str, wl: waves.Wavelet,
              src_arr: waves.Arrivals | None, W: np.ndarray | None = None,
              path_m: float = 1.0) -> waves.Arrivals:
    """Arrivals of ``mode``'s direct packet at sensor ``s`` (None: the source record, no
    gate); ``path_m``: the measured path (the bias bound is relative to its travel time)."""
    fs, pre, freqs = d.setup.fs_hz, d.setup.pretrigger, d.freqs
    W = waves.cwt(x, fs, freqs, wl) if W is None else W
    noise = noise_rms(x, pre, fs, freqs, wl)
    if s is None:
        # the source's own scalogram: its maximum is the source time at every frequency of
        # the band, wherever its instantaneous frequency lies (no leakage test)
        return waves.arrival_times(W, fs, freqs, wl, t0_index=pre, noise_rms=noise,
                                   min_snr_db=d.settings.min_snr_db, min_rel_db=-60.0, max_freq_offset=np.inf)
    lo_s, hi_s = _src_time(d, wl, src_arr)
    lo_s = lo_s + sensor_delay(s, freqs)
    hi_s = hi_s + sensor_delay(s, freqs)
    pk = _packets(d, s, wl)
    target = next((p for p in pk if p.mode == mode and p.path == "direct"), None)
    nf = freqs.size
    reason = [""] * nf
    gate_lo, gate_hi = np.full(nf, np.nan), np.full(nf, np.nan)
    if target is None:
        reason = ["mode not excited at this sensor"] * nf
        return _rejected(freqs, wl, reason)
    A = np.abs(W)
    t = (np.arange(A.shape[1]) - pre) / fs

    ranges = {}
    for p in pk:     # where each packet may lie on the record axis: (earliest, latest) per frequency
        mu = d.margin.get(p.mode, d.settings.gate_margin)
        sc = d.scale.get(p.mode)
        dl = p.delay_s / (np.where(np.isfinite(sc), sc, 1.0) if sc is not None else 1.0)
        ranges[id(p)] = (lo_s + dl / (1 + mu), hi_s + dl / (1 - mu))

    def rng(p: Packet, i: int) -> tuple[float, float]:
        r = ranges[id(p)]
        return r[0][i], r[1][i]

    for i in range(nf):
        if not np.isfinite(target.delay_s[i]) or not np.isfinite(lo_s[i]):
            reason[i] = "no prediction"
            continue
        a_lo, a_hi = rng(target, i)
        sig = target.spread_s[i]
        k0 = max(int(np.ceil((a_lo - 2 * sig - t[0]) * fs)), 1)
        k1 = min(int(np.floor((a_hi + 2 * sig - t[0]) * fs)) + 1, A.shape[1] - 1)
        if k1 - k0 < 3:
            reason[i] = "window outside the record"
            continue
        a = A[i, k0 - 1:k1 + 1]
        peaks = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:])) + k0
        if peaks.size:
            peaks = peaks[A[i, peaks] >= 0.05 * A[i, peaks].max()]
        best = None
        def z(lo_p, hi_p, sp, tc):
            """Distance of tc from a packet's nominal place, in its own uncertainty (the
            half-width of where it may lie plus its width)."""
            return abs(tc - 0.5 * (lo_p + hi_p)) / (0.5 * (hi_p - lo_p) + sp)

        for k in peaks:
            tc = t[k]
            z_t = z(a_lo, a_hi, sig, tc)
            mine = True
            for p in pk:
                if p is target or not np.isfinite(p.delay_s[i]):
                    continue
                p_lo, p_hi = rng(p, i)
                if z(p_lo, p_hi, p.spread_s[i], tc) < z_t:
                    mine = False
                    break
            if mine and (best is None or A[i, k] > A[i, best]):
                best = k
        if best is None:
            reason[i] = "no packet at the predicted time" if peaks.size else "peak on the window edge"
            continue
        gate_lo[i], gate_hi[i] = t[best] - 0.75 * sig, t[best] + 0.75 * sig
    arr = waves.arrival_times(W, fs, freqs, wl, t0_index=pre, gate_s=(gate_lo, gate_hi), noise_rms=noise,
                              min_snr_db=d.settings.min_snr_db, first_fraction=0.999)
    valid = arr.valid.copy()
    why = list(arr.reason)
    leak_max = 10 ** (d.settings.leak_db / 20)
    foreign = []          # per frequency: [(level at the pick, time-shift bound, label)]
    xt = None
    if d.setup.source.electrical and src_arr is not None:
        xt = (np.where(src_arr.valid, src_arr.times_s, np.nan), source_signature(d.setup.source, freqs, wl)[1])
    bias_s = np.zeros(nf)
    s_delay = sensor_delay(s, freqs)
    c_src = source_signature(d.setup.source, freqs, wl)[0] + s_delay
    for i in range(nf):
        if reason[i]:
            valid[i], why[i] = False, reason[i]
            continue
        if not valid[i]:
            continue
        tc, st = arr.times_s[i], target.spread_s[i]
        # the packet's measured width (curvature of log|W| at the pick: amplitude std
        # 1 / (fs sqrt(-d2))) where wider than predicted (a sloping spectrum inside the
        # window, dispersion): every packet at this frequency is taken as that much wider
        kc = int(round((tc - t[0]) * fs))
        widen = 1.0
        if 1 <= kc < A.shape[1] - 1:
            la, lb, lc = np.log(np.maximum(A[i, kc - 1:kc + 2], 1e-300))
            d2 = la - 2 * lb + lc
            if d2 < 0:
                widen = float(np.clip(1.0 / (fs * math.sqrt(-d2)) / st, 1.0, 3.0))
        st *= widen
        # a foreign packet of level rho at the pick, g from it, shifts the maximum of a packet
        # of amplitude std st by ~ rho g st^2 / sp^2 (first order); two edges at the same
        # distance arrive together: the levels and shifts add up (worst case)
        items = []
        onset = 0.5 * (lo_s[i] + hi_s[i]) - c_src[i]          # the onset on the record axis
        peak_t = target.model_w[i].max() if target.model_w is not None else 0.0
        for p in pk:
            if p is target or not np.isfinite(p.delay_s[i]):
                continue
            p_lo, p_hi = rng(p, i)
            if p.model_w is not None and peak_t > 0:
                # the packet's own model scalogram over where it may lie (velocity margin,
                # source-time range), relative to the target's model peak; its slope and
                # level bound the shift: st^2 |dA/dt| / A_T + 0.7 st A / A_T (the phase
                # between the two rotates at most at their frequency spread)
                # the model's packet (no sensor response) sits at onset + sensor delay + tau;
                # on the record it may lie anywhere in [p_lo, p_hi] around its nominal place
                mid = onset + c_src[i] + p.delay_s[i]
                tau = tc - onset - s_delay[i]
                k0 = int(np.floor((tau - (p_hi - mid)) / p.model_step_s))
                k1 = int(np.ceil((tau - (p_lo - mid)) / p.model_step_s)) + 1
                row = p.model_w[i]
                k0, k1 = max(k0 - 1, 0), min(k1 + 1, row.size)
                if k1 - k0 < 1:
                    continue
                amax = float(row[k0:k1].max())
                damax = float(p.model_dw[i, k0:k1].max())
                rho = amax / peak_t
                items.append((rho, (st * st * damax + 0.7 * st * amax) / peak_t,
                              f"{p.mode} {p.path}", (p.mode, round(p.length_m, 3))))
                continue
            g = max(0.0, p_lo - tc, tc - p_hi)
            sp = p.spread_s[i] * widen
            rel = p.amplitude[i] / target.amplitude[i] if target.amplitude[i] > 0 else np.inf
            rho = rel * math.exp(-0.5 * (g / sp) ** 2)
            items.append((rho, rho * max(g, sp) * st * st / (sp * sp), f"{p.mode} {p.path}",
                          (p.mode, round(p.length_m, 3))))
        if xt is not None and np.isfinite(xt[0][i]):
            # the excitation's crosstalk sits at the source time (no sensor response): its
            # level is measured in this record, its width is the source's own
            ts, sx = xt[0][i], xt[1][i]
            k0 = max(int(np.floor((ts - 0.5 * sx - t[0]) * fs)), 0)
            k1 = min(int(np.ceil((ts + 0.5 * sx - t[0]) * fs)) + 1, A.shape[1])
            kc = min(max(int(round((tc - t[0]) * fs)), 0), A.shape[1] - 1)
            if k1 > k0 and A[i, kc] > 0:
                g = abs(tc - ts)
                rho = A[i, k0:k1].max() / A[i, kc] * math.exp(-0.5 * (g / sx) ** 2)
                items.append((rho, rho * max(g, sx) * st * st / (sx * sx), "crosstalk", "crosstalk"))
        if not items:
            continue
        # packets of one mode over paths of equal length (two edges at the same distance)
        # add coherently; distinct groups have unrelated phases (each known only to within
        # the velocity margin, i.e. many cycles): the shift is their rms over a uniform phase
        groups: dict = {}
        for rho, b, label, key in items:
            g = groups.setdefault(key, [0.0, 0.0, label])
            g[0] += rho
            g[1] += b
        level = sum(g[0] for g in groups.values())
        shift = math.sqrt(sum(g[1] ** 2 for g in groups.values()) / 2.0)
        travel = path_m * target.delay_s[i] / target.length_m
        if d.strict and (level > leak_max or shift > d.settings.max_bias * travel):
            worst = max(groups.values(), key=lambda g: g[1])[2]
            valid[i], why[i] = False, f"overlap: {worst}"
        else:
            bias_s[i] = shift
    # the sensor's own group delay is not the plate's; the foreign packets' shift bound
    # joins the time uncertainty as a systematic term
    return replace(arr, valid=valid, reason=tuple(why), times_s=arr.times_s - sensor_delay(s, freqs),
                   sigma_s=np.hypot(arr.sigma_s, bias_s))


def _rejected(freqs, wl, reason) -> waves.Arrivals:
    nan = np.full(freqs.size, np.nan)
    return waves.Arrivals(freqs, nan, nan, nan, nan, np.zeros(freqs.size, bool), tuple(reason), wl)


def _velocity(d: _Direction, mode: str, wl: waves.Wavelet, rec: Mapping[str, np.ndarray],
              cache: dict) -> tuple[waves.GroupVelocity, dict]:
    """One shot's curve of ``mode`` and its arrivals {'far', 'near', 'source'}."""
    far, near = d.pair(mode)
    force = d.setup.force_channel
    assign = d.settings.assign

    def W(ch):
        if (ch, wl) not in cache:
            cache[(ch, wl)] = waves.cwt(rec[ch], d.setup.fs_hz, d.freqs, wl)
        return cache[(ch, wl)]

    src = None
    if force is not None:
        if ("src", force, wl) not in cache:
            cache[("src", force, wl)] = _arrivals(d, rec[force], None, mode, wl, None, W(force))
        src = cache[("src", force, wl)]
    out = {"source": src}
    path = far.distance_m - (near.distance_m if near is not None else 0.0)
    a_far = _arrivals(d, rec[far.channel], far, mode, wl, src, W(far.channel), path)
    # the curvature correction needs a dispersive mode: fitted to S0's nearly constant
    # delays its tau'' is noise (docs/wavelet-bias.md); S0 is reassigned only
    correct = d.settings.assign == "instantaneous" and mode == "A0"
    if correct:
        a_far = waves.correct_dispersion_bias(a_far)
    out["far"] = a_far
    if src is not None:
        g = waves.group_velocity(a_far, far.distance_m, src, assign=assign)
    elif near is not None:
        a_near = _arrivals(d, rec[near.channel], near, mode, wl, None, W(near.channel), path)
        if correct:
            a_near = waves.correct_dispersion_bias(a_near)
        out["near"] = a_near
        g = waves.group_velocity(a_far, far.distance_m, a_near, near_distance_m=near.distance_m, assign=assign)
    else:
        g = waves.group_velocity(a_far, far.distance_m, source_time_s=0.0, assign=assign)
    return g, out


def _nominal(d: _Direction, mode: str) -> np.ndarray:
    """Direct-path nominal SAFE group velocity of ``mode`` along the direction (NaN where
    the mode does not exist on the grid)."""
    if not d.nominal_cg:
        d.nominal_cg.update({m: v[1] for m, v in mode_velocities(d.setup.laminate, d.freqs,
                                                                 direction_deg=d.direction).items()})
    return d.nominal_cg.get(mode, np.full(d.freqs.size, np.nan))


def _check_modes(d: _Direction, curves: dict[str, waves.GroupVelocity], counts: dict) -> dict:
    """Relabel or reject every point nearer another mode's prediction (module step 4)."""
    nominal = {m: _nominal(d, m) * (d.scale[m] if m in d.scale else 1.0) for m in ("A0", "S0", "SH0")}
    nominal = {m: v for m, v in nominal.items() if np.isfinite(v).any()}
    out = {m: (g.velocity_m_s.copy(), g.sigma_m_s.copy(), g.valid.copy()) for m, g in curves.items()}
    for m, g in curves.items():
        for i in np.flatnonzero(g.valid):
            v = g.velocity_m_s[i]
            dev = {k: abs(v / c[i] - 1) for k, c in nominal.items() if np.isfinite(c[i])}
            best = min(dev, key=dev.get)
            if best == m and dev[best] <= d.margin.get(m, d.settings.gate_margin) * 1.5:
                continue
            vm, sm, ok = out[m]
            ok[i] = False
            if best != m and best in out and not out[best][2][i] and \
                    dev[best] <= d.margin.get(best, d.settings.gate_margin) * 1.5:
                vb, sb, okb = out[best]
                vb[i], sb[i], okb[i] = v, g.sigma_m_s[i], True
                counts[m]["relabelled"] = counts[m].get("relabelled", 0) + 1
            else:
                counts[m]["rejected by the mode check"] = counts[m].get("rejected by the mode check", 0) + 1
            vm[i] = sm[i] = np.nan
    return {m: waves.GroupVelocity(d.freqs, v, s, ok) for m, (v, s, ok) in out.items()}


def _reasons(arrs: dict, valid: np.ndarray) -> dict[str, int]:
    """Why the frequencies not in ``valid`` were dropped (far sensor first, then near)."""
    why: dict[str, int] = {}
    for i in np.flatnonzero(~valid):
        r = ""
        for key in ("far", "near", "source"):
            a = arrs.get(key)
            if a is not None and a.reason[i]:
                r = a.reason[i]
                break
        k = _category(r)
        why[k] = why.get(k, 0) + 1
    return why


def _category(r: str) -> str:
    if r.startswith("overlap"):
        return r
    if r.startswith("SNR") or r.startswith("energy"):
        return "weak"
    if not r:
        return "outside the reassigned frequencies"
    return r.split(":")[0].split(" (")[0]


def _shot_curves(d: _Direction, wl: waves.Wavelet, shots, first_only: bool = False):
    """Per shot {mode: GroupVelocity} after the mode check, the first shot's arrivals and
    the drop counts {mode: {reason: n}} of the first shot."""
    per_shot, first_arrs, counts = [], None, None
    for j, rec in enumerate(shots[:1] if first_only else shots):
        cache: dict = {}
        cur, arrs = {}, {}
        _locate_onset(d, wl, rec, cache)
        for m in MODES:
            if d.pair(m)[0] is None:
                continue
            cur[m], arrs[m] = _velocity(d, m, wl, rec, cache)
        cnt = {m: {} for m in cur}
        before = {m: g.valid for m, g in cur.items()}
        cur = _check_modes(d, cur, cnt)
        if j == 0:
            first_arrs = arrs
            # frequencies the pickers dropped (the mode check counts its own)
            counts = {m: {**_reasons(arrs[m], before[m] | cur[m].valid), **cnt[m]} for m in cur}
        per_shot.append(cur)
    return per_shot, first_arrs, counts


def _refine(d: _Direction, per_shot: list[dict]) -> None:
    """Stage 2 predictions: per mode the smooth ratio measured / nominal and its scatter;
    the source onset when it was unknown."""
    for m in MODES:
        nom = _nominal(d, m)
        r = np.array([s[m].velocity_m_s / nom for s in per_shot if m in s])
        if r.size == 0 or not np.isfinite(r).any():
            continue
        has = np.isfinite(r).any(axis=0)
        rm = np.full(d.freqs.size, np.nan)
        rm[has] = np.nanmedian(r[:, has], axis=0)
        ok = np.isfinite(rm)
        if ok.sum() < 3:
            continue
        f = d.freqs
        deg = 1 if ok.sum() >= 8 else 0
        c = np.polynomial.polynomial.polyfit(f[ok] / f.max(), rm[ok], deg)
        fit = np.polynomial.polynomial.polyval(f / f.max(), c)
        res = rm[ok] - fit[ok]
        spread = 1.4826 * np.median(np.abs(res - np.median(res))) if res.size >= 3 else 0.0
        d.scale[m] = fit
        d.margin[m] = float(min(max(4 * spread, 0.015), d.settings.gate_margin))


def _independent(freqs, g: waves.GroupVelocity, wl: waves.Wavelet) -> np.ndarray:
    return waves.independent_points(freqs, g.valid, wl)


def _measure(d: _Direction, wl: waves.Wavelet, shots, first_only: bool = False):
    """Two-stage measurement with one wavelet: (per-shot curves, first arrivals, counts)."""
    d.scale, d.margin = {}, {}
    t0 = d.t0
    # stage 1: picks by the nominal predictions (wide margins: overlaps not judged), only
    # to rescale the predictions; stage 2: the measurement
    d.strict = False
    per_shot, first_arrs, counts = _shot_curves(d, wl, shots, first_only=True)
    d.strict = True
    _refine(d, per_shot)
    out = _shot_curves(d, wl, shots, first_only=first_only)
    d.t0 = t0
    return out


def _wavelet_candidates(d: _Direction, settings: WaveSettings) -> list[waves.Wavelet]:
    if settings.wavelet:
        return [waves.Wavelet(*settings.wavelet)]
    f = d.freqs
    cands = [default_wavelet(d.setup.laminate)]
    if f.size > 1 and f[-1] > f[0]:
        # the centre C giving ~5 independent points over the band (spacing f / (pi C) at B = 2)
        c_band = round(min(max(4 * float(np.mean(f)) / (math.pi * (f[-1] - f[0])), 1.0), 5.0) * 2) / 2
        cands.append(waves.Wavelet(2.0, c_band))
    cands += [waves.Wavelet(2.0, 2.0), waves.Wavelet(2.0, 1.5), waves.PAPER_ALUMINIUM, waves.Wavelet(1.0, 1.0),
              waves.Wavelet(0.5, 1.0)]
    out = []
    for c in cands:
        if c not in out:
            out.append(c)
    return out


def _choose_wavelet(d: _Direction, settings: WaveSettings, shots) -> tuple[waves.Wavelet, list[str]]:
    """The candidate with the most independent points over A0 and S0 (first shot)."""
    cands = _wavelet_candidates(d, settings)
    if len(cands) == 1:
        return cands[0], []
    score = {}
    for wl in cands:
        per_shot, _, _ = _measure(d, wl, shots, first_only=True)
        cur = per_shot[0]
        n_ind = sum(int(_independent(d.freqs, g, wl).sum()) for g in cur.values())
        n_modes = sum(int(g.valid.sum()) >= d.settings.min_points for g in cur.values())
        score[wl] = (n_modes, n_ind)
    # the most modes measured, then the most independent points; on a tie the earlier
    # (longer, less biased) candidate
    best = max(cands, key=lambda c: (score[c], -cands.index(c)))
    note = (f"direction {d.direction:g} deg: wavelet {best.name}, the most modes and independent points "
            "of " + ", ".join(f"{c.name} {score[c][0]}/{score[c][1]}" for c in cands))
    return best, [note]


def _sweep_term(d: _Direction, wl: waves.Wavelet, shots, combined: dict) -> dict:
    """Half the difference to a centre-frequency sweep (C / 1.5, or x 1.5 below C = 2/3)."""
    c_alt = wl.center / 1.5 if wl.center / 1.5 >= 2 / 3 else wl.center * 1.5
    alt_wl = waves.Wavelet(wl.bandwidth, c_alt)
    per_shot, _, _ = _measure(d, alt_wl, shots)
    out = {}
    for m, g in combined.items():
        alt = combine_shots([s[m] for s in per_shot if m in s])
        both = g.valid & alt.valid
        out[m] = np.where(both, 0.5 * np.abs(g.velocity_m_s - alt.velocity_m_s), 0.0)
    return out


# --------------------------------------------------------------------------- the run
def _pairs(sensors: Sequence[Sensor], shots) -> tuple[list[Sensor], list[dict], list[str]]:
    """Top/bottom sensor pairs at one position become their sum (S modes) and difference
    (A modes) records."""
    out, used, notes = [], set(), []
    recs = [dict(r) for r in shots]
    for a in sensors:
        if a.channel in used:
            continue
        b = next((o for o in sensors if o is not a and o.channel not in used and o.face != a.face
                  and abs(o.distance_m - a.distance_m) < 1e-3 and abs(o.direction_deg - a.direction_deg) < 0.5),
                 None)
        if b is None:
            out.append(a)
            continue
        top, bot = (a, b) if a.face == "top" else (b, a)
        used |= {a.channel, b.channel}
        for r in recs:
            r[f"{top.channel}+{bot.channel}"] = 0.5 * (r[top.channel] + r[bot.channel])
            r[f"{top.channel}-{bot.channel}"] = 0.5 * (r[top.channel] - r[bot.channel])
        out.append(replace(top, channel=f"{top.channel}+{bot.channel}", families="S"))
        out.append(replace(top, channel=f"{top.channel}-{bot.channel}", families="A"))
        notes.append(f"{top.channel} (top) and {bot.channel} (bottom): S modes from their sum, "
                     "A modes from their difference")
    return out, recs, notes


def measure_waves(setup: WaveSetup, shots: Sequence[Mapping[str, np.ndarray]], freqs: np.ndarray,
                  settings: WaveSettings = WaveSettings()) -> WaveResult:
    """Group-velocity curves of every direction from the shots' records.

    ``shots``: per shot, channel name -> record in physical units (every sensor of
    ``setup`` and the source channel); ``freqs``: the analysis grid (``analysis_band``).
    """
    notes: list[str] = []
    sensors, shots, pair_notes = _pairs(setup.sensors, shots)
    notes += pair_notes
    fam = setup.source.families
    if fam != frozenset("SA") and fam != frozenset("AS"):
        sensors = [replace(s, families="".join(sorted(set(s.families) & fam))) for s in sensors]
        notes.append(f"collocated actuator pair: {'S' if 'S' in fam else 'A'} modes only")
    by_dir: dict[float, list] = {}
    for ws in sensors:
        by_dir.setdefault(round(ws.direction_deg, 6), []).append(ws)
    out, curves, arrivals, dropped = [], {}, {}, {}
    path_m = length_m = None
    for direction, wss in sorted(by_dir.items()):
        if setup.force_channel is None and len({s.distance_m for s in wss}) < 2:
            notes.append(f"direction {direction:g} deg: one sensor and no source record; "
                         "velocity from the trigger time (source assumed at t = 0)")
        d = _direction(setup, settings, freqs, direction, wss)
        n_rec = len(next(iter(shots[0].values())))
        d.record_s = (n_rec - setup.pretrigger) / setup.fs_hz - (d.t0_prior[0] if d.t0_prior else 0.0)
        wl, wl_notes = _choose_wavelet(d, settings, shots)
        notes.extend(wl_notes)
        per_shot, first_arrs, counts = _measure(d, wl, shots)
        combined = {m: combine_shots([s[m] for s in per_shot if m in s]) for m in per_shot[0]}
        floor = _sweep_term(d, wl, shots, combined)
        combined = {m: combine_shots([s[m] for s in per_shot if m in s], floor[m]) for m in combined}
        for mode, gv in combined.items():
            key = f"{mode}_{direction:g}"
            far, near = d.pair(mode)
            dropped[key] = counts[mode]
            why = ", ".join(f"{k} x{n}" for k, n in sorted(counts[mode].items(), key=lambda t: -t[1])[:4])
            if gv.valid.sum() < settings.min_points:
                notes.append(f"{mode} along {direction:g} deg: {int(gv.valid.sum())} valid frequencies "
                             f"(< {settings.min_points}); not reported (dropped: {why or 'none'})")
                continue
            curves[key] = gv
            arrivals[key] = first_arrs[mode]["far"]
            ok = gv.valid
            if mode == "S0" and not settings.report_s0:
                notes.append(f"S0 along {direction:g} deg: {int(ok.sum())} frequencies measured and stored "
                             "in the run (analysis/waves), not put in the features")
                continue
            # the features carry only points a wavelet resolution apart: neighbours on the
            # dense grid share their errors (the full curve stays in the run file)
            ok = waves.independent_points(freqs, ok, wl)
            out.append(WaveCurve(mode, float(direction), freqs[ok], gv.velocity_m_s[ok], gv.sigma_m_s[ok],
                                 dict(counts[mode])))
            how = "source to sensor" if far is not None and near is None and setup.force_channel is not None \
                else ("two sensors" if near is not None else "from the trigger time")
            notes.append(f"{mode} along {direction:g} deg: {int(ok.sum())} independent frequencies "
                         f"{freqs[ok].min() / 1e3:.3g}-{freqs[ok].max() / 1e3:.3g} kHz from {len(shots)} shot(s), "
                         f"{wl.name}, {how}; dropped: {why or 'none'}")
        if path_m is None:
            far, near = d.pair("A0") if d.pair("A0")[0] is not None else d.pair("S0")
            path_m = far.distance_m - (near.distance_m if near is not None else 0.0)
            length_m = far.length_m
    return WaveResult(tuple(out), curves, arrivals, path_m, length_m, tuple(notes), dropped)
