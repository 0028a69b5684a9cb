"""The candidate unmodelled effects: the single registry, and the physics they share.

Each effect is a physical addition to the nominal model of the plate and rig
(CONTRACT effect names, SI units). The simulated rig (``mock_hw.rig``) injects
them, :class:`~engine.forward.model.ForwardModel` predicts the features with
them, and the gap diagnosis (``engine.gap``) looks for them; all read names,
units, plausible ranges, typical magnitudes and modalities from
:data:`EFFECTS`.

sensor_mass (kg)        point mass at every accelerometer (engine.plate PlateModel.with_point_masses).
support_stiffness (N/m) transverse spring at every support (engine.plate PlateModel.with_springs).
temperature (K)         moduli scale by (1 + alpha dT): ALPHA_FIBRE for E1,
                        ALPHA_MATRIX for E2, G12, G13, G23, ALPHA_ISOTROPIC for E, G.
thickness (1)           relative thickness error, every ply (laminate.scaled_thickness).
timing_offset (s)       measured delay d/cg + dt, so cg_obs = d / (d/cg + dt).
path_length (m)         true path d + delta, processed with d: cg_obs = cg d / (d + delta).
sensor_aperture (m)     strain averaged over length L (replacing the nominal L0):
                        a zero-phase wavenumber filter sinc(kL/2) (:func:`log_sinc_slope`).
viscoelastic (1)        constant-Q (Kjartansson) loss factor eta; the constants
                        hold at F_REF.

Real-plate effects (modelled in ``engine.gap.forward.GapForward``, not in the
nominal ``ForwardModel``; the blind bench injects them through the same code):

misalignment (deg)      material axes of the whole layup turned by +a in the plate
                        plane (fibre or grain angle offset); waves: a path at
                        direction phi sees the material at phi - a.
ply_angle_error (deg)   the top ply (last listed) laid at its angle + e.
density_gradient (1)    linear density rho(x) = rho (1 + g (2x/L - 1)) along the
                        length (g >= 0: the sign is not seen by free-free
                        frequencies, which are even in g for a symmetric plate).
thickness_taper (1)     linear thickness h(x) = h (1 + t xi), xi = 2x/L - 1, along the
                        length, every ply scaled (engine.plate PlateModel.with_thickness_field:
                        A, H ~ s, B ~ s^2, D ~ s^3, inertias I_k ~ s^k per element);
                        t >= 0: as for density_gradient the sign is not seen by the
                        free-free frequencies of a symmetric plate (even in t, second
                        order). Modal only: the wave path sees the mean thickness h.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

__all__ = ["EffectSpec", "EFFECTS", "EffectError", "ALPHA_FIBRE", "ALPHA_MATRIX", "ALPHA_ISOTROPIC",
           "F_REF", "temperature_params", "log_sinc_slope", "PLATE_EFFECTS", "ANGLE_EFFECTS",
           "LOOKALIKES", "separation", "outside_lookalikes"]

#: temperature coefficients of the moduli, 1/K: E -> E (1 + alpha dT) (typical CFRP / aluminium)
ALPHA_FIBRE = -1.0e-4      # E1 of an orthotropic ply (fibre dominated)
ALPHA_MATRIX = -2.0e-3     # E2, G12, G13, G23 (matrix dominated)
ALPHA_ISOTROPIC = -4.0e-4  # E, G of an isotropic metal (aluminium ~ -0.04 %/K)
#: reference frequency (Hz) at which the constants of a viscoelastic plate hold
F_REF = 1000.0


class EffectError(ValueError):
    """An effect the forward model cannot apply (unknown name, rig geometry it needs missing)."""


@dataclass(frozen=True)
class EffectSpec:
    """A candidate effect: unit, plausible range [lo, hi], typical magnitude (FD scale)."""

    name: str
    unit: str
    lo: float
    hi: float
    typical: float
    modalities: tuple[str, ...]
    doc: str


EFFECTS: dict[str, EffectSpec] = {e.name: e for e in (
    EffectSpec("sensor_mass", "kg", 0.0, 0.03, 0.002, ("modal",), "accelerometer mass at each sensor"),
    EffectSpec("support_stiffness", "N/m", 0.0, 5000.0, 200.0, ("modal",), "suspension spring at each support"),
    EffectSpec("temperature", "K", -30.0, 30.0, 5.0, ("modal", "waves"), "specimen minus reference temperature"),
    EffectSpec("thickness", "1", -0.1, 0.1, 0.01, ("modal", "waves"), "relative thickness error"),
    EffectSpec("timing_offset", "s", -2e-5, 2e-5, 1e-6, ("waves",), "delay added to every wave arrival"),
    EffectSpec("path_length", "m", -0.05, 0.05, 0.005, ("waves",), "true minus nominal wave path"),
    EffectSpec("sensor_aperture", "m", 0.0, 0.03, 0.01, ("waves",), "strain-averaging length of the wave sensor"),
    EffectSpec("viscoelastic", "1", 0.0, 0.1, 0.01, ("modal", "waves"), "constant-Q loss factor"),
    EffectSpec("misalignment", "deg", 0.0, 8.0, 2.0, ("modal", "waves"),
               "material axes of the whole layup turned in the plate plane"),
    EffectSpec("ply_angle_error", "deg", -10.0, 10.0, 3.0, ("modal",), "top ply laid at a wrong angle"),
    EffectSpec("density_gradient", "1", 0.0, 0.15, 0.05, ("modal",),
               "linear density change along the length (relative change at each end)"),
    EffectSpec("thickness_taper", "1", 0.0, 0.15, 0.05, ("modal",),
               "linear thickness change along the length (relative change at each end)"),
)}

#: effects of the real plate (layup, geometry, material distribution): orthotropic layups only
#: for the angle effects; evaluated by ``engine.gap.forward.GapForward``
PLATE_EFFECTS = ("misalignment", "ply_angle_error", "density_gradient", "thickness_taper")
ANGLE_EFFECTS = ("misalignment", "ply_angle_error")


#: pairs of library effects that can leave nearly the same signature, and what measurement
#: separates them (the diagnosis names them as one confusable group when the data do not)
LOOKALIKES: dict[frozenset, str] = {
    frozenset({"path_length", "timing_offset"}): (
        "over a nearly flat part of the dispersion curve a path error (delay ~ 1/c_g) and a "
        "timing offset (constant delay) shift every arrival alike; separated by a second "
        "source-sensor distance, a wider band reaching the dispersive low-frequency A0, or S0"),
    frozenset({"density_gradient", "thickness_taper"}): (
        "both are second order in the free-free frequencies and load the same modes; separated "
        "by the thickness at a few points (calliper or ultrasonic gauge) or by weighing, or by "
        "group velocities along the length (a taper changes the local A0 dispersion, a density "
        "gradient much less)"),
    frozenset({"sensor_mass", "density_gradient"}): (
        "mass near the corners: separated by moving or changing one accelerometer (a sensor "
        "mass moves with it)"),
    frozenset({"misalignment", "ply_angle_error"}): (
        "both turn the material axes; separated by group velocities at several directions "
        "(a whole-layup turn shifts every direction alike) or a ply-by-ply cut/CT check"),
    frozenset({"thickness", "temperature"}): (
        "both rescale the moduli the constants absorb; separated by S0 velocities (thickness) "
        "or by measuring at another temperature"),
}

#: effects outside the library that measurably mimic a library effect within the noise
#: (issue 28, bench/bench_gap_independent.py: a mild anticlastic curvature is fitted by
#: support springs), with what separates them
OUTSIDE_LOOKALIKES: dict[str, tuple[tuple[str, str], ...]] = {
    "support_stiffness": (("anticlastic curvature of the plate (not modelled)",
                           "re-hang the plate on softer or longer wires, or at other points: a spring "
                           "effect moves, a curvature does not; or check flatness with a straightedge "
                           "across both diagonals"),),
}


def separation(a: str, b: str) -> str | None:
    """What separates library effects ``a`` and ``b`` (None: not a known look-alike pair)."""
    return LOOKALIKES.get(frozenset({a, b}))


def outside_lookalikes(name: str) -> tuple[tuple[str, str], ...]:
    """(look-alike outside the library, what separates it) for a library effect ``name``."""
    return OUTSIDE_LOOKALIKES.get(name, ())


def temperature_params(params: Mapping[str, float], dT: float) -> dict[str, float]:
    """Constants at a temperature dT (K) above the one they hold at."""
    out = dict(params)
    for k in out:
        if k == "E1":
            out[k] *= 1.0 + ALPHA_FIBRE * dT
        elif k in ("E2", "G12", "G13", "G23"):
            out[k] *= 1.0 + ALPHA_MATRIX * dT
        elif k in ("E", "G"):
            out[k] *= 1.0 + ALPHA_ISOTROPIC * dT
    return out


def log_sinc_slope(x: np.ndarray) -> np.ndarray:
    """d ln|sin x / x| / dx, finite near the nulls (capped 0.15 rad away)."""
    x = np.asarray(x, float)
    n = np.round(x / np.pi)
    near = (n >= 1) & (np.abs(x - n * np.pi) < 0.15)
    xs = np.where(near, n * np.pi - 0.15, x)
    xs = np.where(xs < 1e-6, 1e-6, xs)
    return np.where(x < 1e-6, 0.0, 1.0 / np.tan(xs) - 1.0 / xs)
