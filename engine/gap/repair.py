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

from dataclasses import replace
from typing import Mapping, NamedTuple

import numpy as np

from ..forward import F_REF, temperature_params
from ..forward.modal import extra_modes
from ..identify.verdict import MAX_UNEXPLAINED, MAX_UNEXPLAINED_FRACTION
from ..forward.pairing import SPURIOUS, assign, miss_penalties, visibility
from .forward import GapForward
from .refit import Refit, RefitError, refit
from .residuals import GapFit

__all__ = ["Pairing", "current_selection", "state", "tolerance", "most_likely", "with_selection", "shape_paired",
           "pairing_of", "penalty",
           "MAX_ROUNDS", "TAU_RANGE",
           "repaired", "repair_note", "corrected_pairing"]

#: re-pair / refit rounds per candidate at most
MAX_ROUNDS = 3
#: the pairing tolerance follows the refit's misfit (3 robust stds of the paired peaks'
#: relative residual), in these bounds (identify's ``engine.identify.stages.TAU_RANGE``)
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
    sel = fw.selection if isinstance(fw, GapForward) else None
    if sel is not None:
        return np.asarray(sel, int).copy()
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
    miss = float(np.sum(miss_penalties(f_pred, y.max(), visible, tau)[skipped]))
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


def _forward_like(F: GapFit, **pairing) -> GapForward:
    """A GapForward of ``F``'s problem sharing its plate model and SAFE solver (and so the
    latter's cache), paired as ``pairing`` says (``pairing=`` or ``selection=``)."""
    fw = GapForward(F.problem, safe_order=F.fw.safe_order, plate_model=F.fw.base, **pairing)
    fw.safe = F.fw.safe
    return fw


def shape_paired(F: GapFit) -> GapFit | None:
    """``F`` with the peaks paired at every evaluation by their measured shapes (MAC, or
    log-frequency plus 1 - MAC below ``MIN_MAC_POINTS`` points: ``engine.forward.ForwardModel``'s
    rule), or None without measured shapes."""
    md = F.problem.modal
    if md is None or md.shapes is None or md.points is None:
        return None
    return GapFit(F.problem, _forward_like(F, pairing="order"), F.model_rel_sigma, names=F.names)


def pairing_of(F: GapFit, params: Mapping[str, float], effects: Mapping[str, float]) -> np.ndarray:
    """Per peak the predicted mode index ``F``'s forward model pairs it with at ``params``."""
    par = temperature_params(params, effects.get("temperature", 0.0))
    return np.asarray(F.fw.modal_forward_with(dict(effects)).solve(dict(par)).index, int)


def with_selection(F: GapFit, index: np.ndarray) -> GapFit:
    """``F`` with the peaks paired by ``index`` (per peak a predicted mode, -1: unexplained):
    the same plate model, SAFE solver, corrections and whitening rule."""
    fw = F.fw
    fw2 = _forward_like(F, selection=[None if j < 0 else int(j) for j in np.asarray(index, int)])
    model_sigma = None
    if F.mode_correction is not None:
        ratio, err = F.mode_correction.at(index)
        fw2.peak_correction = ratio
        model_sigma = np.concatenate([err * F.y[:fw.n_modal], np.zeros(len(F.y) - fw.n_modal)])
    F2 = GapFit(F.problem, fw2, F.model_rel_sigma, names=F.names, model_sigma=model_sigma)
    F2.mode_correction = F.mode_correction
    return F2


def repaired(name: str, rf: Refit, F: GapFit, w: np.ndarray, theta_prior: np.ndarray, fl, max_nfev: int,
             proposals=(), a_start: float | None = None) -> Refit:
    """The refit of effect ``name`` with the peaks re-paired under the effect
    (:mod:`engine.gap.repair`). Pairings tried: each of ``proposals`` (per peak a mode
    index, -1 unexplained; refitted from the pairing check's constants and ``a_start``),
    then, while it changes, the most likely pairing at the best refit so far under the
    effect; one is kept when its chi^2 plus pairing penalty (evaluated at its own refit)
    is lower. The returned refit carries the pairing it used (``selection``) and the
    penalty that change added (>= 0)."""
    current = current_selection(F)
    if current is None:
        return rf

    def pen(Fx: GapFit, r: Refit, idx: np.ndarray) -> float:
        eff = {name: r.magnitude}
        f_pred, vis, tau = state(Fx, r.constants, eff, r.residual, idx)
        return penalty(idx, f_pred, vis, Fx.y[:Fx.fw.n_modal], tau).penalty

    try:
        pen0 = cur_pen = pen(F, rf, current)
    except (ValueError, np.linalg.LinAlgError):
        return rf
    best, Fc, cur = rf, F, current
    tried = {tuple(current.tolist())}
    queue = [(idx if isinstance(idx, str) else np.asarray(idx, int), theta, a_start) for idx, theta in proposals]
    for _ in range(MAX_ROUNDS + len(queue)):
        if queue:
            idx, theta, a0 = queue.pop(0)
            if isinstance(idx, str):       # "shapes": refit paired by the measured shapes, keep its pairing
                Fs = shape_paired(F)
                if Fs is None:
                    continue
                try:
                    rs = refit(name, a_start if a_start is not None else rf.magnitude, Fs, theta, w, theta_prior,
                               fl, max_nfev)
                    idx = pairing_of(Fs, rs.constants, {name: rs.magnitude})
                except (RefitError, ValueError, np.linalg.LinAlgError):
                    continue
                theta, a0 = np.log([rs.constants[n_] for n_ in F.names]), rs.magnitude
        else:
            try:
                f_pred, vis, tau = state(Fc, best.constants, {name: best.magnitude}, best.residual, cur)
                idx = most_likely(Fc, f_pred, vis, tau).index
            except (ValueError, np.linalg.LinAlgError):
                break
            theta, a0 = np.log([best.constants[n_] for n_ in F.names]), best.magnitude
        n_un = int(np.sum(idx < 0))
        if tuple(idx.tolist()) in tried or n_un > max(MAX_UNEXPLAINED, MAX_UNEXPLAINED_FRACTION * idx.size):
            if queue:
                continue
            break
        tried.add(tuple(idx.tolist()))
        F2 = with_selection(F, idx)
        try:
            rf2 = refit(name, best.magnitude if a0 is None else a0, F2, theta, w, theta_prior, fl, max_nfev)
            pen2 = pen(F2, rf2, idx)
        except (RefitError, ValueError, np.linalg.LinAlgError):
            continue
        if rf2.chi2 + pen2 < best.chi2 + cur_pen:
            best, Fc, cur, cur_pen = rf2, F2, idx, pen2
        elif not queue:
            break
    if best is rf:
        return rf
    return replace(best, selection=tuple(int(j) for j in cur), penalty=max(0.0, cur_pen - pen0))


def repair_note(effect: str, before, after, y) -> str:
    """One line: how the peaks pair under ``effect`` where that differs from the start's pairing."""
    diff = []
    for i, (a, b) in enumerate(zip(before, after)):
        if a != b:
            was = "no mode" if a < 0 else f"mode {a + 1}"
            now = "no mode (set aside)" if b < 0 else f"mode {b + 1}"
            diff.append(f"peak {i + 1} ({y[i]:.1f} Hz) {was} -> {now}")
    return f"under {effect} the peaks pair differently from the start: " + "; ".join(diff)


def corrected_pairing(F: GapFit, params: Mapping[str, float]) -> GapFit | None:
    """``F`` re-paired at ``params`` by the most likely pairing with the *corrected* predicted
    frequencies (``F.mode_correction``: the discretisation correction at the estimate), when that
    differs from ``F``'s pairing and explains the peaks better (chi^2 plus pairing penalty, both
    at ``params``); None otherwise. The correction moves close modes past each other (their
    coarse-mesh order is not their true order), so the order-based or nominal-correction
    pairing identify used can pair two peaks crosswise (issue 28)."""
    current = current_selection(F)
    if current is None or F.mode_correction is None:
        return None
    try:
        r0 = F.residual(params, {})
        f_pred, vis, tau = state(F, params, {}, r0, current)
        new = most_likely(F, f_pred, vis, tau)
    except (ValueError, np.linalg.LinAlgError):
        return None
    n_un = int(np.sum(new.index < 0))
    if np.array_equal(new.index, current) or n_un > max(MAX_UNEXPLAINED, MAX_UNEXPLAINED_FRACTION * new.index.size):
        return None
    F2 = with_selection(F, new.index)
    try:
        r2 = F2.residual(params, {})
    except ValueError:
        return None
    y = F.y[:F.fw.n_modal]
    old_cost = float(r0 @ r0) + penalty(current, f_pred, vis, y, tau).penalty
    return F2 if float(r2 @ r2) + new.penalty < old_cost and float(r2 @ r2) <= float(r0 @ r0) else None
