"""Forward model of the measured features with the candidate unmodelled effects.

The features (CONTRACT section 2) are predicted for elastic constants ``params``
(contract names) plus a dict of effect magnitudes (CONTRACT effect names, SI):

modal frequencies (Hz), paired with the measured modes by MAC when shapes are
given (``engine.identify_models.ModalForward``), and group velocities (m/s) of
each measured wave set (``engine.safe.group_velocity``).

Effect models (each a physical addition to the nominal model)
-------------------------------------------------------------
sensor_mass (kg)        point mass at every accelerometer (plate_fe.with_point_masses).
support_stiffness (N/m) transverse spring at every support (plate_fe.with_springs).
temperature (K)         moduli scale by (1 + alpha dT): ALPHA_FIBRE for E1,
                        ALPHA_MATRIX for E2, G12, G13, G23, ALPHA_ISOTROPIC for E, G.
thickness (1)           relative thickness error, every ply (laminate.scaled_thickness).
timing_offset (s)       measured delay d/cg + dt, so cg_obs = d / (d/cg + dt).
path_length (m)         true path d + delta, processed with d: cg_obs = cg d / (d + delta).
sensor_aperture (m)     strain averaged over length L (replacing the nominal L0):
                        a zero-phase wavenumber filter sinc(kL/2). It moves no
                        phase; it tilts the spectrum, so the complex-Morlet
                        (bandwidth B, centre C) ridge at f samples the packet at
                        the centroid f + sigma_f^2 d ln|H|/df, sigma_f = f/(pi C
                        sqrt(2B)); the picked delay moves by
                        tau_g'(f) sigma_f^2 [d ln|H_L|/df - d ln|H_L0|/df].
viscoelastic (1)        constant-Q (Kjartansson) loss factor eta: causal
                        (Kramers-Kronig) moduli M(f) = M (f/F_REF)^(2 eta/pi);
                        modes f = F_REF (f0/F_REF)^(1/(1 - eta/pi)); waves
                        cg(f) = sqrt(s) cg0(f/sqrt(s)) / (1 - eta/pi),
                        s = (f/F_REF)^(2 eta/pi), plus the attenuation
                        exp(-eta k d/2) seen through the same centroid shift
                        (d ln A/df = -pi eta d / cg).

Units SI: m, kg, s, Pa, Hz, m/s, K.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from .identify_models import ModalForward
from .laminate import Laminate

__all__ = ["EffectSpec", "EFFECTS", "ALPHA_FIBRE", "ALPHA_MATRIX", "ALPHA_ISOTROPIC", "F_REF",
           "ModalData", "WaveData", "RigLayout", "GapProblem", "ForwardModel", "temperature_params",
           "GapError"]

#: temperature coefficients of the moduli, 1/K (typical CFRP / aluminium)
ALPHA_FIBRE = -1.0e-4
ALPHA_MATRIX = -2.0e-3
ALPHA_ISOTROPIC = -4.0e-4
#: reference frequency (Hz) at which the constants of a viscoelastic plate hold
F_REF = 1000.0


class GapError(ValueError):
    """Bad diagnosis input (no data, unknown effect, inconsistent arrays)."""


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
)}


@dataclass(frozen=True)
class ModalData:
    """Measured natural frequencies (Hz), their sigmas, optional mode shapes at points (m)."""

    frequency_hz: np.ndarray
    sigma_hz: np.ndarray
    points: np.ndarray | None = None
    shapes: np.ndarray | None = None
    pairing: str = "auto"   # 'mac', 'frequency', 'order' or 'auto' (MAC with >= 6 shape points)


@dataclass(frozen=True)
class WaveData:
    """Measured group velocities of one wave mode along one direction."""

    mode: str
    direction_deg: float
    frequency_hz: np.ndarray
    group_velocity_m_s: np.ndarray
    sigma_m_s: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.mode}@{self.direction_deg:g}deg"


@dataclass(frozen=True)
class RigLayout:
    """Nominal rig geometry (m): accelerometer and support points, wave path, sensor length."""

    accelerometers: tuple[tuple[float, float], ...] = ()
    supports: tuple[tuple[float, float], ...] = ()
    wave_path_m: float | None = None
    sensor_length_m: float = 0.0
    temperature_c: float | None = None
    wavelet_bandwidth: float = 2.0
    wavelet_center: float = 5.0
    accelerometer_masses: tuple[float, ...] = ()   # kg, declared (part of the nominal model)

    def masses(self, extra: float = 0.0) -> list[tuple[float, float, float]]:
        """(x, y, m) point masses: declared accelerometer masses plus ``extra`` kg each."""
        m0 = self.accelerometer_masses or (0.0,) * len(self.accelerometers)
        return [(x, y, m + extra) for (x, y), m in zip(self.accelerometers, m0) if m + extra != 0.0]


@dataclass(frozen=True)
class GapProblem:
    """Everything the diagnoser is given: nominal specimen, rig layout, measured features."""

    laminate: Laminate
    length: float
    width: float
    rig: RigLayout
    modal: ModalData | None = None
    waves: tuple[WaveData, ...] = ()
    material: str | None = None

    def __post_init__(self) -> None:
        if self.modal is None and not self.waves:
            raise GapError("features hold neither modal frequencies nor wave group velocities")
        if self.waves and not self.rig.wave_path_m:
            raise GapError("waves given without rig.wave_path_m (needed for timing/path effects)")

    @property
    def material_obj(self):
        mats = self.laminate.materials
        return mats[self.material] if self.material else next(iter(mats.values()))

    def param_names(self) -> tuple[str, ...]:
        """Fitted constants: every modulus and Poisson ratio (density is weighed)."""
        m = self.material_obj
        return ("E", "G") if m.isotropic else ("E1", "E2", "nu12", "G12", "G13", "G23")

    def nominal(self) -> dict[str, float]:
        p = self.material_obj.params()
        return {n: p[n] for n in self.param_names()}


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


def _log_sinc_slope(x: np.ndarray) -> np.ndarray:
    """d ln|sin x / x| / dx, finite near the nulls (capped 0.15 rad away)."""
    x = np.asarray(x, float)
    n = np.round(x / np.pi)
    near = (n >= 1) & (np.abs(x - n * np.pi) < 0.15)
    xs = np.where(near, n * np.pi - 0.15, x)
    xs = np.where(xs < 1e-6, 1e-6, xs)
    return np.where(x < 1e-6, 0.0, 1.0 / np.tan(xs) - 1.0 / xs)


#: fewer shape points than this: measured modes are paired once, at the nominal
#: model, by log-frequency distance / PAIR_REL_FREQ + (1 - MAC) (Hungarian)
MIN_MAC_POINTS = 6
PAIR_REL_FREQ = 0.05


class _FreqPaired:
    """A ModalForward over n + extra modes (by order) restricted to a fixed selection."""

    def __init__(self, inner: ModalForward, sel: np.ndarray):
        self.inner, self.sel, self.model = inner, sel, inner.model

    def predict(self, params):
        return self.inner.predict(params)[self.sel]

    def jacobian(self, params, names):
        f, J = self.inner.jacobian(params, names)
        return f[self.sel], J[self.sel]

    def solve(self, params):
        modes, idx = self.inner.solve(params)
        return modes, idx[self.sel]


class ForwardModel:
    """Features predicted for constants and effects (see module docstring).

    ``mesh`` is passed to ``PlateModel.build`` (None: the default mesh);
    ``safe_order`` to the SAFE solver. Results are cached per input.
    """

    def __init__(self, problem: GapProblem, mesh=None, safe_order: int | None = None,
                 plate_model=None):
        from .plate import PlateModel
        self.problem, self.safe_order = problem, safe_order
        if problem.modal is not None:
            self.base = plate_model if plate_model is not None else PlateModel.build(
                problem.laminate, problem.length, problem.width, mesh)
        else:
            self.base = None
        self._modal_fw: dict = {}
        self._sel: np.ndarray | None = None
        self._cg: dict = {}
        self._cp: dict = {}
        self.n_modal = 0 if problem.modal is None else len(problem.modal.frequency_hz)
        self.n_waves = [len(w.frequency_hz) for w in problem.waves]

    # -- observations ----------------------------------------------------------
    @property
    def observed(self) -> np.ndarray:
        p = self.problem
        parts = [] if p.modal is None else [np.asarray(p.modal.frequency_hz, float)]
        parts += [np.asarray(w.group_velocity_m_s, float) for w in p.waves]
        return np.concatenate(parts)

    @property
    def sigma(self) -> np.ndarray:
        p = self.problem
        parts = [] if p.modal is None else [np.broadcast_to(p.modal.sigma_hz, (self.n_modal,))]
        parts += [np.broadcast_to(w.sigma_m_s, (len(w.frequency_hz),)) for w in p.waves]
        return np.concatenate(parts).astype(float)

    # -- pieces ----------------------------------------------------------------
    def modal_forward(self, mass: float = 0.0, spring: float = 0.0, thickness: float = 0.0
                      ) -> ModalForward:
        key = (round(mass, 12), round(spring, 9), round(thickness, 12))
        fw = self._modal_fw.get(key)
        if fw is None:
            p = self.problem
            model = self.base
            if thickness:
                model = self.base.with_laminate(p.laminate.scaled_thickness(1.0 + thickness))
            if mass and not p.rig.accelerometers:
                raise GapError("sensor_mass needs rig.accelerometers")
            masses = p.rig.masses(mass)
            if masses:
                model = model.with_point_masses(masses)
            if spring:
                if not p.rig.supports:
                    raise GapError("support_stiffness needs rig.supports")
                model = model.with_springs([(x, y, spring) for x, y in p.rig.supports])
            md = p.modal
            by_freq = md.pairing == "frequency" or (
                md.pairing == "auto" and (md.shapes is None or np.shape(md.shapes)[1] < MIN_MAC_POINTS))
            if by_freq:
                # too few shape points for MAC: pair once, at the nominal model, by
                # nearest log-frequency among n + 4 predicted modes (missing modes allowed)
                inner = ModalForward(model, self.n_modal + 4, material=p.material)
                if self._sel is None:
                    from scipy.optimize import linear_sum_assignment

                    from .identify_models import mac
                    f_nom = inner.predict(p.nominal())
                    cost = np.abs(np.log(np.asarray(md.frequency_hz, float))[:, None]
                                  - np.log(f_nom)[None, :]) / PAIR_REL_FREQ
                    if md.shapes is not None and md.points is not None:
                        modes, idx = inner.solve(p.nominal())
                        cost = cost + 1.0 - mac(np.asarray(md.shapes, float),
                                                inner.model.shapes_at(modes, md.points)[idx])
                    rows, cols = linear_sum_assignment(cost)
                    self._sel = cols[np.argsort(rows)]
                fw = _FreqPaired(inner, self._sel)
            else:
                fw = ModalForward(model, self.n_modal, points=md.points, shapes=md.shapes,
                                  material=p.material)
            if len(self._modal_fw) > 24:
                self._modal_fw.pop(next(iter(self._modal_fw)))
            self._modal_fw[key] = fw
        return fw

    def _laminate(self, params: Mapping[str, float], thickness: float) -> Laminate:
        lam = self.problem.laminate.with_params(dict(params), self.problem.material)
        for m in lam.materials.values():
            m.check()
        return lam.scaled_thickness(1.0 + thickness) if thickness else lam

    def group_velocity(self, params, thickness: float, w: WaveData, f: np.ndarray) -> np.ndarray:
        from .safe import group_velocity
        key = (tuple(sorted(params.items())), round(thickness, 12), w.mode, w.direction_deg,
               tuple(np.round(f, 6)))
        v = self._cg.get(key)
        if v is None:
            v = np.asarray(group_velocity(self._laminate(params, thickness), f, mode=w.mode,
                                          direction_deg=w.direction_deg, order=self.safe_order), float)
            if len(self._cg) > 256:
                self._cg.pop(next(iter(self._cg)))
            self._cg[key] = v
        return v

    def phase_velocity(self, params, thickness: float, w: WaveData, f: np.ndarray) -> np.ndarray:
        from .safe import dispersion
        key = (tuple(sorted(params.items())), round(thickness, 12), w.mode, w.direction_deg,
               tuple(np.round(f, 6)))
        v = self._cp.get(key)
        if v is None:
            d = dispersion(self._laminate(params, thickness), f, w.direction_deg, order=self.safe_order)
            v = np.asarray(d.mode(w.mode).phase_velocity_m_s, float)
            if len(self._cp) > 64:
                self._cp.pop(next(iter(self._cp)))
            self._cp[key] = v
        return v

    # -- prediction ------------------------------------------------------------
    def predict_modal(self, params: Mapping[str, float], effects: Mapping[str, float]) -> np.ndarray:
        e = effects
        par = temperature_params(params, e.get("temperature", 0.0))
        fw = self.modal_forward(e.get("sensor_mass", 0.0), e.get("support_stiffness", 0.0),
                                e.get("thickness", 0.0))
        f0 = fw.predict(par)
        eta = e.get("viscoelastic", 0.0)
        if eta:
            f0 = F_REF * (f0 / F_REF) ** (1.0 / (1.0 - eta / np.pi))
        return f0

    def predict_waves(self, params: Mapping[str, float], effects: Mapping[str, float]) -> list[np.ndarray]:
        e = effects
        par = temperature_params(params, e.get("temperature", 0.0))
        th = e.get("thickness", 0.0)
        eta = e.get("viscoelastic", 0.0)
        ap = e.get("sensor_aperture", None)
        rig = self.problem.rig
        d = rig.wave_path_m
        out = []
        for w in self.problem.waves:
            f = np.asarray(w.frequency_hz, float)
            if eta:
                s = (f / F_REF) ** (2.0 * eta / np.pi)
                cg = np.sqrt(s) * self.group_velocity(par, th, w, f / np.sqrt(s)) / (1.0 - eta / np.pi)
            else:
                cg = self.group_velocity(par, th, w, f)
            slope = np.zeros_like(f)        # change of d ln A / df seen by the wavelet
            if eta:
                slope += -np.pi * eta * d / cg
            if ap is not None and ap != rig.sensor_length_m:
                cp = self.phase_velocity(par, th, w, f)
                dkdf = 2.0 * np.pi / cg
                k = 2.0 * np.pi * f / cp
                for L, sign in ((ap, 1.0), (rig.sensor_length_m, -1.0)):
                    if L > 0:
                        slope += sign * _log_sinc_slope(k * L / 2.0) * (L / 2.0) * dkdf
            tau = d / cg
            if np.any(slope):
                h = 1e-3
                cg2 = self.group_velocity(par, th, w, f * (1.0 + h)) if not eta else None
                if cg2 is None:
                    s2 = (f * (1 + h) / F_REF) ** (2.0 * eta / np.pi)
                    cg2 = np.sqrt(s2) * self.group_velocity(par, th, w, f * (1 + h) / np.sqrt(s2)) \
                        / (1.0 - eta / np.pi)
                dtau = (d / cg2 - tau) / (h * f)
                sig_f = f / (np.pi * rig.wavelet_center * np.sqrt(2.0 * rig.wavelet_bandwidth))
                tau = tau + dtau * sig_f ** 2 * slope
            delta = e.get("path_length", 0.0)
            tau = tau * (d + delta) / d + e.get("timing_offset", 0.0)
            out.append(d / tau)
        return out

    def predict(self, params: Mapping[str, float], effects: Mapping[str, float] | None = None
                ) -> np.ndarray:
        """All features (modal Hz, then each wave set m/s), concatenated."""
        effects = {k: float(v) for k, v in (effects or {}).items() if v or k == "sensor_aperture"}
        unknown = set(effects) - set(EFFECTS)
        if unknown:
            raise GapError(f"unknown effect(s) {sorted(unknown)}; expected {list(EFFECTS)}")
        parts = []
        if self.problem.modal is not None:
            parts.append(self.predict_modal(params, effects))
        if self.problem.waves:
            with np.errstate(divide="ignore", invalid="ignore"):   # absent mode: non-finite
                parts += self.predict_waves(params, effects)
        return np.concatenate(parts)

    def modal_jacobian(self, params: Mapping[str, float], names: Sequence[str]) -> np.ndarray:
        """d f / d p (Hz per unit p) of the nominal modal model (analytic)."""
        _, J = self.modal_forward().jacobian(dict(params), list(names))
        return J
