"""Sim-to-real gap diagnosis: is there a gap, where, which unmodelled effect, how far it shrinks.

Procedure (:func:`diagnose`), on features whitened by their sigmas (plus a small
model-discretisation allowance, ``GapOptions.model_rel_sigma``):

1. The constants are those ``labid identify`` estimated (a :class:`StartEstimate`:
   same parameters, prior, pairing; engine-only callers get
   :func:`~engine.gap.start.own_estimate`, the same estimator); chi^2 of the
   whitened residuals against the chi^2 law on the degrees of freedom left
   (n minus the trace of the hat matrix, :func:`gap_test`): a gap is declared
   when the p-value is below ``alpha`` (the false-alarm rate on clean data).
   With a gap and modes paired by order, :mod:`engine.gap.pairing` checks
   whether re-pairing explains it (verdict ``pairing``).
2. Where: chi^2 split by modality, mode, mode family (from the predicted mode
   shapes), frequency band, wave mode and direction (:mod:`engine.gap.where`).
   Without a gap only the effects that need no new plate model are screened
   (their ``undetectable`` report, e.g. the temperature bias, is kept).
   With no more independent features than the constants plus one effect
   parameter the verdict is ``insufficient_data`` (with what to add) and no
   effect is tried (:func:`engine.gap.verdict.insufficient`).
2. Where: chi^2 split by modality, mode, mode family (from the predicted mode
   shapes), frequency band, wave mode and direction (:mod:`engine.gap.where`).
3. Which: every candidate effect is screened (:mod:`engine.gap.candidates`:
   signature, what the constants absorb, detectability; with a gap, a quadratic
   screen so that second-order effects are judged by their shape); every
   detectable candidate whose screen is not conclusively worse (``skip_dchi2``
   behind an accepted refit) is refitted jointly with the constants
   (:mod:`engine.gap.refit`; at most ``max_refits``), and so is the known
   look-alike partner of the best one if only the cap left it out; ranked by chi^2 (equal parameter count,
   so by BIC too). The held-out gap (two interleaved folds of modes and of wave
   bands, linearised about the fit) is reported.
4. Verdict (:mod:`engine.gap.verdict`): ``none`` without a significant gap;
   ``pairing`` when re-pairing the peaks passes the test and beats every
   effect; the best effect when it passes the chi^2 test (p > ``accept_alpha``)
   and beats "no effect" by BIC; otherwise ``unattributed``. Accepted effects
   whose chi^2 is within ``confusable_dchi2`` of the best form its confusable
   group, with what would separate them.

Gap figures are rms whitened residuals (1 = noise level). :func:`diagnose`
returns a frozen :class:`GapResult`; ``GapResult.to_dict()`` is the JSON of
``labid diagnose`` (CONTRACT section 3 keys first).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..features import Features
from ..fit import Prior, estimate
from ..fit.chisq import chi2_isf, chi2_sf
from ..forward import EFFECTS, ForwardModel
from ..forward.effects import ANGLE_EFFECTS, LOOKALIKES, PLATE_EFFECTS
from ..identify.verdict import MAX_UNEXPLAINED, MAX_UNEXPLAINED_FRACTION
from .candidates import Candidate, applies, screen
from .convergence import REBUILD, peak_corrections, under_effect
from .forward import GapForward
from .pairing import pairing_check
from .refit import RefitError, refit
from .repair import corrected_pairing, current_selection, repair_note, repaired
from .residuals import GapError, GapFit
from .result import (ConfusableGroup, ConstantsChange, FeatureResiduals, GapFigures, GapResult, RankedEffect,
                     Undetectable)
from .start import StartEstimate, identify_pairing, own_estimate
from .verdict import accepted, decide, group, insufficient, ranking
from .where import feature_labels, folds, group_table, groups, held_out, mode_families

__all__ = ["GapOptions", "GapResult", "GapFigures", "RankedEffect", "Undetectable", "ConstantsChange",
           "FeatureResiduals", "ConfusableGroup", "diagnose", "gap_test"]


@dataclass(frozen=True)
class GapOptions:
    """Tuning of the diagnosis (see module docstring)."""

    alpha: float = 0.01
    accept_alpha: float = 0.001
    model_rel_sigma: tuple[float, float] = (1.5e-4, 2e-4)   # (modal, waves) relative
    detect_sigma: float = 3.0
    max_refits: int = 5              # candidates refitted at most (the look-alike partner besides)
    confusable_dchi2: float = 4.0
    skip_dchi2: float = 25.0         # screened chi^2 this far above an accepted refit's: not refitted
    candidates: tuple[str, ...] = tuple(EFFECTS)
    max_nfev: int = 30
    discretisation: bool = True      # per-mode FE error from a second, finer mesh in the whitening


def gap_test(r: np.ndarray, J: np.ndarray, w: np.ndarray, alpha: float) -> dict:
    """Chi^2 test of whitened residuals r of a (prior-regularised) least-squares fit.

    J: whitened Jacobian (n, k) at the fit; w: prior sqrt-precisions (k,).
    Degrees of freedom n - trace(H), H = J (J'J + diag(w^2))^-1 J'; a gap is
    significant when P(chi^2_dof >= r'r) < alpha (the false-alarm rate).
    """
    r = np.asarray(r, float)
    n = len(r)
    A = J.T @ J + np.diag(np.asarray(w, float) ** 2)
    # pinv: a constant no residual constrains (e.g. every peak set aside) leaves A singular
    dof = max(n - float(np.trace(J @ np.linalg.pinv(A) @ J.T)), 1.0)
    chi = float(r @ r)
    p = float(chi2_sf(chi, dof))
    return {"chi2": chi, "dof": dof, "p_value": p, "threshold": float(chi2_isf(alpha, dof)), "alpha": alpha,
            "significant": bool(p < alpha)}


# ------------------------------------------------------------------ steps --
@dataclass(frozen=True)
class _ConstantsFit:
    """Step 1: the start estimate (identify's) and the gap test there."""

    start: StartEstimate
    p_hat: dict[str, float]
    w: np.ndarray            # prior sqrt-weights (log constants); zeros: maximum likelihood
    theta_prior: np.ndarray  # log prior mean (log start when no prior)
    J: np.ndarray            # whitened Jacobian (log constants) at p_hat
    r0: np.ndarray           # whitened residual at p_hat
    test: dict

    @property
    def theta(self) -> np.ndarray:
        return np.log([self.p_hat[n] for n in self.start.names])

    @property
    def dtheta(self) -> np.ndarray:
        return self.theta - self.theta_prior


def _check(problem: Features, opts: GapOptions) -> None:
    if problem.modal is None and not problem.waves:
        raise GapError("features hold neither modal frequencies nor wave group velocities")
    if problem.waves and not problem.rig.wave_path_m:
        raise GapError("waves given without rig.wave_path_m (needed for timing/path effects)")
    unknown = set(opts.candidates) - set(EFFECTS)
    if unknown:
        raise GapError(f"candidates {sorted(unknown)}: expected names from {list(EFFECTS)}")


def _base(F: GapFit, start: StartEstimate, opts: GapOptions) -> _ConstantsFit:
    names = start.names
    p_hat = {n: float(start.params[n]) for n in names}
    k = len(names)
    w = np.full(k, 0.0 if start.prior_rel_std is None else 1.0 / start.prior_rel_std)
    mean = start.prior_mean or p_hat
    theta_prior = np.log([mean.get(n, p_hat[n]) for n in names])
    try:
        J = F.jacobian(p_hat, {})
        r0 = F.residual(p_hat, {})
    except ValueError as exc:
        raise GapError(f"the start estimate cannot be evaluated ({exc})") from None
    return _ConstantsFit(start, p_hat, w, theta_prior, J, r0, gap_test(r0, J, w, opts.alpha))


def _families(problem: Features, fw: ForwardModel, p_hat) -> list[str] | None:
    if problem.modal is None:
        return None
    try:
        return mode_families(fw, p_hat)
    except Exception:  # noqa: BLE001 - families are descriptive only
        return None


def _corrected_pairing(F: GapFit, start: StartEstimate) -> tuple[GapFit, StartEstimate, str]:
    """(F, start, note): when the discretisation correction at the estimate moves close modes
    past each other so that the peaks pair better crosswise (:func:`engine.gap.repair.corrected_pairing`),
    ``F`` re-paired and the constants refitted locally from identify's estimate (the same
    estimator, prior about identify's start); else unchanged with an empty note."""
    F2 = corrected_pairing(F, start.params)
    if F2 is None:
        return F, start, ""
    prior = None if start.prior_rel_std is None else Prior(
        mean={n: start.prior_mean.get(n, start.params[n]) for n in start.names},
        rel_std={n: start.prior_rel_std for n in start.names})
    try:
        est = estimate(F2.blocks(), start.names, dict(start.params), prior=prior, max_iter=30)
    except (np.linalg.LinAlgError, ValueError):
        return F, start, ""
    if not np.all(np.isfinite(est.values)):
        return F, start, ""
    before, after = current_selection(F), current_selection(F2)
    moved = [f"peak {i + 1} mode {a + 1} -> {b + 1}" for i, (a, b) in enumerate(zip(before, after)) if a != b]
    st = replace(start, params=dict(est.params), std={n: float(v) for n, v in zip(start.names, est.std)},
                 mode_index=tuple(None if j < 0 else int(j) for j in after), pairing="identify")
    return F2, st, ("the discretisation correction at the estimate reorders close modes; the peaks are "
                    "paired by the corrected frequencies (" + "; ".join(moved) + ") and the constants "
                    "refitted from identify's estimate")


def _refit_one(c: Candidate, F: GapFit, base: _ConstantsFit, fl, opts: GapOptions, proposals) -> Candidate:
    """Candidate ``c`` refitted jointly with the constants (from identify's estimate and, when
    that is doubtful, from identify's start too), the peaks re-paired under it."""
    dof = max(base.test["dof"] - 1, 1)
    try:
        rf = refit(c.name, c.magnitude_linear, F, base.theta, base.w, base.theta_prior, fl, opts.max_nfev)
        far = bool(np.any(np.abs(base.theta - base.theta_prior) > math.log(1.5)))
        if (far or not rf.converged or chi2_sf(rf.chi2, dof) < opts.accept_alpha) \
                and np.any(base.theta_prior != base.theta):
            # second start: identify's start values (its estimate may sit in a minimum the
            # effect made: a constant > 1.5x from its start, or a refit not converged / rejected)
            try:
                rf2 = refit(c.name, c.magnitude_linear, F, base.theta_prior, base.w, base.theta_prior, fl,
                            opts.max_nfev)
                rf = rf2 if rf2.chi2 < rf.chi2 else rf
            except RefitError:
                pass
        rf = repaired(c.name, rf, F, base.w, base.theta_prior, fl, opts.max_nfev, proposals, c.magnitude_linear)
        if chi2_sf(rf.chi2, dof) < opts.accept_alpha and rf.chi2 < 0.5 * base.test["chi2"]:
            # explains much of the gap but fails the test: the mesh correction under the effect?
            nm = F.fw.n_modal
            tol = 0.2 * float(np.min(F.sigma_measured[:nm] / F.y[:nm])) if nm else 0.0
            rf = under_effect(c.name, rf, F, base.w, base.theta_prior, fl, opts.max_nfev, tol)
        return replace(c, refit=rf)
    except RefitError as exc:
        return replace(c, error=str(exc))


def _screen_and_refit(problem: Features, F: GapFit, base: _ConstantsFit, fl, opts: GapOptions,
                      progress: Callable[[str, int, int], None] | None, proposals=()) -> list[Candidate]:
    """Every applicable candidate screened (quadratic screen when there is a gap); every
    detectable one whose screen is not conclusively worse than an accepted refit refitted (at
    most ``max_refits``), then the look-alike partner of the best if the cap left it out; the
    peaks re-paired under each (``proposals``: pairings to try too, with their constants; see
    :func:`engine.gap.repair.repaired`); ``progress(stage, done, total)`` after each step."""
    Ja = np.vstack([base.J, np.diag(base.w)])     # augmented Jacobian for projections (prior rows)
    names = [n for n in opts.candidates if applies(n, problem)
             and (n not in PLATE_EFFECTS or hasattr(F.fw, "modal_forward_with"))
             and (n not in ANGLE_EFFECTS or not problem.material_obj.isotropic)
             # one ply: its "top ply" turned is the whole layup turned, the same effect as a
             # misalignment (a one-ply wood-like Ritz plate turned 3.4 deg was named ply_angle_error
             # and its misalignment screened out by the two quadratic screens' different points)
             and not (n == "ply_angle_error" and len(problem.laminate.plies) == 1)]
    gap = bool(base.test["significant"])
    if not gap:         # nothing to attribute: only the effects screened without a new plate model
        names = [n for n in names if n not in REBUILD]   # (measured, 10 CFRP modes, E1, E2, G12:
        # ~1 s of a 3.7 s diagnosis; temperature, viscoelastic, the wave effects still report
        # what the constants would absorb)
    total = len(names) + (min(opts.max_refits, len(names)) if gap else 0)
    cands = []
    for i, name in enumerate(names):
        cands.append(screen(name, F, base.p_hat, base.r0, Ja, F.names, opts.detect_sigma, quadratic=gap))
        if progress:
            progress("screen", i + 1, total)
    if not gap:
        return cands         # no gap: nothing to attribute (the screen still reports undetectable effects)
    ranked = sorted([c for c in cands if c.error is None and c.detectable], key=lambda c: c.chi2_linear)
    done: dict[str, Candidate] = {}
    best_ok = math.inf      # chi^2 of the best accepted refit so far
    for c in ranked:
        if len(done) >= opts.max_refits:
            break
        if c.chi2_linear > best_ok + opts.skip_dchi2:
            continue            # conclusively behind an accepted refit even in the screen: not refitted
        done[c.name] = _refit_one(c, F, base, fl, opts, proposals)
        if accepted(done[c.name], base.test, opts.accept_alpha):
            best_ok = min(best_ok, done[c.name].chi2)
        if progress:
            progress("refit", len(names) + len(done), total)
    ok = sorted([c for c in done.values() if accepted(c, base.test, opts.accept_alpha)], key=lambda c: c.cost)
    if ok:              # the best one's look-alike partners left out by the cap, so that a group is measured
        by_name = {c.name: c for c in ranked}
        for pair in LOOKALIKES:
            if ok[0].name in pair:
                other = next(iter(pair - {ok[0].name}))
                if other in by_name and other not in done and by_name[other].chi2_linear <= best_ok + opts.skip_dchi2:
                    done[other] = _refit_one(by_name[other], F, base, fl, opts, proposals)
    return [done.get(c.name, c) for c in cands]


# -------------------------------------------------------------- diagnosis --
def diagnose(problem: Features, options: GapOptions | None = None,
             forward: ForwardModel | None = None, start: StartEstimate | None = None,
             progress: Callable[[str, int, int], None] | None = None) -> GapResult:
    """Gap diagnosis of measured features at a start estimate (see module docstring).

    ``start``: the estimate ``labid identify`` reports (``labid.workflows.diagnosis.start_estimate``);
    None: :func:`engine.gap.start.own_estimate` (identify's default estimator).
    ``forward`` replaces the default forward model of ``problem`` (e.g. another
    mesh; a :class:`~engine.gap.forward.GapForward` for the real-plate effects).
    ``progress(stage, done, total)`` is called after each candidate screened / refitted.
    """
    opts = options or GapOptions()
    _check(problem, opts)
    pairing = start.pairing if start is not None else identify_pairing(problem.modal)
    selection = start.mode_index if start is not None else None
    pre_notes, n_un = [], 0 if selection is None else sum(j is None for j in selection)
    if selection is not None and n_un > max(MAX_UNEXPLAINED, MAX_UNEXPLAINED_FRACTION * len(selection)):
        # identify's fit set most peaks aside (an unmodelled effect can make explaining
        # nothing its cheapest pairing): judging only the peaks it kept would hide the gap
        pre_notes.append(f"identify's pairing set {n_un} of {len(selection)} peaks aside (its fit is "
                         "inconsistent); the diagnosis pairs every peak, in frequency order first, and "
                         "re-pairs under each candidate effect")
        selection, pairing = None, "order"
    fw = forward or GapForward(problem, pairing=None if selection is not None else pairing, selection=selection)
    names = start.names if start is not None else None
    F0 = GapFit(problem, fw, opts.model_rel_sigma, names=names)
    if start is None:
        start = own_estimate(F0)
    model_sigma, notes = None, pre_notes
    if opts.discretisation and fw.n_modal and forward is None:
        try:
            md = problem.modal
            tol = 0.2 * float(np.min(np.asarray(md.sigma_hz, float) / np.asarray(md.frequency_hz, float)))
            ratio, d, note, per_mode, reordered = peak_corrections(fw, start.params, tol=tol)
            fw.peak_correction = ratio          # the identification's correction: same residuals
            model_sigma = np.concatenate([d, np.zeros(len(F0.y) - fw.n_modal)])
            notes.append(note)
        except Exception as exc:  # noqa: BLE001 - the allowance falls back to the constant one
            notes.append(f"discretisation error not estimated ({exc}); constant model allowance only")
    F = GapFit(problem, fw, opts.model_rel_sigma, names=start.names, model_sigma=model_sigma)
    if model_sigma is not None:
        F.mode_correction = per_mode
        if reordered:
            F, start, note = _corrected_pairing(F, start)
            if note:
                notes.append(note)
                fw = F.fw
    base = _base(F, start, opts)
    r0, test = base.r0, base.test
    n, chi0 = len(r0), test["chi2"]

    labels = feature_labels(problem)
    families = _families(problem, fw, base.p_hat)
    table0 = group_table(r0, groups(labels, families), opts.alpha)
    fl = folds(labels)
    ho0 = held_out(r0, base.J, base.w, base.dtheta, fl)

    pair = None
    if test["significant"] and fw.n_modal and pairing == "order" and selection is None:
        pair = pairing_check(F, base.p_hat, r0, opts.alpha, test["dof"])
    proposals = []
    if pair is not None:       # the pairing check's pairing, with an effect on top
        proposals.append((np.array([-1 if j is None else int(j) for j in pair.proposed]),
                          np.log([pair.constants[n_] for n_ in F.names])))
    if selection is not None and problem.modal is not None and problem.modal.shapes is not None:
        # the measured shapes (even at 3 accelerometers) pair the peaks at every evaluation of
        # a refit. Measured (panel session test: simulated 5 g at each of 3 accelerometers, 7 peaks):
        # identify's pairing alone 'unattributed' (gap 68 -> 38 at 2.9 g); frequency order alone
        # worse (chi^2 1.8e6); shape-paired, then fixed: 'sensor_mass' 4.99 g, gap 68 -> 0.24
        proposals.append(("shapes", base.theta))
    advice = insufficient(problem, n - (0 if F.unexplained is None else int(np.sum(F.unexplained))), F.names)
    if advice:        # nothing left to judge a gap with: no candidate is tried
        cands, refitted, verdict, p_best, pair = [], [], "insufficient_data", None, None
        notes.append(advice[0])
    else:
        cands = _screen_and_refit(problem, F, base, fl, opts, progress, proposals)
        refitted = sorted([c for c in cands if c.refit is not None], key=lambda c: c.cost)
        verdict, p_best = decide(refitted, test, n, opts.accept_alpha)
        if pair is not None and pair.explains and (verdict == "unattributed" or (
                refitted and pair.chi2 < refitted[0].cost)):
            verdict, p_best = "pairing", pair.p_value
    grp = group(verdict, refitted, test, opts.accept_alpha, opts.confusable_dchi2)
    chosen = next((c.refit for c in refitted if c.name == verdict), None)
    pairing_used = "identify" if selection is not None else pairing
    if chosen is not None and chosen.selection is not None:
        pairing_used = f"re-paired under {verdict}"
        notes.append(repair_note(verdict, current_selection(F), chosen.selection, F.y[:fw.n_modal]))

    after_r = chosen.residual if chosen is not None else (pair.residual if verdict == "pairing" else r0)
    p_hat, names = base.p_hat, F.names
    gap = GapFigures(
        before=float(math.sqrt(chi0 / n)), after=float(math.sqrt(float(after_r @ after_r) / n)),
        held_out_before=ho0, held_out_after=chosen.held_out_after if chosen is not None else ho0,
        chi2_before=chi0, chi2_after=float(after_r @ after_r), dof=float(test["dof"]), n=n,
        p_value_before=test["p_value"], p_value_after=p_best if p_best is not None else test["p_value"],
        threshold_chi2=test["threshold"], false_alarm_rate=opts.alpha, significant=bool(test["significant"]))
    where = [g for g in table0 if g.significant] if test["significant"] else []
    where_names = tuple(g.group for g in where)
    if pair is not None and pair.findings:
        where_names = tuple(pair.findings) + where_names
    after_constants = chosen.constants if chosen is not None else (
        pair.constants if verdict == "pairing" else p_hat)
    before_std = {n_: float(start.std.get(n_, float("nan"))) for n_ in names}
    ranked = ranking(cands, chi0, n, p_hat, before_std)
    notes += [f"under {verdict}: {f}" for e in ranked if e.name == verdict for f in e.flags]
    return GapResult(
        gap=gap,
        where=where_names,
        where_detail=tuple(where),
        effects=tuple(ranked),
        verdict=verdict,
        confusable=grp.effects if grp is not None and len(grp.effects) > 1 else (),
        undetectable=tuple(Undetectable(c.name, float(c.absorbed_fraction), c.unit, c.bias_per_unit)
                           for c in cands if c.error is None and not c.detectable),
        errors={c.name: c.error for c in cands if c.error is not None},
        groups=tuple(table0),
        constants=ConstantsChange(
            before=p_hat, before_std=before_std,
            after=after_constants,
            relative_change={n_: after_constants[n_] / p_hat[n_] - 1.0 for n_ in names}),
        features=FeatureResiduals(
            labels=tuple(lb["label"] for lb in labels), modality=tuple(lb["modality"] for lb in labels),
            set=tuple(lb["set"] for lb in labels), residual_before=r0, residual_after=after_r,
            sigma=F.sigma, mode_families=None if families is None else tuple(families)),
        converged=bool(start.converged), message=start.message,
        start=start, pairing=None if pair is None else pair.to_dict(),
        model_sigma=None if model_sigma is None else model_sigma[:fw.n_modal], notes=tuple(notes),
        pairing_used=pairing_used, confusable_groups=() if grp is None else (grp,), advice=advice)
