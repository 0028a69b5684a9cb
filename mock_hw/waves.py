"""Wave shots of the simulated rig: what a guided-wave record of a real plate holds.

For each wave sensor, the surface strain at its position is the sum over the SAFE
modes (``engine.safe.mode_transfer``: per-mode transfer functions of the specimen
as the simulated 'real' plate has it) and over the ray paths of ``engine.waves.ray_paths``
(the direct path and, by image sources, the edge reflections up to
``[simulation] reflections``, first order by default), times the source spectrum:

* sources: 'pencil' (lead break: step of rise_s; on the top face a normal force, on the
  plate's edge, ``break_on = "edge"``, an in-plane force at mid-thickness: ``edge_rays``),
  'hammer' (half-sine of contact_s),
  'tone_burst' (normal point force, windowed sine burst), 'pzt' (a bonded piezo disc
  driven by a burst: ring of radial pin force of the disc's radius on its face, or a
  collocated top/bottom pair driven in phase or in anti-phase);
* reflections: every mode reflects into itself with coefficient 1 at each edge (no
  mode conversion, no phase change: a simplification); each path's group and phase
  velocities are the SAFE ones along its direction (the image's ray; for an anisotropic
  plate the ray is taken along the wave vector, no beam skew);
* sensors: radial strain of every arriving ray (a disc sensor's area strain in the far
  field), averaged over the sensor length along the ray, on the sensor's face; then its
  declared response: first-order high-pass (``highpass_hz``, AC/IEPE coupling) and
  resonance (``resonance_hz``, ``resonance_q``: w0^2 / (w0^2 - w^2 + i w w0 / Q)),
  applied causally on the fine grid (bilinear transform, the resonance pre-warped);
* the channel recording the source reads the force (N) or the excitation voltage (V)
  times its sensitivity.

The device adds crosstalk (``crosstalk_db``: every channel picks up that fraction of
the sum of the others, before the anti-alias filter), then filter, noise and ADC
(``mock_hw.rig``). Unit source amplitude throughout (``source_peak`` scales a shot).
Units: SI (m, s, Hz, N, V).
"""
from __future__ import annotations

import contextlib
import functools
import math

import numpy as np
from scipy.fft import irfft, next_fast_len

from engine import safe
from engine.waves import ray_paths

__all__ = ["OVERSAMPLE", "source_force", "source_peak", "mechanical", "wave_channels", "sensor_response",
           "apply_crosstalk", "transfer_model", "model_token", "force_direction", "edge_rays"]

OVERSAMPLE = 4
#: where the source acts inside the synthesis' FFT period (s): longer than a step source's
#: settling within the analysis band and the longest analysis wavelet (~5 cycles at 20 kHz)
SOURCE_PAD_S = 200e-6
_MODEL: dict = {"name": "engine.safe", "transfer": None}


@contextlib.contextmanager
def transfer_model(name: str, transfer):
    """Synthesise wave shots with another guided-wave model inside the block: ``transfer``
    has the signature and result of ``engine.safe.mode_transfer`` ({label: complex strain
    per newton}); ``name`` labels it in the shots' meta ('sim_wave_model') and the caches.
    For benches that must not judge labid by records of its own SAFE model."""
    old = dict(_MODEL)
    _MODEL.update(name=str(name), transfer=transfer)
    try:
        yield
    finally:
        _MODEL.clear()
        _MODEL.update(old)


def model_token() -> str:
    """The name of the model the wave shots are synthesised with ('engine.safe' by default)."""
    return _MODEL["name"]


def mechanical(src) -> bool:
    """A hand-made source (hammer, pencil) whose force scatters from shot to shot."""
    return src.kind in ("hammer", "pencil")


def source_peak(src) -> float:
    """Nominal amplitude of a shot: N for forces, V of excitation for a pzt."""
    return src.burst.amplitude if src.kind == "pzt" else src.force_n


def _force_key(src) -> tuple:
    if src.kind == "pencil":
        return ("pencil", src.rise_s)
    if src.kind == "hammer":
        return ("hammer", src.contact_s)
    b = src.burst
    return ("burst", b.frequency_hz, b.cycles, b.window)


def source_force(key: tuple) -> safe.ForceHistory:
    """Unit-amplitude history of a source key (``_force_key``)."""
    if key[0] == "pencil":
        return safe.pencil_lead_break(rise_s=key[1], amplitude_n=1.0)
    if key[0] == "hammer":
        return safe.hammer_force(key[1], amplitude_n=1.0)
    return safe.tone_burst(key[1], key[2], 1.0, window=key[3])


def _load(src) -> tuple:
    """(load, radius, ((face, sign), ...)) of the source for ``mode_transfer``.

    A lead broken on the edge at mid-thickness: an in-plane point force, half on each face.
    The in-plane displacement of every mode below the first cut-off is linear through the
    thickness at low fh (membrane + bending), so the mean of the two faces' u is u at
    mid-thickness: the S modes' factor, the A modes' cancels (symmetric laminate)."""
    if src.kind == "pencil" and getattr(src, "break_on", "face") == "edge":
        return "inplane", 0.0, (("top", 0.5), ("bottom", 0.5))
    if src.kind != "pzt":
        return "normal", 0.0, (("top", 1.0),)
    if src.pair:
        return "pin", src.diameter_m / 2, (("top", 1.0), ("bottom", 1.0 if src.pair == "symmetric" else -1.0))
    return "pin", src.diameter_m / 2, ((src.face, 1.0),)


def sensor_response(highpass_hz, resonance_hz, resonance_q, fs_hz: float):
    """Second-order sections of a sensor's declared response at rate fs_hz (None: flat)."""
    from scipy import signal  # noqa: PLC0415 - where used: ~0.8 s CPU at every command's start otherwise
    sos = []
    if highpass_hz:
        sos.append(signal.butter(1, highpass_hz, "highpass", fs=fs_hz, output="sos"))
    if resonance_hz:
        w0 = 2 * fs_hz * math.tan(math.pi * resonance_hz / fs_hz)      # pre-warped
        z, p, k = signal.bilinear_zpk([], np.roots([1.0, w0 / resonance_q, w0 * w0]), w0 * w0, fs_hz)
        sos.append(signal.zpk2sos(z, p, k))
    return np.vstack(sos) if sos else None


def apply_crosstalk(raw: dict[str, np.ndarray], crosstalk_db: float | None) -> dict[str, np.ndarray]:
    """Every channel plus 10^(db/20) times the sum of the other channels."""
    if crosstalk_db is None or len(raw) < 2:
        return raw
    c = 10.0 ** (crosstalk_db / 20.0)
    total = sum(raw.values())
    return {k: v + c * (total - v) for k, v in raw.items()}


def wave_channels(rig, plate_size_m: tuple[float, float], lam, effects, channels, fs: float, lead: int,
                  nf: int) -> dict[str, np.ndarray]:
    """Unit-amplitude fine-grid signals (V at the input) of the wave device's channels on a
    plate of ``plate_size_m`` (length, width); t = 0 (source onset) at fine sample ``lead``."""
    src, sim = rig.wave_source, rig.sim
    fmax = min(sim.wave_fmax_hz, 0.45 * fs)
    key = _force_key(src)
    fsf = OVERSAMPLE * fs
    tf = (np.arange(nf) - lead) / fsf
    out: dict[str, np.ndarray] = {}
    iso = _isotropic(lam)
    length, width = plate_size_m
    for c in channels:
        if c.name == src.channel or (src.channel is None and c.kind == "force"):
            out[c.name] = c.sensitivity * source_force(key)(tf) * (tf >= 0)
            continue
        ws = rig.wave_sensor(c.name)
        if ws is None:
            continue
        ap = effects.sensor_aperture if effects.sensor_aperture > 0 else ws.length_m
        rays = []
        paths = ray_paths((src.x, src.y), (c.x, c.y), length, width, order=sim.reflections)
        for p, weight in zip(paths, edge_rays(src, paths, plate_size_m)):
            if weight == 0.0:
                continue
            if iso:
                direction = 0.0
            elif p.order == 0:
                direction = ws.direction_deg
            else:        # theta and theta + 180 deg carry the same waves; 1 deg steps share models
                direction = (round(p.direction_deg) + 90.0) % 180.0 - 90.0
            rays.append((p.length_m + effects.path_length, float(direction), float(weight)))
        strain = _wave_fine(lam, tuple(rays), key, fs, nf - lead, ap, fmax, effects.viscoelastic,
                            effects.timing_offset, _load(src), ws.face, model_token())
        gain = ws.volts_per_strain * c.sensitivity * (src.newton_per_volt if src.kind == "pzt" else 1.0)
        y = np.concatenate([np.zeros(lead), gain * strain])
        sos = sensor_response(ws.highpass_hz, ws.resonance_hz, ws.resonance_q, fsf)
        from scipy import signal  # noqa: PLC0415 - see sensor_response
        out[c.name] = signal.sosfilt(sos, y) if sos is not None else y
    return out


def force_direction(src, plate_size_m: tuple[float, float]) -> float:
    """In-plane force direction (deg from x) of a lead broken on the edge: ``force_deg``, else
    the inward normal of the plate edge nearest the source."""
    if src.force_deg is not None:
        return float(src.force_deg)
    length, width = plate_size_m
    gaps = {0.0: src.x, 180.0: length - src.x, 90.0: src.y, -90.0: width - src.y}
    return min(gaps, key=gaps.get)


def edge_rays(src, paths, plate_size_m: tuple[float, float]) -> list[float]:
    """Amplitude factor of each ray path: 1 for a face source; for an edge break, the
    in-plane force's directivity cos(theta) of the S-mode radial field (theta between the
    force and the ray as it leaves the source: the image ray's direction with its x / y
    component flipped once per reflection on an x / y edge). The source lies on an edge, so
    its image in that edge lies on it: that path is the direct ray itself (its factor the
    direct's, i.e. the direct field doubled: the rig's reflection coefficient 1, a free edge
    loaded by the force)."""
    if not (src.kind == "pencil" and getattr(src, "break_on", "face") == "edge"):
        return [1.0] * len(paths)
    fd = math.radians(force_direction(src, plate_size_m))
    length, width = plate_size_m
    tol = 1e-6 * max(length, width)
    own = {n for n, gap in (("x=0", src.x), ("x=L", length - src.x), ("y=0", src.y), ("y=W", width - src.y))
           if abs(gap) <= tol}
    out = []
    for p in paths:
        a = math.radians(p.direction_deg)
        names = p.name.replace("corner ", "").split(",")
        fx = sum(n.startswith("x=") and n not in own for n in names)
        fy = sum(n.startswith("y=") and n not in own for n in names)
        out.append(math.cos(a) * (-1) ** fx * math.cos(fd) + math.sin(a) * (-1) ** fy * math.sin(fd))
    return out


def _isotropic(lam) -> bool:
    return len(lam.plies) == 1 and all(m.isotropic for m in lam.materials.values())


@functools.lru_cache(maxsize=64)
def _wave_fine(lam, rays: tuple, force_key: tuple, fs: float, n_fine: int, aperture: float, fmax: float,
               eta: float, delay_s: float, load: tuple, face: str, model: str = "engine.safe") -> np.ndarray:
    """Surface strain per unit source amplitude on the fine grid (OVERSAMPLE * fs), t = 0
    at the source onset, summed over the rays (length m, direction deg, amplitude factor).

    Sum over the SAFE modes of ``engine.safe.mode_transfer`` times the source
    spectrum (half-cosine taper over the top 10 % below fmax, DC dropped), each mode
    attenuated by exp(-eta k_m r / 2) with k_m = 2 pi f / c_phase,m. The source sits
    ``SOURCE_PAD_S`` into the FFT period (8 records plus that pad): a lead break is a step
    whose strain never returns to zero, so the period's wrapped-around tail and the DC drop's
    offset must lie in a long stretch before the first arrival, not within a wavelet's length
    of it (session 26: with the source at the period's first sample, ``_causal`` cut that tail
    differently at 20 and 40 cm and biased an S0 pair by +1.6 .. +1.9 % at 55-75 kHz). Made
    causal (``_causal`` at the pad + 0.95 r / c_max), then read from the source onset delayed
    by delay_s (to the nearest fine sample).
    """
    force = source_force(force_key)
    n_rec = -(-n_fine // OVERSAMPLE)
    pad = int(round(SOURCE_PAD_S * fs))               # coarse samples; the source at t = pad / fs
    n_fft = next_fast_len(8 * n_rec + pad, real=True)
    f = np.fft.rfftfreq(n_fft, 1.0 / fs)
    band = (f > 0) & (f <= fmax)
    fb = f[band]
    taper = np.where(fb <= 0.9 * fmax, 1.0, 0.5 * (1 + np.cos(np.pi * (fb - 0.9 * fmax) / (0.1 * fmax))))
    kind, radius, faces = load
    total = np.zeros(fb.size, complex)
    for r, direction, weight in rays:
        for src_face, sign in faces:
            transfer = _MODEL["transfer"] or safe.mode_transfer
            H = transfer(lam, r, fb, direction_deg=direction, quantity="strain",
                         sensor_length_m=min(aperture, 1.9 * r), source="point", load=kind,
                         actuator_radius_m=radius, source_face=src_face, sensor_face=face)
            if eta > 0:
                cp = _phase_velocities(lam, direction, fmax)
                for label in H:
                    if label in cp:
                        fp, vp = cp[label]
                        H[label] = H[label] * np.exp(-eta * (2 * np.pi * fb / np.interp(fb, fp, vp)) * r / 2.0)
            total += weight * sign * sum(H.values(), np.zeros(fb.size, complex))
    Y = np.zeros(f.shape, complex)
    Y[band] = np.conj(total) * force.spectrum(fb) * taper * np.exp(-2j * np.pi * fb * (pad / fs))
    y = irfft(Y, n=OVERSAMPLE * n_fft) * fs * OVERSAMPLE
    r0, d0, _ = min(rays)
    t_first = max(r0 - aperture / 2.0, 1e-6) / _fastest(lam, d0, fmax)
    y = _causal(y, OVERSAMPLE * fs, t_first, pad / fs)
    start = OVERSAMPLE * pad - int(round(delay_s * OVERSAMPLE * fs))   # delay to the nearest fine sample
    y = y[start:] if start >= 0 else np.concatenate([np.zeros(-start), y])
    return y[:n_fine]


@functools.lru_cache(maxsize=32)
def _phase_velocities(lam, direction_deg: float, fmax: float) -> dict:
    """label -> (frequencies, phase velocities) where the mode exists, below fmax."""
    disp = safe.dispersion(lam, np.linspace(fmax / 256, fmax, 256), direction_deg)
    out = {}
    for m in disp.modes:
        ok = np.isfinite(m.phase_velocity_m_s)
        if ok.sum() >= 2:
            out[m.label] = (disp.frequency_hz[ok], m.phase_velocity_m_s[ok])
    return out


@functools.lru_cache(maxsize=16)
def _fastest(lam, direction_deg: float, fmax: float) -> float:
    """Largest group velocity (m/s) of any guided mode below fmax."""
    disp = safe.dispersion(lam, np.linspace(fmax / 200, fmax, 200), direction_deg)
    return float(max(np.nanmax(m.group_velocity_m_s) for m in disp.modes))


def _causal(y: np.ndarray, fs: float, t_first: float, t_source: float = 0.0) -> np.ndarray:
    """Enforce causality on a SAFE record whose source acts at t_source (s from the period's
    start): nothing can arrive before t_source + t_first, t_first = d / c_max.

    The propagating-mode sum with its DC bin dropped carries a constant offset
    (the period mean of the quasi-static step response) plus a slow drift (a face break's
    A0 strain, without its evanescent partner, grows linearly: a sawtooth over the period);
    the level at the cut t_cut = t_source + 0.95 t_first (a straight line fitted to the
    stretch before it) is subtracted everywhere, so the record is continuous there, and the
    stretch is zeroed, faded out with a half-cosine over its last 0.19 t_first.
    """
    y = np.array(y, float)
    m = int((t_source + 0.95 * t_first) * fs)
    if m >= 2:
        c0, c1 = np.polynomial.polynomial.polyfit(np.arange(m, dtype=float), y[:m], 1)
        y -= c0 + c1 * m
        ramp = np.zeros(m)
        k = max(1, min(m, int(0.95 * t_first * fs)) // 5)
        ramp[m - k:] = 0.5 - 0.5 * np.cos(np.pi * (np.arange(k) + 1) / (k + 1))
        y[:m] *= ramp
    else:
        y -= y[0]
    return y
