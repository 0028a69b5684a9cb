"""Re-pairing the peaks under a candidate effect (issue 13: pairing inside each refit).

``labid identify`` pairs the measured peaks with predicted modes at its own estimate,
without any effect (``engine.forward.pairing.assign``: missing modes and spurious peaks
allowed, weighted by each mode's visibility at the response points). An effect that moves
modes past each other (a sensor mass lowers some modes much more than others) makes that
pairing wrong exactly where the effect is, and a refit under the old pairing cannot find
the effect. So after each candidate refit the peaks are paired again, with the same
likelihood rule, at the refitted constants *under the effect*; when the pairing changes
and its penalised cost (chi^2 + ``SPURIOUS`` per unexplained peak + the visibility-weighted
``MISS`` of each skipped in-band mode, as identify's) falls, the candidate is refitted
with it, up to ``MAX_ROUNDS`` times.

Only for modal data paired by likelihood or by order (MAC pairing with measured shapes
re-pairs at every evaluation already). Units: Hz.
"""
from __future__ import annotations

from typing import Mapping, NamedTuple

import numpy as np

from ..forward import F_REF, temperature_params
from ..forward.modal import extra_modes
from ..forward.pairing import MISS, MISS_UNKNOWN, SPURIOUS, V_SEEN, assign, visibility
from .forward import GapForward
from .residuals import GapFit

__all__ = ["Pairing", "current_selection", "state", "tolerance", "most_likely", "with_selection", "shape_paired", "pairing_of", "penalty",
           "MAX_ROUNDS", "TAU_RANGE"]

#: re-pair / refit rounds per candidate at most
MAX_ROUNDS = 3
#: the pairing tolerance follows the refit's misfit (3 robust stds of the paired peaks'
#: relative residual), in these bounds (identify's ``engine.forward.identify.TAU_RANGE``)
TAU_RANGE = (0.003, 0.05)


class Pairing(NamedTuple):
    """Per peak the predicted mode index (-1: unexplained), the in-band modes no peak
    explains, and the pairing penalty (unexplained peaks and skipped modes, chi^2 units)."""

    index: np.ndarray
    skipped: np.ndarray
    penalty: float


def current_selection(F: GapFit) -> np.ndarray | None:
    """Per peak the predicted mode index the residuals of ``F`` use (-1: unexplained);
    None when the pairing is not a fixed one (MAC pairing, no modal data)."""
    fw = F.fw
    n = fw.n_modal
    if not n:
        return None
    sel = getattr(fw, "_selection", None) if isinstance(fw, GapForward) else None
    if sel is not None:
        idx = np.asarray(sel, int).copy()
        if fw.unexplained is not None:
            idx[np.asarray(fw.unexplained, bool)] = -1
        return idx
    if getattr(fw, "pairing", None) == "order":
        return np.arange(n)
    return None


def _predicted(F: GapFit, params: Mapping[str, float], effects: Mapping[str, float], n_solve: int):
    """(corrected frequencies Hz of the n_solve lowest modes under ``effects``, visibility or None)."""
    fw, prob = F.fw, F.problem
    mf = fw.modal_forward_with(dict(effects))
    model = mf.model
    par = temperature_params(params, effects.get("temperature", 0.0))
    modes = model.solve(n_solve, params=dict(par), material=prob.material)
    f = np.asarray(modes.frequencies_hz, float)
    if F.mode_correction is not None:
        f = f * F.mode_correction.at(np.arange(f.size))[0]
    eta = effects.get("viscoelastic", 0.0)
    if eta:
        f = F_REF * (f / F_REF) ** (1.0 / (1.0 - eta / np.pi))
    md = prob.modal
    resp = prob.rig.accelerometers or (md.points if md.points is not None else None)
    vis = visibility(model, modes, resp) if resp is not None and len(resp) else None
    return f, vis


def penalty(index: np.ndarray, f_pred: np.ndarray, visible, y: np.ndarray, tau: float) -> Pairing:
    """The pairing penalty of ``index`` against predictions ``f_pred`` (as
    ``engine.forward.pairing.assign`` counts it): SPURIOUS per unexplained peak, and per
    in-band predicted mode (below the highest peak by more than 3 tau) no peak explains
    MISS x min(1, (v / V_SEEN)^2) (MISS_UNKNOWN without visibility)."""
    index = np.asarray(index, int)
    in_band = np.flatnonzero(f_pred < y.max() * (1.0 - 3.0 * tau))
    skipped = np.array(sorted(set(in_band.tolist()) - set(index[index >= 0].tolist())), int)
    if visible is None:
        miss = MISS_UNKNOWN * skipped.size
    else:
        miss = float(np.sum(MISS * np.minimum(1.0, (np.asarray(visible, float)[skipped] / V_SEEN) ** 2)))
    return Pairing(index, skipped, float(SPURIOUS * np.sum(index < 0) + miss))


def tolerance(F: GapFit, residual: np.ndarray, index: np.ndarray) -> float:
    """Pairing tolerance (relative) from a whitened ``residual``: 3 robust stds of the
    paired peaks' relative misfit, in TAU_RANGE (one wrong pair must not widen it)."""
    n = F.fw.n_modal
    y, sig = F.y[:n], F.sigma[:n]
    paired = np.asarray(index) >= 0
    rel = np.abs(residual[:n][paired] * sig[paired] / y[paired])
    return float(np.clip(3.0 * 1.4826 * np.median(rel), *TAU_RANGE)) if rel.size else TAU_RANGE[1]


def state(F: GapFit, params: Mapping[str, float], effects: Mapping[str, float], residual: np.ndarray,
          index: np.ndarray):
    """(predicted Hz of the lowest modes, their visibility or None, tolerance) at ``params``
    under ``effects``, for pairing the peaks of ``F`` (``index``: the pairing ``residual`` used)."""
    n = F.fw.n_modal
    n_solve = max(n + extra_modes(n), int(np.max(index)) + 2)
    f_pred, vis = _predicted(F, params, effects, n_solve)
    return f_pred, vis, tolerance(F, residual, index)


def most_likely(F: GapFit, f_pred: np.ndarray, visible, tau: float) -> Pairing:
    """The most likely pairing (``engine.forward.pairing.assign``, the features' mode labels
    kept) of the peaks of ``F`` with predictions ``f_pred``."""
    n = F.fw.n_modal
    y, sig = F.y[:n], F.sigma[:n]
    labels = getattr(F.problem.modal, "mode_index", None)
    a = assign(y, sig, f_pred, visible, tau, fixed=labels)
    return penalty(a.index, f_pred, visible, y, tau)


def shape_paired(F: GapFit) -> GapFit | None:
    """``F`` with the peaks paired at every evaluation by their measured shapes (MAC, or
    log-frequency plus 1 - MAC below ``MIN_MAC_POINTS`` points: ``engine.forward.ForwardModel``'s
    rule), or None without measured shapes."""
    md = F.problem.modal
    if md is None or md.shapes is None or md.points is None:
        return None
    fw = F.fw
    fw2 = GapForward(F.problem, safe_order=fw.safe_order, plate_model=fw.base, pairing="order")
    fw2.safe = fw.safe
    return GapFit(F.problem, fw2, F.model_rel_sigma, names=F.names)


def pairing_of(F: GapFit, params: Mapping[str, float], effects: Mapping[str, float]) -> np.ndarray:
    """Per peak the predicted mode index ``F``'s forward model pairs it with at ``params``."""
    par = temperature_params(params, effects.get("temperature", 0.0))
    return np.asarray(F.fw.modal_forward_with(dict(effects)).solve(dict(par)).index, int)


def with_selection(F: GapFit, index: np.ndarray) -> GapFit:
    """``F`` with the peaks paired by ``index`` (per peak a predicted mode, -1: unexplained):
    the same plate model, SAFE solver, corrections and whitening rule."""
    fw = F.fw
    sel = [None if j < 0 else int(j) for j in np.asarray(index, int)]
    fw2 = GapForward(F.problem, safe_order=fw.safe_order, plate_model=fw.base, selection=sel)
    fw2.safe = fw.safe                       # keep the SAFE solver's cache
    model_sigma = None
    if F.mode_correction is not None:
        ratio, err = F.mode_correction.at(index)
        fw2.peak_correction = ratio
        model_sigma = np.concatenate([err * F.y[:fw.n_modal], np.zeros(len(F.y) - fw.n_modal)])
    F2 = GapFit(F.problem, fw2, F.model_rel_sigma, names=F.names, model_sigma=model_sigma)
    F2.mode_correction = F.mode_correction
    return F2
