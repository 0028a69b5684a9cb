"""The diagnosis' forward model: ``ForwardModel`` plus the real-plate effects and a fixed pairing.

:class:`GapForward` predicts every feature like ``engine.forward.ForwardModel``
and adds the effects of ``engine.forward.effects.PLATE_EFFECTS``:

* ``misalignment`` a (deg): every ply at angle + a (plate model); a wave path at
  direction phi sees the material at phi - a (SAFE);
* ``ply_angle_error`` e (deg): the top ply (last listed) at angle + e;
* ``density_gradient`` g: rho(x) = rho (1 + g xi), xi = 2x/L - 1: the laminate
  density scaled by (1 - g) plus g times the mass of the density rho (1 + xi): point
  masses rho h w (1 + xi) with rotary inertia m h^2/12 at 3 x 3 Gauss points of every
  plate element (w: the Gauss weight times the element area), assembled once per plate
  model (:func:`gradient_mass`) and scaled by g. Measured against the independent Ritz
  plate with a density field (issue 28): the former lumps on a 24 x 12 grid without rotary
  inertia shifted every mode 0.4-1 per mille too high at g = 0.05-0.10 (aluminium 20 modes
  at 0.1 %: the taper, not the gradient, fitted best);
* ``thickness_taper`` t: h(x) = h (1 + t xi), every ply scaled, as a thickness field
  of the plate model (``PlateModel.with_thickness_field``); modal only (the
  wave path sees the mean thickness h).

The plate model is built by ``ForwardModel``'s one builder (``_plate_model``):
this class only adds the real-plate parts (``_plate_parts``), its pairing
(``_paired``) and a smaller cache.

``pairing`` fixes how measured modes are paired: ``"order"`` / ``"mac"`` as
``labid identify`` does (``engine.forward.ModalForward``), or None for the
``ForwardModel`` default. ``selection`` (one predicted elastic-mode index per
peak, None for a peak identify left unexplained) fixes identify's own
assignment: those modes are predicted by order and picked; :attr:`unexplained`
masks the peaks without a partner (``GapFit`` gives them no residual). Units SI, angles in degrees.
"""
from __future__ import annotations

import weakref
from dataclasses import replace
from typing import Mapping

import numpy as np

from ..features import Features, WaveData
from ..forward import ForwardModel, ModalForward, SelectedModes
from ..forward.effects import F_REF, PLATE_EFFECTS, temperature_params
from ..forward.memo import method_lru
from ..laminate import Laminate, Ply

__all__ = ["GapForward", "turned_laminate", "gradient_mass"]

#: Gauss points per element and direction of the density gradient's mass
GRADIENT_GAUSS = 3
#: unit gradient mass data per plate model (built once; weak keys: dropped with the model)
_GRADIENT_MASS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def gradient_mass(model, length: float, area_density: float, thickness: float) -> np.ndarray:
    """Mass data (``PlateModel.m_add`` layout) of the areal density ``area_density`` (1 + xi),
    xi = 2x/``length`` - 1, on ``model``'s mesh: point masses with rotary inertia m h^2/12 at
    GRADIENT_GAUSS x GRADIENT_GAUSS Gauss points of every element (kg, kg m^2)."""
    key = (float(length), float(area_density), float(thickness))
    hit = _GRADIENT_MASS.get(model)
    if hit is not None and hit[0] == key:
        return hit[1]
    g, wg = np.polynomial.legendre.leggauss(GRADIENT_GAUSS)
    xe, ye = model.mesh.xe, model.mesh.ye
    pts = []
    for x0, x1 in zip(xe[:-1], xe[1:]):
        for y0, y1 in zip(ye[:-1], ye[1:]):
            for gx, wx in zip(g, wg):
                x = x0 + (gx + 1.0) * (x1 - x0) / 2.0
                for gy, wy in zip(g, wg):
                    m = area_density * wx * wy * (x1 - x0) * (y1 - y0) / 4.0 * (2.0 * x / length)
                    if m > 0:
                        pts.append((x, y0 + (gy + 1.0) * (y1 - y0) / 2.0, m, m * thickness ** 2 / 12.0,
                                    m * thickness ** 2 / 12.0))
    data = np.array(model.with_point_masses(pts).m_add) - np.array(model.m_add)
    _GRADIENT_MASS[model] = (key, data)
    return data


def turned_laminate(lam: Laminate, misalignment: float = 0.0, ply_error: float = 0.0) -> Laminate:
    """The laminate with every ply turned by ``misalignment`` deg and the top ply by ``ply_error`` more."""
    n = len(lam.plies)
    return Laminate(tuple(Ply(p.material, p.angle_deg + misalignment + (ply_error if i == n - 1 else 0.0),
                              p.thickness) for i, p in enumerate(lam.plies)))


class GapForward(ForwardModel):
    """``ForwardModel`` with the real-plate effects and a fixed pairing (see module docstring)."""

    def __init__(self, features: Features, mesh=None, safe_order: int | None = None, plate_model=None,
                 pairing: str | None = None, selection=None):
        self.unexplained = None
        self._selection = None
        #: per measured peak, the discretisation correction f_fine / f_default of its mode
        #: (engine.gap.convergence.peak_corrections; None: uncorrected)
        self.peak_correction = None
        if selection is not None and features.modal is not None:
            pairing = "order"
            self._selection = np.array([0 if j is None else int(j) for j in selection], int)
            self.unexplained = np.array([j is None for j in selection], bool)
        if pairing is not None and features.modal is not None:
            features = replace(features, modal=replace(features.modal, pairing=pairing))
        super().__init__(features, mesh=mesh, safe_order=safe_order, plate_model=plate_model)
        self.pairing = pairing
        # few models at a time: a refit moves the effect every evaluation, and each plate
        # model holds its matrices and factorisation (the parent caches 32: ~900 MiB)
        self._plate_fw = method_lru(self._build_plate_forward, 4)
        self._misalign = 0.0

    # -- modal -------------------------------------------------------------
    @property
    def selection(self) -> np.ndarray | None:
        """Per measured peak the predicted elastic-mode index the pairing is fixed to
        (-1: a peak left unexplained); None when the pairing is not fixed."""
        if self._selection is None:
            return None
        return np.where(self.unexplained, -1, self._selection)

    def modal_forward(self, mass: float = 0.0, spring: float = 0.0, thickness: float = 0.0):
        """As ``ForwardModel.modal_forward``; with a fixed ``pairing`` built here (small cache)."""
        if self.pairing is None:
            return super().modal_forward(mass, spring, thickness)
        return self._plate_fw((float(mass), float(spring), float(thickness)), (0.0,) * len(PLATE_EFFECTS))

    def modal_forward_with(self, effects: Mapping[str, float]):
        """The paired modal forward model with every modal effect of ``effects`` built in."""
        e = effects
        plate = tuple(float(e.get(k, 0.0)) for k in PLATE_EFFECTS)
        base = (float(e.get("sensor_mass", 0.0)), float(e.get("support_stiffness", 0.0)),
                float(e.get("thickness", 0.0)))
        if not any(plate) and self.pairing is None:
            return super().modal_forward(*base)
        return self._plate_fw(base, plate)

    def _build_plate_forward(self, base: tuple, plate: tuple):
        keys = ("sensor_mass", "support_stiffness", "thickness") + PLATE_EFFECTS
        return self._paired(self._plate_model(dict(zip(keys, base + plate))))

    def _plate_parts(self, effects: Mapping[str, float]) -> tuple:
        """``ForwardModel._plate_parts`` with the real-plate effects (see module docstring)."""
        p = self.features
        mis, ply, g, taper = (float(effects.get(k, 0.0)) for k in PLATE_EFFECTS)
        thickness = effects.get("thickness", 0.0)
        lam = turned_laminate(p.laminate, mis, ply) if (mis or ply) else p.laminate
        if thickness:
            lam = lam.scaled_thickness(1.0 + thickness)
        if g:
            mat = lam.materials[p.material] if p.material else next(iter(lam.materials.values()))
            lam = lam.with_params({"density": mat.density * (1.0 - g)}, mat.name)
        m_extra = None
        if g:
            h = p.laminate.thickness * (1.0 + thickness)
            m_extra = g * gradient_mass(self.base, p.length, p.laminate.mean_density * h, h)
        field = None
        if taper:
            length = p.length
            field = lambda x, y: 1.0 + taper * (2.0 * x / length - 1.0)   # noqa: E731
        return lam, field, [], m_extra

    def _paired(self, model):
        """Identify's fixed ``selection`` / ``pairing`` when given, else ``ForwardModel``'s pairing."""
        p, md = self.features, self.features.modal
        if self._selection is not None:
            inner = ModalForward(model, int(self._selection.max()) + 1, material=p.material)
            return SelectedModes(inner, self._selection)
        if self.pairing is None:
            return super()._paired(model)
        return ModalForward(model, self.n_modal, points=md.points if md.shapes is not None else None,
                            shapes=md.shapes, material=p.material)

    def predict_modal(self, params: Mapping[str, float], effects: Mapping[str, float]) -> np.ndarray:
        stripped = {k: v for k, v in effects.items() if k not in PLATE_EFFECTS}
        par = temperature_params(params, stripped.get("temperature", 0.0))
        f0 = self.modal_forward_with(effects).predict(par)
        if self.peak_correction is not None:
            f0 = f0 * self.peak_correction
        eta = stripped.get("viscoelastic", 0.0)
        if eta:
            f0 = F_REF * (f0 / F_REF) ** (1.0 / (1.0 - eta / np.pi))
        return f0

    # -- waves -------------------------------------------------------------
    def predict_waves(self, params: Mapping[str, float], effects: Mapping[str, float]) -> list[np.ndarray]:
        self._misalign = float(effects.get("misalignment", 0.0))
        try:
            return super().predict_waves(params, {k: v for k, v in effects.items() if k not in PLATE_EFFECTS})
        finally:
            self._misalign = 0.0

    def _turned(self, w: WaveData) -> WaveData:
        return replace(w, direction_deg=w.direction_deg - self._misalign) if self._misalign else w

    def group_velocity(self, params, thickness: float, w: WaveData, f: np.ndarray) -> np.ndarray:
        return super().group_velocity(params, thickness, self._turned(w), f)

    def phase_velocity(self, params, thickness: float, w: WaveData, f: np.ndarray) -> np.ndarray:
        return super().phase_velocity(params, thickness, self._turned(w), f)
