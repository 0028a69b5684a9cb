"""Picking the direct packet of a mode at a sensor, knowing the geometry.

The inputs of the wave-feature method (``WaveSettings``, ``Sensor``, ``WaveSetup``) and its
per-direction state (``Direction``); ``arrivals_of`` picks one mode's direct packet in one
record: a scalogram maximum inside the target's predicted window that lies nearer its
prediction than any foreign packet's (``engine.wavefeatures.predict``); the frequency is dropped
where foreign packets could shift the pick by more than ``max_bias`` of the travel time
(the bound of the ones kept joins sigma), and the sensor's own group delay is removed.
``locate_onset`` finds the source onset of a shot triggered on a sensor. The method
around it is ``engine.wavefeatures.pipeline``. Units: s, Hz, m, m/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from .. import waves
from ..laminate import Laminate
from ..safe import mode_velocities
from .peaks import pick_widths, target_peaks
from .predict import Packet, SourceModel, family, model_maxima, predict_packets, source_signature
from .noise import noise_level
from . import judge

__all__ = ["MODES", "WaveSettings", "Sensor", "WaveSetup", "Direction", "noise_rms", "sensor_delay",
           "direction_of", "locate_onset", "packets_at", "arrivals_of", "nominal_cg"]

MODES = ("A0", "S0")


@dataclass(frozen=True)
class WaveSettings:
    """Choices of the wave measurement (None: automatic).

    wavelet: (B, C) of the complex Morlet; default: per frequency the candidate wavelet, the
        longest whose picks pass (engine.wavefeatures.pipeline, step 6).
    band_hz: (fmin, fmax) of the CWT grid; default from the source and the records
        (engine.wavefeatures.band).
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


def noise_rms(x: np.ndarray, pre: int, fs: float, freqs: np.ndarray, wl: waves.Wavelet) -> np.ndarray | None:
    """RMS of |W| per frequency of the record's noise (None: too short or noiseless).

    The noise std is the smaller of two segments' median std of their 64-sample blocks:
    the pre-trigger samples and the last quarter of the record (a record triggered on a
    sensor holds a packet, or the source, before its trigger; one whose source is recorded
    ends quiet); the median ignores a packet in fewer than half a segment's blocks. (The
    smallest block's std, used before, was 17-22 % under the noise's std for 38-150 blocks
    of white noise, so every pick's sigma was as much too small: issue 24, session 27.) When
    both hold signal, the white level above the packets (``noise.noise_level``, session 30).
    """
    if int(0.8 * pre) < 64:      # (before the estimate: its white level is a scalogram of the record)
        return None
    level = noise_level(x, pre, fs)     # the estimate crosstalk.noise_std shares (engine.wavefeatures.noise)
    if level is None:
        return None
    std = level[0]
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


@dataclass
class Direction:
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
    prior_scale: dict = field(default_factory=dict)   # mode -> ratio found by the survey (stage 0)
    prior_margin: dict = field(default_factory=dict)  # mode -> its relative uncertainty
    absent: dict = field(default_factory=dict)   # mode -> level factor the records allow (survey, < 1)
    strict: bool = True        # stage 1 (False): overlaps are not dropped, the picks only rescale
    record_s: float = 0.0      # how long after the earliest onset the records reach (s)
    memo: dict = field(default_factory=dict)   # one shot's picks by wavelet, stage and state (pipeline)

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


def direction_of(setup: WaveSetup, settings: WaveSettings, freqs: np.ndarray, direction: float,
               wss: list[Sensor]) -> Direction:
    d = Direction(setup, settings, freqs, direction, sorted(wss, key=lambda w: w.distance_m))
    if setup.trigger_distance_m is not None and not d.known_source:
        # triggered on a sensor: the onset lies before the first packet reaching it
        fast = max(float(np.nanmax(nominal_cg(d, m))) for m in MODES)
        slow = min(float(np.nanmin(nominal_cg(d, m))) for m in MODES)
        dur = setup.source.force().duration_s
        d.t0_prior = (-setup.trigger_distance_m / (slow * (1 - settings.gate_margin)) - dur,
                      -setup.trigger_distance_m / (fast * (1 + settings.gate_margin)))
        d.t0 = d.t0_prior
    return d


def locate_onset(d: Direction, wl: waves.Wavelet, rec: Mapping[str, np.ndarray], cache: dict) -> None:
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
    direct = [p for p in packets_at(d, s, wl) if p.path == "direct"]
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


def packets_at(d: Direction, s: Sensor, wl: waves.Wavelet) -> list[Packet]:
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
        d.packets[key] = [p if p.mode not in d.absent else _scaled(p, d.absent[p.mode])
                          for p in pk if family(p.mode) in s.families]
    return d.packets[key]


def _scaled(p: Packet, k: float) -> Packet:
    """``p`` at ``k`` x its predicted level (a mode the records hold less of, ``survey``)."""
    return replace(p, amplitude=p.amplitude * k, model_w=None if p.model_w is None else p.model_w * k,
                   model_dw=None if p.model_dw is None else p.model_dw * k)


def _src_time(d: Direction, wl: waves.Wavelet, src_arr: waves.Arrivals | None) -> tuple[np.ndarray, np.ndarray]:
    """Source reference time per frequency on the record axis: (earliest, latest)."""
    if src_arr is not None:
        t = np.where(src_arr.valid, src_arr.times_s, np.nan)
        return t, t
    c, _, _ = source_signature(d.setup.source, d.freqs, wl)
    return c + d.t0[0], c + d.t0[1]


def arrivals_of(d: Direction, x: np.ndarray, s: Sensor | None, mode: str, wl: waves.Wavelet,
              src_arr: waves.Arrivals | None, W: np.ndarray | None = None,
              path_m: float = 1.0, xtalk: np.ndarray | None = None, A=None, noise=False) -> waves.Arrivals:
    """Arrivals of ``mode``'s direct packet at sensor ``s`` (None: the source record, no
    gate); ``path_m``: the measured path (the bias bound is relative to its travel time);
    ``xtalk``: the bound of the source's crosstalk in this record, on ``W``'s grid
    (``crosstalk.bound_in``; None: no electrical source); ``A``, ``noise``: |W| and ``noise_rms``, if known."""
    fs, pre, freqs = d.setup.fs_hz, d.setup.pretrigger, d.freqs
    W = waves.cwt(x, fs, freqs, wl) if W is None else W
    noise = noise_rms(x, pre, fs, freqs, wl) if noise is False else noise
    if s is None:
        # the source's own scalogram: its maximum is the source time at every frequency of
        # the band, wherever its instantaneous frequency lies (no leakage test)
        return waves.arrival_times(W, fs, freqs, wl, t0_index=pre, noise_rms=noise, A=A,
                                   min_snr_db=d.settings.min_snr_db, min_rel_db=-60.0, max_freq_offset=np.inf)
    lo_s, hi_s = _src_time(d, wl, src_arr)
    lo_s = lo_s + sensor_delay(s, freqs)
    hi_s = hi_s + sensor_delay(s, freqs)
    pk = packets_at(d, s, wl)
    target = next((p for p in pk if p.mode == mode and p.path == "direct"), None)
    nf = freqs.size
    reason = [""] * nf
    gate_lo, gate_hi = np.full(nf, np.nan), np.full(nf, np.nan)
    if target is None:
        reason = ["mode not excited at this sensor"] * nf
        return _rejected(freqs, wl, reason)
    A = np.abs(W) if A is None else A
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

    # the foreign packets that may claim a peak, per frequency: predicted there and not much
    # weaker than the target (see below); their centre and half-width, arrays over (packet,
    # frequency), so that each frequency's test is one array expression (issue 29: the
    # per-packet, per-peak Python loop was a third of this function's CPU)
    others = [p for p in pk if p is not target]
    with np.errstate(invalid="ignore"):
        claim = np.array([np.isfinite(p.delay_s) & ~(np.isfinite(p.amplitude) & np.isfinite(target.amplitude)
                                                     & (p.amplitude < 0.05 * target.amplitude)) for p in others],
                         bool).reshape(len(others), nf)
    o_mid = np.array([0.5 * (ranges[id(p)][0] + ranges[id(p)][1]) for p in others]).reshape(len(others), nf)
    o_half = np.array([0.5 * (ranges[id(p)][1] - ranges[id(p)][0]) + p.spread_s for p in others]
                      ).reshape(len(others), nf)

    best, why = target_peaks(A, t, fs, *ranges[id(target)], target.spread_s, claim, o_mid, o_half,
                             np.isfinite(target.delay_s) & np.isfinite(lo_s))
    guard = wl.time_std_s(freqs)
    for i in range(nf):
        if why[i]:
            reason[i] = why[i]
            continue
        # a dispersive packet within one wavelet time std of the onset is not yet formed (A0's
        # near field: 1-2 % at the low end of a pencil's band, 6 cm from it); S0, barely
        # dispersive, arrives as the source pulse itself, and an electrical source's crosstalk
        # is measured in the record (``crosstalk``, below): S0 is not held to it (issue 24)
        if mode.startswith("A") and t[best[i]] - hi_s[i] < guard[i]:
            reason[i] = "within a wavelet length of the source time"
            continue
        sig = target.spread_s[i]
        gate_lo[i], gate_hi[i] = t[best[i]] - 0.75 * sig, t[best[i]] + 0.75 * sig
    arr = waves.arrival_times(W, fs, freqs, wl, t0_index=pre, gate_s=(gate_lo, gate_hi), noise_rms=noise, A=A,
                              min_snr_db=d.settings.min_snr_db, first_fraction=0.999)
    valid = arr.valid.copy()
    why = list(arr.reason)
    leak_max = 10 ** (d.settings.leak_db / 20)
    bias_s = np.zeros(nf)
    s_delay = sensor_delay(s, freqs)
    c_src = source_signature(d.setup.source, freqs, wl)[0] + s_delay
    onsets = 0.5 * (lo_s + hi_s) - c_src          # the onset on the record axis
    rows = np.flatnonzero(valid & ~np.array([bool(r) for r in reason], bool))
    pre_w = {} if target.model_w is None else {id(p): model_maxima(
        p, rows, arr.times_s[rows] - onsets[rows] - s_delay[rows], ranges[id(p)][0][rows], ranges[id(p)][1][rows],
        onsets[rows] + c_src[rows] + p.delay_s[rows]) for p in pk if p is not target and p.model_w is not None}
    at = {int(i): j for j, i in enumerate(rows)}
    peaks_t = target.model_w.max(axis=1) if target.model_w is not None else np.zeros(nf)   # per row, at once
    widens, a_at = pick_widths(A, t, fs, arr.times_s[rows], target.spread_s[rows], rows)
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
        widen = float(widens[at[i]])        # (``peaks.pick_widths``: every row at once)
        st *= widen
        # a foreign packet of level rho at the pick, g from it, shifts the maximum of a packet
        # of amplitude std st by ~ rho g st^2 / sp^2 (first order); two edges at the same
        # distance arrive together: the levels and shifts add up (worst case)
        items = []
        onset = 0.5 * (lo_s[i] + hi_s[i]) - c_src[i]          # the onset on the record axis
        peak_t = peaks_t[i]
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
                pre = pre_w.get(id(p))
                if pre is not None and pre[0][at[i]]:      # the same maxima, computed at once
                    if pre[1][at[i]]:
                        continue
                    amax, damax = float(pre[2][at[i]]), float(pre[3][at[i]])
                    items.append((amax / peak_t, (st * st * damax + 0.7 * st * amax) / peak_t,
                                  f"{p.mode} {p.path}", (p.mode, round(p.length_m, 3))))
                    continue
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
        if xtalk is not None:
            # the excitation's crosstalk as measured in this record (``crosstalk.bound_in``): its level
            # and slope bound the shift like a foreign packet's, taken at the target's predicted
            # time, not at the pick (``judge``: a test at the pick keeps the late ones)
            a_kc = a_at[at[i]]
            if a_kc > 0:
                items.append((*judge.crosstalk_at(xtalk[i], a_kc, 0.5 * sum(rng(target, i)) - t[0], fs, st),
                              "crosstalk", "crosstalk"))
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
        # the level guards the first-order shift bound: like the shift, the groups' levels add
        # in rms (a coherent sum of every edge's echo at one instant is not a record)
        level = math.sqrt(sum(g[0] ** 2 for g in groups.values()))
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


def nominal_cg(d: Direction, mode: str) -> np.ndarray:
    """Direct-path nominal SAFE group velocity of ``mode`` along the direction (NaN where
    the mode does not exist on the grid)."""
    if not d.nominal_cg:
        d.nominal_cg.update({m: v[1] for m, v in mode_velocities(d.setup.laminate, d.freqs,
                                                                 direction_deg=d.direction).items()})
    return d.nominal_cg.get(mode, np.full(d.freqs.size, np.nan))
