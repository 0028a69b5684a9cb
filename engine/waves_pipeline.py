"""The wave-feature method: group-velocity curves of a wave run from its records.

For each propagation direction of the wave sensors (``measure_waves``):

1. band (``analysis_band``): ``band_hz``, else (fmax / 20, fmax) with fmax = 50 kHz for
   an isotropic plate and 200 kHz for a laminate, at most 0.4 x rate; with a recorded
   source force, fmax stops where the force spectrum falls 10 dB below its peak (near
   its first zero the ridges are biased: docs/wavelet-bias.md);
2. path: source to sensor when the source's force is recorded (the force scalogram
   gives the source time per frequency), else between the nearest and the farthest
   sensor of the direction, else (one sensor) from the trigger time;
3. gates around the nominal SAFE A0 and S0 curves with a wide margin, closed before
   the first edge echo (mirror images) and the other mode; when the record is
   triggered on a sensor, the source time lies between the fastest A0 and S0 fronts
   reaching it;
4. wavelet: ``wavelet``, else the paper's for the material; if that one resolves
   fewer than half the frequencies of A0 (two sensors close to the source: A0 and S0
   overlap within a long wavelet), cmor2-2 then cmor2-1 are tried and the best is kept;
5. A0 through that wavelet, S0 through one of bandwidth B/4 (docs/wavelet-bias.md,
   "S0 next to a strong A0"); per shot a curve, then the inverse-variance mean over
   shots (Birge-scaled); a centre-frequency sweep (C / 1.5, or x 1.5 below C = 2/3)
   adds half the difference to sigma as a systematic term;
6. the features keep only points a wavelet resolution apart (``independent_points``);
   S0 goes into them only on request (``report_s0``).

Pure: arrays and small frozen dataclasses in, a ``WaveResult`` out (its notes
included); no files, no run store. Units: s, Hz, m, m/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from . import waves
from .laminate import Laminate
from .safe import group_velocity as safe_group_velocity

__all__ = ["WaveSettings", "Sensor", "WaveSetup", "WaveCurve", "WaveResult", "default_wavelet",
           "analysis_band", "echo_path", "noise_rms", "combine_shots", "measure_waves"]


@dataclass(frozen=True)
class WaveSettings:
    """Choices of the wave measurement (None: automatic).

    wavelet: (B, C) of the complex Morlet; default by material: (2, 1) for an
        isotropic plate, (2, 5) for a laminate (the paper's choices).
    band_hz: (fmin, fmax) of the CWT grid; default (fmax / 20, fmax) with
        fmax = 50 kHz (isotropic) or 200 kHz (laminate), at most 0.4 x rate.
    n_freqs: points of the CWT grid.
    assign: 'instantaneous' (reassigned, bias-corrected) or 'nominal' (the paper).
    min_snr_db: reject arrivals weaker than this over the pre-trigger noise.
    gate_margin: relative velocity margin of the gates around the nominal SAFE curves.
    echo_margin: how much faster than nominal an edge echo may travel (it closes the gate).
    min_points: fewest valid frequencies for a curve to be reported.
    report_s0: put the S0 curve in the features too (it is always measured, with a wavelet
        of bandwidth B/4): off by default; the A0 tail that biased it 1-7 % is gone
        (docs/wavelet-bias.md), but the short wavelet leaves about one independent point
        and the low end's sigma is still small by up to ~2.
    """

    wavelet: tuple[float, float] | None = None
    band_hz: tuple[float, float] | None = None
    n_freqs: int = 100
    assign: str = "instantaneous"
    min_snr_db: float = 20.0
    gate_margin: float = 0.35
    echo_margin: float = 0.10
    min_points: int = 5
    report_s0: bool = False


@dataclass(frozen=True)
class Sensor:
    """A wave sensor: its channel, distance (m) and direction (deg) from the source, its
    length along the path (m) and its (x, y) on the plate (m; None: unknown, no echo gate)."""

    channel: str
    distance_m: float
    direction_deg: float = 0.0
    length_m: float = 0.0
    xy: tuple[float, float] | None = None


@dataclass(frozen=True)
class WaveSetup:
    """What the method needs of a wave run besides its signals.

    plate_size_m: (length, width) of the plate, m. source_xy: the wave source, m.
    pretrigger: samples before the trigger (t = 0). sensors: the wave sensors, in
    channel order. force_channel: the channel recording the source force, if any.
    trigger_distance_m: distance of the trigger sensor from the source when the record
    is triggered on a wave sensor (the source time is then unknown), else None.
    """

    laminate: Laminate
    plate_size_m: tuple[float, float]
    source_xy: tuple[float, float]
    fs_hz: float
    pretrigger: int
    sensors: tuple[Sensor, ...]
    force_channel: str | None = None
    trigger_distance_m: float | None = None


@dataclass(frozen=True)
class WaveCurve:
    """One measured curve of the features: its independent points (Hz, m/s, m/s)."""

    mode: str
    direction_deg: float
    frequency_hz: np.ndarray
    group_velocity_m_s: np.ndarray
    sigma_m_s: np.ndarray


@dataclass(frozen=True)
class WaveResult:
    """What ``measure_waves`` found.

    features: the curves for the features document, in order. curves / arrivals: every
    measured curve on the full grid and the first shot's far-sensor arrivals, by key
    '<mode>_<direction>' (e.g. 'A0_0'). wave_path_m / sensor_length_m: path and sensor
    length of the first direction (None without one). notes: what was done, in order.
    """

    features: tuple[WaveCurve, ...]
    curves: Mapping[str, waves.GroupVelocity]
    arrivals: Mapping[str, waves.Arrivals]
    wave_path_m: float | None
    sensor_length_m: float | None
    notes: tuple[str, ...]


def default_wavelet(laminate: Laminate) -> waves.Wavelet:
    """The paper's wavelet: cmor2-1 for an isotropic plate, cmor2-5 for a laminate."""
    iso = all(m.isotropic for m in laminate.materials.values()) and len(laminate.plies) == 1
    return waves.PAPER_ALUMINIUM if iso else waves.PAPER_CFRP


def analysis_band(laminate: Laminate, fs_hz: float, settings: WaveSettings = WaveSettings(),
                  force: np.ndarray | None = None, pretrigger: int = 0) -> tuple[np.ndarray, tuple[str, ...]]:
    """The analysis frequencies (Hz) and the notes on how they were chosen.

    ``force``: the source force record (any unit) of the first shot, if recorded.
    Raises WaveError when the band does not lie within (0, fs/2).
    """
    notes: list[str] = []
    fs, pre = fs_hz, pretrigger
    if settings.band_hz:
        fmin, fmax = settings.band_hz
    else:
        fmax = min(50e3 if default_wavelet(laminate) == waves.PAPER_ALUMINIUM else 200e3, 0.4 * fs)
        fmin = fmax / 20
    if not 0 < fmin < fmax < fs / 2:
        raise waves.WaveError(f"wave band {fmin:g}..{fmax:g} Hz: expected 0 < fmin < fmax < rate/2 = {fs / 2:g} Hz")
    if force is not None and not settings.band_hz:
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
    return np.linspace(fmin, fmax, settings.n_freqs), tuple(notes)


def echo_path(src: tuple[float, float], dst: tuple[float, float], length: float, width: float) -> float:
    """Shortest source -> edge -> sensor path on a length x width plate (mirror images), m."""
    sx, sy = src
    x, y = dst
    images = [(-x, y), (2 * length - x, y), (x, -y), (x, 2 * width - y)]
    return min(math.hypot(ix - sx, iy - sy) for ix, iy in images)


def noise_rms(x: np.ndarray, pre: int, fs: float, freqs: np.ndarray, wl: waves.Wavelet) -> np.ndarray | None:
    """RMS of |W| per frequency of the record's pre-trigger noise (None: too short or noiseless)."""
    m = int(0.8 * pre)
    if m < 64:
        return None
    std = float(np.std(x[:m] - np.mean(x[:m])))
    if not std > 0:  # a noiseless (simulated) record: nothing to compare with
        return None
    return waves.white_noise_level(std, fs, freqs, wl)


def combine_shots(curves: list[waves.GroupVelocity]) -> waves.GroupVelocity:
    """Inverse-variance mean over shots, sigma scaled by the Birge ratio where shots disagree."""
    f = curves[0].frequencies_hz
    V = np.array([c.velocity_m_s for c in curves])
    S = np.array([c.sigma_m_s for c in curves])
    ok = np.isfinite(V) & np.isfinite(S) & (S > 0)
    w = np.where(ok, 1.0 / np.where(ok, S, 1.0) ** 2, 0.0)
    n = ok.sum(axis=0)
    sw = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(sw > 0, (w * np.where(ok, V, 0.0)).sum(axis=0) / sw, np.nan)
        s = np.where(sw > 0, 1.0 / np.sqrt(sw), np.nan)
        chi2 = (w * (np.where(ok, V, 0.0) - v) ** 2).sum(axis=0)
        birge = np.where(n > 1, np.sqrt(chi2 / np.maximum(n - 1, 1)), 1.0)
    s = s * np.maximum(birge, 1.0)
    valid = n > 0
    return waves.GroupVelocity(f, np.where(valid, v, np.nan), np.where(valid, s, np.nan), valid)


# --------------------------------------------------------------------------- one direction
@dataclass(frozen=True)
class _Direction:
    """One propagation direction: its sensors, nominal curves and source-time window."""

    setup: WaveSetup
    settings: WaveSettings
    freqs: np.ndarray
    direction: float
    far: Sensor
    near: Sensor | None
    cg_a0: np.ndarray         # nominal SAFE A0 group velocity
    cg_s0: np.ndarray         # nominal SAFE S0, NaN replaced by its maximum
    t_early: float            # source time on the record axis, earliest and latest (s)
    t_late: float


def _direction(setup: WaveSetup, settings: WaveSettings, freqs: np.ndarray, direction: float,
               wss: list[Sensor]) -> _Direction:
    wss = sorted(wss, key=lambda w: w.distance_m)
    far = wss[-1]
    near = None if setup.force_channel is not None or len(wss) < 2 else wss[0]
    lam = setup.laminate
    cg = {m: np.asarray(safe_group_velocity(lam, freqs, m, direction), float) for m in ("A0", "S0")}
    cg_s0 = np.where(np.isfinite(cg["S0"]), cg["S0"], np.nanmax(cg["S0"]))
    # source time on the record axis: unknown when triggered on a sensor, between the
    # fastest A0 and the fastest S0 front reaching the trigger sensor
    t_early = t_late = 0.0
    if setup.trigger_distance_m is not None:
        t_early = -setup.trigger_distance_m / float(np.nanmax(cg["A0"])) * 1.3
        t_late = -setup.trigger_distance_m / float(np.nanmax(cg_s0)) / 1.3
    return _Direction(setup, settings, freqs, direction, far, near, cg["A0"], cg_s0, t_early, t_late)


def _gates(d: _Direction, ws: Sensor, mode: str, wl: waves.Wavelet) -> tuple[np.ndarray, np.ndarray]:
    """Per-frequency time gate (s) of ``mode`` at sensor ``ws``."""
    xy = ws.xy
    echo = echo_path(d.setup.source_xy, xy, *d.setup.plate_size_m) if xy else None
    ts = wl.time_std_s(d.freqs)
    kw = dict(reflection_m=echo, time_std_s=ts, echo_margin=d.settings.echo_margin)
    if mode == "A0":
        kw.update(cg_expected=d.cg_a0, margin=d.settings.gate_margin, faster_cg=d.cg_s0)
    else:
        # A0 is the strong one under a normal force: keep S0 well clear of its arrival
        kw.update(cg_expected=d.cg_s0, margin=d.settings.gate_margin / 2, slower_cg=d.cg_a0,
                  mode_clearance=3.0)
    lo, _ = waves.expected_gate(ws.distance_m, source_time_s=d.t_early, **kw)
    _, hi = waves.expected_gate(ws.distance_m, source_time_s=d.t_late, **kw)
    return lo, hi


def _arrivals(d: _Direction, x: np.ndarray, ws: Sensor | None, mode: str, wl: waves.Wavelet) -> waves.Arrivals:
    """Arrivals in one record (``ws`` None: the force channel, no gate)."""
    fs, pre, freqs = d.setup.fs_hz, d.setup.pretrigger, d.freqs
    W = waves.cwt(x, fs, freqs, wl)
    a = waves.arrival_times(W, fs, freqs, wl, t0_index=pre,
                            gate_s=_gates(d, ws, mode, wl) if ws is not None else None,
                            noise_rms=noise_rms(x, pre, fs, freqs, wl),
                            min_snr_db=d.settings.min_snr_db)
    # S0 (nearly flat below the knee): no curvature to correct; a cubic fitted
    # to its noisy delays would only add its noise
    return waves.correct_dispersion_bias(a) if d.settings.assign == "instantaneous" \
        and mode == "A0" else a


def _measure(d: _Direction, mode: str, wl: waves.Wavelet, shots: Sequence[Mapping[str, np.ndarray]]):
    """(curve combined over shots, the first shot's far-sensor arrivals)."""
    far, near, force = d.far, d.near, d.setup.force_channel
    shot_curves, first = [], None
    for rec in shots:
        # S0 is flat below the knee: the nominal frequency is as good, and the
        # reassigned one of a short wavelet drifts with the source spectrum's slope
        assign = d.settings.assign if mode == "A0" else "nominal"
        a_far = _arrivals(d, rec[far.channel], far, mode, wl)
        if force is not None:
            g = waves.group_velocity(a_far, far.distance_m, _arrivals(d, rec[force], None, mode, wl),
                                     assign=assign)
        elif near is not None:
            g = waves.group_velocity(a_far, far.distance_m, _arrivals(d, rec[near.channel], near, mode, wl),
                                     near_distance_m=near.distance_m, assign=assign)
        else:
            g = waves.group_velocity(a_far, far.distance_m, source_time_s=0.0, assign=assign)
        shot_curves.append(g)
        first = first or a_far
    return combine_shots(shot_curves), first


def _choose_wavelet(d: _Direction, wl0: waves.Wavelet, shots) -> tuple[waves.Wavelet, list[str]]:
    """The given wavelet, or the first of the paper's, cmor2-2, cmor2-1 that resolves half of A0."""
    wl = wl0
    notes = []
    freqs = d.freqs
    if not d.settings.wavelet:
        tried = []
        for cand in (wl0, waves.Wavelet(2.0, 2.0), waves.PAPER_ALUMINIUM):
            if cand in [c for c, _ in tried]:
                continue
            n_ok = int(_measure(d, "A0", cand, shots[:1])[0].valid.sum())
            tried.append((cand, n_ok))
            if n_ok >= 0.5 * freqs.size:
                break
        wl = max(tried, key=lambda t: (t[1] >= 0.5 * freqs.size, -tried.index(t), t[1]))[0] \
            if any(n >= 0.5 * freqs.size for _, n in tried) else max(tried, key=lambda t: t[1])[0]
        if wl != wl0:
            notes.append(f"direction {d.direction:g} deg: {wl0.name} resolves too few A0 frequencies "
                         f"({dict((c.name, n) for c, n in tried)}); used {wl.name}")
    return wl, notes


def _mode_curve(d: _Direction, mode: str, wl: waves.Wavelet, shots):
    """(curve with the wavelet-sweep term in sigma, first arrivals, wavelet used) of one mode."""
    # S0 through a wavelet twice as short (B / 4): under a normal force S0 is ~100 x
    # weaker than A0 and the tail of A0 in a cmor2-C scalogram shifted its maximum
    # by several % (docs/wavelet-bias.md, "S0 next to a strong A0"); S0 is nearly
    # non-dispersive below the knee, so the coarser frequency resolution costs nothing
    wm = wl if mode == "A0" else waves.Wavelet(wl.bandwidth / 4, wl.center)
    gv, first_arr = _measure(d, mode, wm, shots)
    # centre-frequency sweep (docs/wavelet-bias.md): the same records through a
    # wavelet 1.5 x shorter (longer if that would go below C = 2/3); half the
    # difference joins sigma as a systematic term
    c_alt = wm.center / 1.5 if wm.center / 1.5 >= 2 / 3 else wm.center * 1.5
    alt, _ = _measure(d, mode, waves.Wavelet(wm.bandwidth, c_alt), shots)
    both = gv.valid & alt.valid
    if both.any():
        sys_term = np.where(both, 0.5 * np.abs(gv.velocity_m_s - alt.velocity_m_s), 0.0)
        gv = waves.GroupVelocity(gv.frequencies_hz, gv.velocity_m_s,
                                 np.hypot(gv.sigma_m_s, sys_term), gv.valid)
    return gv, first_arr, wm


def _rejections(first_arr: waves.Arrivals | None) -> str:
    """The three commonest reasons (with counts) why frequencies were rejected."""
    why: dict[str, int] = {}
    for r in (first_arr.reason if first_arr is not None else ()):
        if r:
            k = r.split(" (")[0].split(":")[0].split(" -")[0]
            k = "SNR too low" if k.startswith("SNR") else k
            why[k] = why.get(k, 0) + 1
    return ", ".join(f"{k} x{n}" for k, n in sorted(why.items(), key=lambda t: -t[1])[:3])


# --------------------------------------------------------------------------- the run
def measure_waves(setup: WaveSetup, shots: Sequence[Mapping[str, np.ndarray]], freqs: np.ndarray,
                  settings: WaveSettings = WaveSettings()) -> WaveResult:
    """Group-velocity curves of every direction from the shots' records.

    ``shots``: per shot, channel name -> record in physical units (every sensor of
    ``setup`` and the force channel); ``freqs``: the analysis grid (``analysis_band``).
    """
    notes: list[str] = []
    lam = setup.laminate
    wl0 = waves.Wavelet(*settings.wavelet) if settings.wavelet else default_wavelet(lam)
    by_dir: dict[float, list] = {}
    for ws in setup.sensors:
        by_dir.setdefault(round(ws.direction_deg, 6), []).append(ws)
    out, curves, arrivals = [], {}, {}
    path_m = length_m = None
    for direction, wss in sorted(by_dir.items()):
        if setup.force_channel is None and len(wss) < 2:
            notes.append(f"direction {direction:g} deg: one sensor and no source force channel; "
                         "velocity from the trigger time (source assumed at t = 0)")
        d = _direction(setup, settings, freqs, direction, wss)
        wl, wl_notes = _choose_wavelet(d, wl0, shots)
        notes.extend(wl_notes)
        for mode in ("A0", "S0"):
            gv, first_arr, wm = _mode_curve(d, mode, wl, shots)
            key = f"{mode}_{direction:g}"
            if gv.valid.sum() < settings.min_points:
                notes.append(f"{mode} along {direction:g} deg: {int(gv.valid.sum())} valid frequencies "
                             f"(< {settings.min_points}); not reported (far sensor: {_rejections(first_arr)}; "
                             "an empty gate means an edge echo or the other mode within the wavelet's reach)")
                continue
            curves[key] = gv
            arrivals[key] = first_arr
            ok = gv.valid
            if mode == "S0" and not settings.report_s0:
                notes.append(f"S0 along {direction:g} deg: {int(ok.sum())} frequencies measured and stored "
                             "in the run (analysis/waves), not put in the features (--with-s0)")
                continue
            # the features carry only points a wavelet resolution apart: neighbours on the
            # dense grid share their errors (the full curve stays in the run file)
            ok = waves.independent_points(freqs, ok, wm)
            out.append(WaveCurve(mode, float(direction), freqs[ok], gv.velocity_m_s[ok], gv.sigma_m_s[ok]))
            notes.append(f"{mode} along {direction:g} deg: {int(ok.sum())} independent frequencies "
                         f"{freqs[ok].min() / 1e3:.3g}-{freqs[ok].max() / 1e3:.3g} kHz from {len(shots)} shot(s), "
                         f"{wm.name}, {'source to sensor' if setup.force_channel is not None or d.near is None else 'two sensors'}")
        if path_m is None:
            path_m = d.far.distance_m - (d.near.distance_m if d.near is not None else 0.0)
            length_m = d.far.length_m
    return WaveResult(tuple(out), curves, arrivals, path_m, length_m, tuple(notes))
