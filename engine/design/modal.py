"""The plate's modes at prior draws, sampled where sensors and the hammer may go.

A modal test's information on the constants comes from the natural frequencies it
measures; which of them it measures, and how well, depends on where the accelerometers
sit and where the hammer strikes (a mode with a nodal line at either is not seen), on the
band the hammer and the acquisition cover, and on the sensors' own mass. This module
solves the plate (``engine.plate.PlateModel``, free-free) once per parameter draw and
keeps what the design needs: frequencies, the relative sensitivities
d ln f / d ln p of every constant (from ``PlateModel.eigen_sensitivities``, the analytic
derivative the fit uses), and the transverse shape at every candidate point, both as the
amplitude relative to the mode's peak on the plate (the pairing's visibility rule,
``engine.forward.pairing.visibility``) and as the squared mass-normalised value (a point
mass m there changes ln f by -m phi^2 / 2 to first order).

:class:`Measurement` is the model of how a peak is measured (docs/plan.md): a frequency
std ``sigma_rel`` f for a well excited peak, growing as 1/response below ``v_ref``; a
peak below ``v_min`` is not seen; of two seen peaks closer than their half-power
bandwidth (or two frequency bins) only the stronger is measured; the hammer's half-sine
spectrum and the acquisition band set the excitation.

Units SI: Hz, m, kg, s; sensitivities per unit ln p (dimensionless).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from ..laminate import Material, PhysicsError

__all__ = ["Measurement", "ModalSet", "modal_set", "prior_draws", "half_sine_spectrum", "AMP_GRID"]

#: points per direction of the edge-to-edge grid on which a mode's peak |w| is found
AMP_GRID = 25


def half_sine_spectrum(f_hz, contact_s: float | None) -> np.ndarray:
    """|F(f)| / F(0) of a half-sine force pulse of duration ``contact_s`` (s): cos(pi f T) /
    (1 - (2 f T)^2), first zero at 1.5 / T. ``None``: a flat spectrum (1)."""
    f = np.asarray(f_hz, float)
    if not contact_s:
        return np.ones_like(f)
    u = 2.0 * f * contact_s
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.abs(np.cos(0.5 * np.pi * u) / (1.0 - u ** 2))
    return np.where(np.abs(u - 1.0) < 1e-9, np.pi / 4.0, g)


@dataclass(frozen=True)
class Measurement:
    """How a modal test measures a peak (docs/plan.md, "measurement model").

    sigma_rel: relative frequency std of a fully visible peak (the lab's repeatability);
    v_ref: response (relative amplitude at the tap times that at the sensors, root-sum-
    square over the sensors, times the hammer spectrum) at which the noise-limited std
    equals sigma_rel: sigma = sigma_rel f sqrt(1 + (v_ref / v)^2); v_min: a peak weaker
    than this is not measured; damping: modal damping ratio (half-power bandwidth 2 zeta f);
    resolution_hz: the spectrum's bin (1 / record length); contact_s: hammer contact time
    (s; None: flat excitation); f_max_hz: the acquisition band (anti-alias cutoff);
    mass_kg: each accelerometer's mass; mass_u_rel: its relative standard uncertainty.
    """

    sigma_rel: float = 1e-3
    v_ref: float = 0.25
    v_min: float = 0.05
    damping: float = 0.005
    resolution_hz: float = 0.5
    contact_s: float | None = 2.0e-4
    f_max_hz: float = math.inf
    mass_kg: float = 0.0
    mass_u_rel: float = 0.1

    def excitation(self, f_hz) -> np.ndarray:
        """Relative force spectrum at ``f_hz``, 0 above the acquisition band."""
        f = np.asarray(f_hz, float)
        return np.where(f < self.f_max_hz, half_sine_spectrum(f, self.contact_s), 0.0)

    def band_hz(self, level: float = 0.1) -> float:
        """Highest frequency measured: the acquisition band or where the hammer's spectrum
        first falls below ``level`` (0.1: -20 dB), Hz."""
        if not self.contact_s:
            return float(self.f_max_hz)
        f = np.linspace(0.0, 1.5 / self.contact_s, 3001)
        low = np.flatnonzero(half_sine_spectrum(f, self.contact_s) < level)
        return float(min(self.f_max_hz, f[low[0]] if low.size else f[-1]))

    def bandwidth_hz(self, f_hz) -> np.ndarray:
        """Frequency separation below which two peaks are not resolved, Hz."""
        return np.maximum(2.0 * self.damping * np.asarray(f_hz, float), 2.0 * self.resolution_hz)


@dataclass(frozen=True)
class ModalSet:
    """Modes at D prior draws, M modes each (padded with NaN frequencies), C points.

    ``names``: the constants of ``jac``'s columns; ``params``: each draw's constants;
    ``freqs`` (D, M) Hz; ``jac`` (D, M, P) d ln f / d ln p; ``amp`` (D, M, C) |w| at the
    points over the mode's peak |w| on the plate (0 for in-plane modes); ``phi2`` (D, M, C)
    w^2 of the mass-normalised shape (1/kg); ``points`` (C, 2) m; ``first_modes``: the
    ``engine.plate.Modes`` of the first draw (the nominal), for figures and labels.
    """

    names: tuple[str, ...]
    params: tuple[dict, ...]
    freqs: np.ndarray
    jac: np.ndarray
    amp: np.ndarray
    phi2: np.ndarray
    points: np.ndarray
    first_modes: object = field(default=None, repr=False, compare=False)

    @property
    def n_draws(self) -> int:
        return self.freqs.shape[0]


def prior_draws(material: Material, names: Sequence[str], prior_rel: Mapping[str, float], n: int,
                seed: int = 0) -> list[dict[str, float]]:
    """The nominal constants and ``n - 1`` draws around them: each constant of ``names``
    log-normal with relative std ``prior_rel[name]`` (0: fixed), quasi-random (scrambled
    Sobol mapped to normal deviates); draws giving an inadmissible material (3D stiffness not
    positive definite) are skipped. Values SI."""
    nominal = material.params()
    base = {k: nominal[k] for k in names}
    out = [dict(base)]
    free = [k for k in names if prior_rel.get(k, 0.0) > 0]
    if n <= 1 or not free:
        return out
    from scipy.stats import norm, qmc  # here: ~0.4 s CPU to import, needed by plan only
    sob = qmc.Sobol(len(free), scramble=True, seed=seed)
    tries = 0
    while len(out) < n and tries < 8:
        tries += 1
        u = np.clip(sob.random(max(2, 1 << int(np.ceil(np.log2(n))))), 1e-6, 1 - 1e-6)
        for z in norm.ppf(u):
            p = dict(base)
            for k, zk in zip(free, z):
                p[k] = base[k] * float(np.exp(prior_rel[k] * zk))
            try:
                material.with_params(**p).check()
            except (PhysicsError, ValueError):
                continue
            out.append(p)
            if len(out) == n:
                break
    return out


def modal_set(model, draws: Sequence[Mapping[str, float]], names: Sequence[str], points, n_modes: int,
              material: str | None = None, progress: Callable[[str], None] | None = None) -> ModalSet:
    """Solve ``model`` (a ``PlateModel``, no sensor masses) at every draw and sample its
    ``n_modes`` lowest elastic modes at ``points`` ((C, 2), m). Sensitivities to ``names``."""
    pts = np.asarray(points, float)
    L, W = model.mesh.length, model.mesh.width
    g = np.array([[x, y] for x in np.linspace(0, L, AMP_GRID) for y in np.linspace(0, W, AMP_GRID)])
    D, M, C, P = len(draws), int(n_modes), len(pts), len(names)
    freqs = np.full((D, M), np.nan)
    jac = np.zeros((D, M, P))
    amp = np.zeros((D, M, C))
    phi2 = np.zeros((D, M, C))
    params, first = [], None
    for d, p in enumerate(draws):
        if progress is not None:
            progress(f"modes at draw {d + 1}/{D}")
        modes = model.solve(M, params=dict(p), material=material)
        first = modes if d == 0 else first
        dw2 = model.eigen_sensitivities(modes, list(names), params=dict(p), material=material)
        vals = np.array([p[n] for n in names])
        freqs[d] = modes.frequencies_hz
        jac[d] = dw2 * vals[None, :] / (2.0 * modes.omega2[:, None])
        w_pts = model.shapes_at(modes, pts)                       # (M, C), 1/sqrt(kg)
        peak = np.abs(model.shapes_at(modes, g)).max(axis=1)
        ref = float(np.median(peak)) if peak.size else 0.0
        ok = peak > 1e-6 * ref                                    # in-plane modes: no w
        amp[d] = np.where(ok[:, None], np.abs(w_pts) / np.where(ok, peak, 1.0)[:, None], 0.0)
        phi2[d] = w_pts ** 2
        params.append(dict(p))
    return ModalSet(tuple(names), tuple(params), freqs, jac, np.clip(amp, 0.0, 1.0), phi2, pts, first)
