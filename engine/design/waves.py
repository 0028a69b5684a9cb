"""Guided waves in a test plan: where the source and sensors go, what the velocities deliver.

A leg is a direction from one source with two sensors on it (near and far, m): the A0
group velocity along it is measured from the difference of their arrival times per
frequency (``labid analyze``), so its relative std per point is

    sigma_cg / cg = sqrt(floor^2 + 2 (sigma_t cg / (d_far - d_near))^2)

(``sigma_t``: one sensor's arrival-time std). How many independent points a leg gives
depends on the plate's size: the wavelet that times the A0 packet must end before the next
packet arrives at either sensor (S0 direct, or A0/S0 reflected by an edge: image sources,
``engine.waves.ray_paths``), so its time std is at most a third of that clearance; a
shorter wavelet resolves frequency more coarsely (sigma_t sigma_f = 1 / 4 pi), and points
closer than 2 sqrt(2) frequency stds are not independent (``engine.waves.independent_points``'
rule). A frequency where even a one-cycle wavelet (cmor2-1) does not fit is lost.

The band is the analysis' default for the source (``engine.wavefeatures.band.source_band``:
a pencil-lead break, fmax/20..fmax, fmax 200 kHz for a laminate, 50 kHz isotropic, at most
0.4 x the sample rate). Sensitivities d ln cg / d ln p are forward differences of the SAFE
model (``engine.safe.dispersion``) at the nominal constants. Units SI: m, s, Hz, m/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..laminate import Laminate
from ..safe import dispersion, group_velocity
from ..wavefeatures.band import source_band
from ..wavefeatures.predict import SourceModel
from ..waves import ray_paths

__all__ = ["Velocities", "velocity_table", "Leg", "WavePlan", "clearance", "leg_points", "plan_geometry",
           "wave_jacobian", "leg_weights", "default_band", "WAVELETS", "CLEAR_STDS", "REL_STEP"]
#: relative step of the forward differences of the SAFE velocities
REL_STEP = 1e-3
#: modes whose packets may overlap the A0 packet: an out-of-plane source (pencil, hammer)
#: launches a weak S0 (the demo's CFRP records: S0 "weak" at 65 of 100 frequencies,
#: bench/RESULTS.md issue 14), so only the A0 reflections bound the window
PACKET_MODES = ("A0",)


@dataclass(frozen=True)
class Velocities:
    """Group velocities (m/s) of ``modes`` on ``freqs`` (Hz) along ``directions`` (deg, 0..90;
    a balanced orthotropic laminate repeats them by symmetry about both axes)."""

    freqs: np.ndarray
    directions: np.ndarray
    cg: Mapping[str, np.ndarray]       # mode -> (n_dir, n_f)

    def at(self, mode: str, direction_deg: float) -> np.ndarray:
        """cg of ``mode`` on ``freqs`` along any direction (folded into 0..90, linear in angle)."""
        a = abs(math.remainder(direction_deg, 180.0))
        a = 180.0 - a if a > 90.0 else a
        tab, dirs = self.cg[mode], self.directions
        if len(dirs) == 1:
            return tab[0]
        k = int(np.clip(np.searchsorted(dirs, a) - 1, 0, len(dirs) - 2))
        t = min(max((a - dirs[k]) / (dirs[k + 1] - dirs[k]), 0.0), 1.0)
        return (1.0 - t) * tab[k] + t * tab[k + 1]


def velocity_table(laminate: Laminate, freqs, directions=(0.0, 30.0, 60.0, 90.0),
                   modes: Sequence[str] = PACKET_MODES) -> Velocities:
    """SAFE group velocities at the laminate's constants (one dispersion solve per direction)."""
    f = np.asarray(freqs, float)
    out = {m: np.full((len(directions), f.size), np.nan) for m in modes}
    for i, d in enumerate(directions):
        disp = dispersion(laminate, f, float(d))
        for m in modes:
            if m in disp.labels:
                out[m][i] = disp.mode(m).group_velocity_m_s
    return Velocities(f, np.asarray(directions, float), out)


def default_band(laminate: Laminate, rate_hz: float) -> tuple[float, float]:
    """The analysis' default band of a pencil-lead source at ``rate_hz`` (Hz)."""
    lo, hi, _ = source_band(laminate, rate_hz, SourceModel(kind="pencil"), -20.0, None, 0)
    return lo, min(hi, 0.4 * rate_hz)


def clearance(vel: Velocities, source, sensor, length: float, width: float) -> np.ndarray:
    """Per frequency of ``vel``, the time (s) between the direct A0 packet at ``sensor`` and
    the nearest other packet (S0 direct; A0 or S0 by one edge reflection)."""
    paths = ray_paths(tuple(source), tuple(sensor), length, width, order=1)
    direct = paths[0] if paths[0].name == "direct" else next(p for p in paths if p.name == "direct")
    t0 = direct.length_m / vel.at("A0", direct.direction_deg)
    gap = np.full(vel.freqs.size, np.inf)
    for p in paths:
        for m in PACKET_MODES:
            if m not in vel.cg or (p.name == "direct" and m == "A0"):
                continue
            t = p.length_m / vel.at(m, p.direction_deg)
            gap = np.fmin(gap, np.abs(t - t0))
    return gap


@dataclass(frozen=True)
class Leg:
    """Two sensors ``near_m`` and ``far_m`` from the source along ``direction_deg``; ``freqs``:
    its independent A0 points (Hz); ``cg``: A0 group velocity there (m/s)."""

    direction_deg: float
    near_m: float
    far_m: float
    freqs: tuple[float, ...]
    cg: tuple[float, ...]

    @property
    def spacing_m(self) -> float:
        return self.far_m - self.near_m

    def positions(self, source) -> tuple[tuple[float, float], tuple[float, float]]:
        c, s = math.cos(math.radians(self.direction_deg)), math.sin(math.radians(self.direction_deg))
        return ((source[0] + self.near_m * c, source[1] + self.near_m * s),
                (source[0] + self.far_m * c, source[1] + self.far_m * s))


#: the wavelets the analysis chooses from (``engine.wavefeatures.pipeline``: the paper's for
#: the material, then cmor2-2, 2-1.5, 2-1, 1-1, 0.5-1), as (bandwidth B, centre C)
WAVELETS = ((2.0, 2.0), (2.0, 1.5), (2.0, 1.0), (1.0, 1.0), (0.5, 1.0))
#: a packet is measured where the wavelet's time std is at most 1/CLEAR_STDS of the clearance.
#: Calibrated on what ``labid analyze`` measured from the simulated rig's CFRP records (edge
#: reflections, noise; bench/RESULTS.md, issue 25): pencil 4 cm from an edge, sensors at 5 and
#: 20 cm along 0 deg: 3 A0 points; source (92.5, 92.5) mm, sensors at 5 and 18.8 cm: 3 along
#: 0 deg, 2 along 90 deg. 6 predicts 3, 3, 2; 4 predicted 4, 5, 3; 3 predicted 5, 6, 4.
CLEAR_STDS = 6.0


def leg_points(vel: Velocities, source, direction_deg: float, near: float, far: float, length: float,
               width: float, wavelet) -> Leg:
    """The independent A0 points of a leg: of the analysis' candidate wavelets (``wavelet``,
    the material's default, first), the one giving the most points where its time std fits
    a third of the clearance at both sensors, spaced 2 sqrt(2) of its frequency stds."""
    c, s = math.cos(math.radians(direction_deg)), math.sin(math.radians(direction_deg))
    gap = np.fmin(clearance(vel, source, (source[0] + near * c, source[1] + near * s), length, width),
                  clearance(vel, source, (source[0] + far * c, source[1] + far * s), length, width))
    f = vel.freqs
    cg = vel.at("A0", direction_deg)
    best: list[int] = []
    for B, C in ((wavelet.bandwidth, wavelet.center),) + WAVELETS:
        k_t = C * math.sqrt(B) / 2.0                   # time std x f
        usable = (CLEAR_STDS * k_t / f <= gap) & np.isfinite(cg)
        step = 2.0 * math.sqrt(2.0) / (2.0 * math.pi * C * math.sqrt(B))   # spacing / f
        keep, last = [], -np.inf
        for i in np.flatnonzero(usable):
            if not np.isfinite(last) or f[i] - last >= step * f[i]:
                keep.append(i)
                last = f[i]
        if len(keep) > len(best):
            best = keep
    return Leg(float(direction_deg), float(near), float(far), tuple(float(f[i]) for i in best),
               tuple(float(cg[i]) for i in best))


def leg_weights(leg: Leg, timing_s: float, floor_rel: float) -> np.ndarray:
    """1 / sigma^2 of each point's relative velocity (module docstring)."""
    cg = np.asarray(leg.cg, float)
    rel = np.sqrt(floor_rel ** 2 + 2.0 * (timing_s * cg / leg.spacing_m) ** 2)
    return 1.0 / rel ** 2


def _score(leg: Leg, timing_s: float, floor_rel: float) -> float:
    return float(leg_weights(leg, timing_s, floor_rel).sum()) if leg.freqs else 0.0


@dataclass(frozen=True)
class WavePlan:
    """A source position (m) and its legs."""

    source: tuple[float, float]
    legs: tuple[Leg, ...]
    band_hz: tuple[float, float]

    @property
    def n_points(self) -> int:
        return sum(len(l.freqs) for l in self.legs)


def plan_geometry(vel: Velocities, length: float, width: float, directions: Sequence[float], wavelet, *,
                  margin: float = 0.02, near: float = 0.05, timing_s: float = 1e-7, floor_rel: float = 5e-4,
                  n_grid: int = 9, band_hz: tuple[float, float] = (0.0, 0.0)) -> WavePlan:
    """Source position, sign of each direction and far distances maximising the product of
    the legs' summed point weights (each direction informs its own constants: a leg without
    a usable point is no plan); each leg's best far distance for a source position."""
    xs = np.linspace(margin, length - margin, n_grid)
    ys = np.linspace(margin, width - margin, n_grid)
    best: tuple[float, WavePlan | None] = (-np.inf, None)
    for x0 in xs:
        for y0 in ys:
            legs, total = [], 0.0
            for d in directions:
                cand = None
                for sgn in (0.0, 180.0):
                    ang = d + sgn
                    c, s = math.cos(math.radians(ang)), math.sin(math.radians(ang))
                    room = min((length - margin - x0) / c if c > 1e-9 else ((x0 - margin) / -c if c < -1e-9 else np.inf),
                               (width - margin - y0) / s if s > 1e-9 else ((y0 - margin) / -s if s < -1e-9 else np.inf))
                    if room < near + 0.02:
                        continue
                    for far in np.linspace(near + 0.02, room, 6):
                        leg = leg_points(vel, (x0, y0), ang % 360.0, near, float(far), length, width, wavelet)
                        sc = _score(leg, timing_s, floor_rel)
                        if cand is None or sc > cand[0]:
                            cand = (sc, leg)
                if cand is None or cand[0] <= 0:
                    break
                legs.append(cand[1])
                total += math.log(cand[0])
            if len(legs) == len(directions) and total > best[0]:
                best = (total, WavePlan((float(x0), float(y0)), tuple(legs), band_hz))
    if best[1] is None:
        raise ValueError(f"no room for a {near:g} m near sensor and a farther one on the "
                         f"{length:g} x {width:g} m plate")
    return best[1]


def wave_jacobian(laminate: Laminate, names: Sequence[str], params: Mapping[str, float], legs: Sequence[Leg],
                  material: str | None = None, thickness: bool = False,
                  progress: Callable[[str], None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(n, P) d ln cg / d ln p of every leg's points (forward differences, SAFE) and (n, 1)
    d ln cg / d ln h (thickness; zeros unless ``thickness``)."""
    rows, rows_h = [], []
    base = dict(params)

    def cg(lam, leg):
        return group_velocity(lam, np.asarray(leg.freqs), "A0", leg.direction_deg)

    for li, leg in enumerate(legs):
        if not leg.freqs:
            continue
        if progress is not None:
            progress(f"wave sensitivities, leg {li + 1}/{len(legs)}")
        lam0 = laminate.with_params(base, material)
        c0 = np.log(cg(lam0, leg))
        J = np.zeros((len(leg.freqs), len(names)))
        for j, n in enumerate(names):
            p = dict(base)
            p[n] = base[n] * math.exp(REL_STEP)
            J[:, j] = (np.log(cg(laminate.with_params(p, material), leg)) - c0) / REL_STEP
        rows.append(J)
        if thickness:
            rows_h.append(((np.log(cg(lam0.scaled_thickness(math.exp(REL_STEP)), leg)) - c0) / REL_STEP)[:, None])
        else:
            rows_h.append(np.zeros((len(leg.freqs), 1)))
    if not rows:
        return np.zeros((0, len(names))), np.zeros((0, 1))
    return np.vstack(rows), np.vstack(rows_h)
