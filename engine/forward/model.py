"""Every feature of a :class:`~engine.features.Features` predicted for constants plus effects.

The features (CONTRACT section 2) are predicted for elastic constants
``params`` (contract names) plus a dict of effect magnitudes (names and units
of :data:`~engine.forward.effects.EFFECTS`): modal frequencies (Hz) by
:mod:`engine.forward.modal` (paired by MAC with enough measured shape points,
else once by frequency, or by order), then the group velocities (m/s) of each
measured wave set by :class:`~engine.forward.waves.SafeWaves`.

Effect models (each a physical addition to the nominal model; see
:mod:`engine.forward.effects`)
-------------------------------------------------------------------------------
sensor_mass, support_stiffness: point masses / springs added to the plate model.
temperature             moduli scale by (1 + alpha dT) (``temperature_params``).
thickness               every ply scaled by (1 + thickness), plate and SAFE models.
timing_offset, path_length: cg_obs = d / ((d/cg) (d + delta)/d + dt).
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

from typing import Mapping

import numpy as np

from ..features import Features, WaveData
from ..plate import PlateModel
from .effects import EFFECTS, F_REF, EffectError, log_sinc_slope, temperature_params
from .memo import method_lru
from .modal import MIN_MAC_POINTS, ModalForward, SelectedModes, mac, pair_by_frequency
from .waves import SafeWaves

__all__ = ["ForwardModel", "MODAL_KEPT"]

#: modal forward models (plate models with effects built in) kept per ForwardModel
MODAL_KEPT = 4


class ForwardModel:
    """Features predicted for constants and effects (see module docstring).

    ``mesh`` is passed to ``PlateModel.build`` (None: the default mesh);
    ``safe_order`` to the SAFE solver; ``plate_model`` replaces the nominal
    plate model (same specimen). Results are memoised per input.
    """

    def __init__(self, features: Features, mesh=None, safe_order: int | None = None,
                 plate_model=None):
        if features.waves and not features.rig.wave_path_m:
            raise EffectError("waves given without rig.wave_path_m (needed for timing/path effects)")
        self.features, self.safe_order = features, safe_order
        if features.modal is not None:
            self.base = plate_model if plate_model is not None else PlateModel.build(
                features.laminate, features.length, features.width, mesh)
        else:
            self.base = None
        self.safe = SafeWaves(features.laminate, features.material, safe_order)
        # few plate models at a time: each holds its matrices, mass data and modes (~4-8 MiB on
        # the demo's mesh), and a refit of sensor_mass or support_stiffness makes a new one per
        # trial value: with 32 kept, a 3-constant diagnosis of a sensor mass peaked at 347 MiB
        # (bench/RESULTS.md, issue 29 session 24); the solves are deterministic, a miss re-solves
        self._modal_fw = method_lru(self._build_modal_forward, MODAL_KEPT)
        self._sel: np.ndarray | None = None
        self.n_modal = 0 if features.modal is None else len(features.modal.frequency_hz)
        self.n_waves = [len(w.frequency_hz) for w in features.waves]

    # -- observations ----------------------------------------------------------
    @property
    def observed(self) -> np.ndarray:
        p = self.features
        parts = [] if p.modal is None else [np.asarray(p.modal.frequency_hz, float)]
        parts += [np.asarray(w.group_velocity_m_s, float) for w in p.waves]
        return np.concatenate(parts)

    @property
    def sigma(self) -> np.ndarray:
        p = self.features
        parts = [] if p.modal is None else [np.broadcast_to(p.modal.sigma_hz, (self.n_modal,))]
        parts += [np.broadcast_to(w.sigma_m_s, (len(w.frequency_hz),)) for w in p.waves]
        return np.concatenate(parts).astype(float)

    # -- pieces ----------------------------------------------------------------
    def modal_forward(self, mass: float = 0.0, spring: float = 0.0, thickness: float = 0.0
                      ) -> ModalForward | SelectedModes:
        """The paired modal forward model of the plate with ``mass`` kg added at every
        accelerometer, a ``spring`` N/m at every support and a relative ``thickness`` error."""
        return self._modal_fw(mass, spring, thickness)

    def _build_modal_forward(self, mass: float, spring: float, thickness: float
                             ) -> ModalForward | SelectedModes:
        return self._paired(self._plate_model(
            {"sensor_mass": mass, "support_stiffness": spring, "thickness": thickness}))

    # -- the one plate-model builder (engine.gap.GapForward extends _plate_parts / _paired) --
    def _plate_parts(self, effects: Mapping[str, float]) -> tuple:
        """(laminate, thickness field for ``PlateModel.with_thickness_field`` or None,
        extra point masses (x, y, kg), added mass data on the model's sparse pattern
        (``PlateModel.m_add`` layout) or None) of the plate with ``effects``; here: ``thickness``."""
        lam = self.features.laminate
        th = effects.get("thickness", 0.0)
        return (lam.scaled_thickness(1.0 + th) if th else lam), None, [], None

    def _plate_model(self, effects: Mapping[str, float]) -> PlateModel:
        """The nominal plate model with every modal effect of ``effects`` built in: the
        laminate and thickness field of ``_plate_parts``, its point masses, then
        ``sensor_mass`` kg at every accelerometer and ``support_stiffness`` N/m at every support."""
        p = self.features
        lam, field, pts, m_extra = self._plate_parts(effects)
        model = self.base.with_laminate(lam) if lam is not p.laminate else self.base
        if m_extra is not None:      # a mass distribution precomputed on this mesh (one scaled vector)
            model = model.with_added_mass(m_extra)
        if field is not None:
            model = model.with_thickness_field(field)
        mass, spring = effects.get("sensor_mass", 0.0), effects.get("support_stiffness", 0.0)
        if mass and not p.rig.accelerometers:
            raise EffectError("sensor_mass needs rig.accelerometers")
        pts = list(pts) + p.rig.masses(mass)
        if pts:
            model = model.with_point_masses(pts)
        if spring:
            if not p.rig.supports:
                raise EffectError("support_stiffness needs rig.supports")
            model = model.with_springs([(x, y, spring) for x, y in p.rig.supports])
        return model

    def _paired(self, model: PlateModel) -> ModalForward | SelectedModes:
        """The modal forward model of ``model`` paired with the measured modes (by MAC with
        enough shape points, else once by frequency at the nominal model, or by order)."""
        p = self.features
        md = p.modal
        by_freq = md.pairing == "frequency" or (
            md.pairing == "auto" and (md.shapes is None or np.shape(md.shapes)[1] < MIN_MAC_POINTS))
        if not by_freq:
            return ModalForward(model, self.n_modal, points=md.points, shapes=md.shapes,
                                material=p.material)
        # too few shape points for MAC: pair once, at the nominal model, by
        # nearest log-frequency among n + 4 predicted modes (missing modes allowed)
        inner = ModalForward(model, self.n_modal + 4, material=p.material)
        if self._sel is None:
            f_nom = inner.predict(p.nominal())
            macs = None
            if md.shapes is not None and md.points is not None:
                modes, idx, _ = inner.solve(p.nominal())
                macs = mac(np.asarray(md.shapes, float), inner.model.shapes_at(modes, md.points)[idx])
            self._sel = pair_by_frequency(md.frequency_hz, f_nom, macs)
        return SelectedModes(inner, self._sel)

    def group_velocity(self, params, thickness: float, w: WaveData, f: np.ndarray) -> np.ndarray:
        return self.safe.group_velocity(params, thickness, w.mode, w.direction_deg, f)

    def phase_velocity(self, params, thickness: float, w: WaveData, f: np.ndarray) -> np.ndarray:
        return self.safe.phase_velocity(params, thickness, w.mode, w.direction_deg, f)

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
        rig = self.features.rig
        d = rig.wave_path_m
        out = []
        for w in self.features.waves:
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
                        slope += sign * log_sinc_slope(k * L / 2.0) * (L / 2.0) * dkdf
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
            raise EffectError(f"unknown effect(s) {sorted(unknown)}; expected {list(EFFECTS)}")
        parts = []
        if self.features.modal is not None:
            parts.append(self.predict_modal(params, effects))
        if self.features.waves:
            with np.errstate(divide="ignore", invalid="ignore"):   # absent mode: non-finite
                parts += self.predict_waves(params, effects)
        return np.concatenate(parts)
