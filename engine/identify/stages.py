"""The identification's fit over data blocks, with its stages and its verdict (issue 12).

:func:`fit_blocks` is the estimator the workflow (``labid.workflows.identification.estimation.run``) and the gap
diagnosis call, on the blocks of ``engine.identify.blocks.feature_blocks``:

1. the blocks (``modal_block`` with the discretisation correction of
   ``engine.plate.convergence`` and likelihood pairing; ``wave_block``), kept in the fit's
   box (:func:`bounds`: moduli within BOX x nominal, Poisson ratios in (0, 1); the
   positive-definite stiffness is checked by the forward models);
2. with likelihood pairing, a cheap global stage (:func:`global_starts`,
   ``engine.identify.surrogate``) gives up to N_GLOBAL_FITS starts; each is moved to the
   surrogate's own minimum over every fitted elastic constant (``refine``), then fitted with
   re-pairing between local fits (:func:`_repair_loop`, oscillation guarded) until one
   is consistent; the most likely is kept;
3. Birge refit and data-set consistency (``engine.fit.checks``);
4. the verdict (:func:`verdict`): chi2, dof, p-value, consistent, std scaled by
   sqrt(chi2/nu) when > 1, flags (runaway > RUNAWAY x nominal, at the box or the
   admissible edge), identified; and the pairing report (:func:`pairing_report`).

Units SI.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import replace
from typing import Callable, Mapping, Sequence

import numpy as np

from ..fit import (DataBlock, Estimate, IdentificationError, Prior, bayesian_update, checks, estimate,
                   laplace, nelder_mead_fit, whitened_jacobian)
from ..fit.estimators import STOP_CHI2
from ..fit.lm import STALLED
from ..laminate import PhysicsError
from ..plate import PlateModel, mode_families
from ..plate.convergence import FINE_FACTOR, ORDER, finer_mesh, mode_corrections
from ..forward.pairing import MISS, MISS_UNKNOWN, SPURIOUS, visibility
from .surrogate import RitzSurrogate, global_search, refine
from .verdict import BOX, POISSON_MAX, RUNAWAY, FitContext, admissibility, bounds, boxed, systematic, verdict

__all__ = ["FitContext", "fit_blocks", "verdict", "admissibility", "bounds", "boxed",
           "global_starts", "pairing_report", "discretisation", "RUNAWAY", "BOX",
           "POISSON_MAX", "N_GLOBAL_FITS", "MAX_REPAIR", "TAU_RANGE", "N_EXTRA_MODES", "identifiable",
           "HOLD_REL", "HELD_PRIOR", "systematic"]

METHODS = ("lm", "bayes", "nelder-mead")
#: predicted modes beyond the measured count (at least; corrections, pairing with missing modes)
N_EXTRA_MODES = 4


def fit_blocks(ctx: FitContext, blocks: Sequence[DataBlock], names: Sequence[str], start: Mapping[str, float],
               *, method: str = "lm", prior: float | Prior | None = None, max_iter: int = 60,
               scale_sigmas: bool = True, consistency: bool = True, global_stage: bool = True,
               notes: Sequence[str] = (), on_error: Callable[[Exception], Exception] = lambda e: e,
               held: Mapping[str, tuple[float, str]] | None = None) -> Estimate:
    """The estimate of ``names`` from ``start`` (every name given) with the stages of the
    module docstring; ``notes`` are prepended to the warnings; ``on_error`` maps an
    ``IdentificationError`` to the exception raised (the workflow's UserError).
    ``held``: {name: (value, reason)} constants the data hardly constrain: fitted too,
    under a weak prior (log-std HELD_PRIOR) centred on ``value``, so that their
    uncertainty widens the others' stds; never reported as identified (``held``)."""
    held = dict(held or {})
    names = tuple(names) + tuple(h for h in held if h not in names)
    st = {**{h: v for h, (v, _) in held.items()}, **dict(start)}
    if held:
        base = prior if isinstance(prior, (int, float)) else None
        if isinstance(prior, Prior):
            raise IdentificationError("held constants need a numeric prior (or none)")
        prior = Prior(mean=dict(st), rel_std={n: (HELD_PRIOR if n in held else base) for n in names})
    if ctx.modal_forward is not None:
        ctx.modal_forward.reset_tracking()
    fixed = {h: v for h, (v, _) in held.items()}
    blocks = boxed(ctx, blocks)

    def fit(start_: Mapping[str, float], give_up: float | None = None) -> Estimate:
        try:
            if method == "lm":
                return estimate(blocks, names, start_, prior=prior, max_iter=max_iter, give_up=give_up,
                                dtol=STOP_CHI2)
            if method == "bayes":
                return bayesian_update(blocks, names, start_,
                                       prior_rel_std=0.5 if prior is None else prior, max_iter=max_iter)
            return nelder_mead_fit(blocks, names, start_, prior=prior)
        except IdentificationError as e:
            raise on_error(e) from None

    fwd = ctx.modal_forward
    like = fwd is not None and getattr(fwd, "likelihood_pairing", False)
    pair_notes: list[str] = []
    starts, ranked, prepare = [st], [], dict
    if like and global_stage:          # every method: the Lai-Ip update needs a good start as much
        starts, note, ranked, prepare = global_starts(ctx, names, st, fixed)
        pair_notes.append(note)
    def fit_paired(start_: Mapping[str, float], give_up: float | None = None, assignment=None) -> Estimate:
        """A fit from ``start_``, with its own likelihood pairing (re-paired until it stands);
        ``assignment``: the pairing to start from (default: paired afresh at ``start_``)."""
        if not like:
            return fit(start_, give_up)
        if assignment is None:
            fwd.reset_pairing()
        else:
            fwd.repair_fixed_assignment(assignment)
        fit_ = (lambda s_: fit(s_, give_up)) if give_up is not None else fit
        e_, notes_ = _repair_loop(ctx, fit_(start_), fit_, st)
        return replace(e_, fit={"assignment": fwd.assignment, "notes": notes_})

    # several candidate starts: a descent that stalls far above an acceptable chi^2 is ended
    # early (engine.fit.lm.STALLED) and the next candidate tried; it is resumed only when it
    # is kept (no candidate fits)
    n_pts = sum(b.observed.size for b in blocks)
    give_up = GIVE_UP * (n_pts + 3.0 * math.sqrt(2.0 * n_pts)) if method == "lm" and len(starts) > 1 else None
    tried: list[Estimate] = []
    modal_only = all(b.kind == "modal" for b in blocks)
    for k, s0 in enumerate(starts):
        # the given start is refined only when the data are modal alone: the surrogate sees the
        # modes only, and on the demo's combined features it moved the nominal start's G13, G23
        # (which the waves fix) from a cost of 4.6 to 139 (2 more solves)
        if modal_only or any(s0[n] != st[n] for n in names):
            s0 = prepare(s0)
        try:
            e = fit_paired(s0, give_up)
        except ValueError:   # a candidate start outside the admissible region: the next one
            if k < len(starts) - 1 or tried:
                continue
            raise
        tried.append(e)
        if _fits(e):                  # consistent enough: stop
            break
    short = like and np.size(fwd.observed) <= RIVAL_MAX_PEAKS
    rival = _rival_start(tried[-1], ranked, ctx) if short and tried and _fits(tried[-1]) else None
    if rival is not None:
        # the best-ranked global-stage candidate in another basin: a second minimum that fits
        # as well makes the constants it moves ambiguous. Measured on real data (Badiane et
        # al.'s spruce plate 9, 8 peaks): E2 0.98 GPa from a generic start, 0.51 GPa from the
        # authors' values, both consistent; the first was reported with a 1.7 % std
        try:
            tried.append(fit_paired(rival))
        except ValueError:
            pass
    i = min(range(len(tried)), key=lambda j: _penalised(tried[j]))
    est = tried[i]                    # by position: Estimates hold arrays (== is no identity test)
    if est.message == STALLED:        # kept although stalled: fitted to the end from where it stopped
        e = fit_paired(est.params, assignment=est.fit["assignment"] if like else None)
        tried[i] = est = replace(e, iterations=est.iterations + e.iterations, history=est.history + e.history,
                                 seconds=est.seconds + e.seconds)
    ambiguous = _ambiguity(est, tried)
    if like:
        fwd.repair_fixed_assignment(est.fit["assignment"])
        pair_notes += est.fit["notes"]
        est = replace(est, fit=None, start=dict(st), iterations=sum(e.iterations for e in tried),
                      seconds=sum(e.seconds for e in tried))
        if len(tried) > 1:
            pair_notes.append(f"global stage: {len(tried)} candidate starts fitted; kept the most likely")
    scale_notes: list[str] = []
    if scale_sigmas and method == "lm":
        est, scale_notes = checks.birge_refit(blocks, est, names, st, prior, max_iter)
    if consistency and method == "lm" and len({b.kind for b in blocks}) > 1:
        scale_notes += checks.consistency(blocks, est, names, prior, max_iter)
    warnings = list(est.warnings) + list(notes) + pair_notes + scale_notes
    est, sys_note = systematic(ctx, est)
    est, verdict_notes = verdict(ctx, est, scale_sigmas=scale_sigmas, extra_flags=ambiguous)
    verdict_notes = sys_note + verdict_notes
    warnings += verdict_notes
    if like:
        est = replace(est, fit={**est.fit, **pairing_report(ctx, est.params)})
    if ctx.modal_forward is not None:
        warnings += ctx.modal_forward.warnings
    if held:
        ident = dict(est.identifiability)
        params = dict(ident["parameters"])
        for h, (v, why) in held.items():
            params[h] = {**params[h], "identified": False,
                         "reason": f"held at {v:.4g} under a weak prior (log-std {HELD_PRIOR:g}): {why}"}
        ident["parameters"] = params
        ident["poorly_identified"] = [n for n in names if not params[n]["identified"]]
        fit_ = {**est.fit, "identified": False if len(held) == len(names) else est.fit["identified"],
                "held": {h: {"value": float(v), "reason": why} for h, (v, why) in held.items()}}
        fit_["identified"] = bool(fit_["consistent"] and all(params[n]["identified"] for n in names
                                                             if n not in held) and not fit_["flags"])
        est = replace(est, identifiability=ident, fit=fit_)
        warnings.append("held under a weak prior (not identified): "
                        + ", ".join(f"{k} ({why})" for k, (_, why) in held.items()))
    return replace(est, warnings=tuple(warnings))


#: log-std of the weak prior a held constant is fitted under
HELD_PRIOR = 0.3


#: relative std (Laplace, at the start, no prior) above which a default constant is held
HOLD_REL = 0.3


def identifiable(blocks: Sequence[DataBlock], names: Sequence[str], start: Mapping[str, float],
                 hold_rel: float = HOLD_REL) -> tuple[tuple[str, ...], dict[str, tuple[float, str]]]:
    """(names to fit, held {name: (start value, reason)}): the constant whose relative std
    at the start (Laplace, these data alone, no prior) is the largest is held while it is
    above ``hold_rel``, and the others judged again without it (never all: the
    best-constrained one is always fitted)."""
    J = np.vstack(list(whitened_jacobian(blocks, dict(start), list(names)).values()))
    keep = list(range(len(names)))
    held: dict[str, tuple[float, str]] = {}
    while len(keep) > 1:    # greedy: hold the worst, then judge the others without it
        cov = laplace([J[:, keep]], np.zeros(len(keep)))
        with np.errstate(invalid="ignore"):
            rel = np.sqrt(np.abs(np.diag(cov)))
        rel = np.where(np.isfinite(rel), rel, np.inf)
        worst = int(np.argmax(rel))
        if rel[worst] <= hold_rel:
            break
        n = names[keep[worst]]
        held[n] = (float(start[n]), f"relative std {rel[worst]:.3g} > {hold_rel:g} at the start")
        keep.pop(worst)
    return tuple(names[i] for i in keep), held



#: candidate starts of the global stage fitted at most (the next only when the last was inconsistent)
N_GLOBAL_FITS = 3
#: with several candidate starts, a descent stalled above GIVE_UP x the acceptable chi^2 (see
#: _fits) is ended early (engine.fit.estimate's give_up) and the next candidate tried
GIVE_UP = 10.0
#: a global-stage candidate this far (log) in some constant the modes constrain best from an
#: accepted minimum lies in another basin (a rival start)
RIVAL_LOG = math.log(1.25)
#: rival starts only for peak lists this short. Measured: 60 simulated lists of 30-60 peaks
#: (bench_identify_real.py --cases 60): a rival on every one, none ambiguous, median fit CPU
#: 2.31 -> 4.01 s; the ambiguous measured plate had 8 peaks
RIVAL_MAX_PEAKS = 20
#: a second accepted minimum within this penalised cost (chi^2 units) of the best one fits "as
#: well": one peak-list defect apart (a missed visible mode or a spurious peak), which a peak
#: list without mode shapes cannot rule out (the visibility itself rests on the stated sensor point)
AMBIGUOUS_DCOST = max(MISS, SPURIOUS)


def _fits(est: Estimate) -> bool:
    """chi^2 within 3 sigma of its expectation (n data points): a fit the data accept."""
    chi2 = sum(r["chi2"] for r in est.residuals.values())
    n = sum(r["n"] for r in est.residuals.values())
    return chi2 <= n + 3.0 * math.sqrt(2.0 * n)


def _best_constrained(ctx: FitContext, names) -> list[str]:
    """The constants modal data constrain best (E1, E2, G12; isotropic E, G) among ``names``."""
    return [n for n in (("E", "G") if ctx.isotropic else ("E1", "E2", "G12")) if n in names]


def _rival_start(est: Estimate, ranked: Sequence[Mapping[str, float]], ctx: FitContext) -> dict | None:
    """The best-ranked global-stage candidate more than RIVAL_LOG away from ``est`` in E1,
    E2 or G12 (isotropic: E, G), or None."""
    keys = _best_constrained(ctx, est.params)
    for c in ranked:
        if keys and max(abs(math.log(c[n] / est.params[n])) for n in keys) > RIVAL_LOG:
            return dict(c)
    return None


def _ambiguity(best: Estimate, tried: Sequence[Estimate]) -> dict[str, str]:
    """{parameter: reason} for the constants another accepted minimum puts elsewhere: more
    than 3 combined stds (and 1 %) away, its penalised cost within AMBIGUOUS_DCOST."""
    out: dict[str, str] = {}
    c0 = _penalised(best)
    for e in tried:
        if e is best or not _fits(e) or _penalised(e) > c0 + AMBIGUOUS_DCOST:
            continue
        for i, n in enumerate(best.names):
            v0, v1 = best.params[n], e.params[n]
            s = math.hypot(float(best.std[i]), float(e.std[i]))
            if abs(v1 - v0) > max(3.0 * s, 0.01 * abs(v0)) and n not in out:
                out[n] = (f"ambiguous: another minimum at {v1:.4g} fits the data as well (penalised "
                          f"cost {_penalised(e):.3g} against {c0:.3g}); more modes or mode shapes needed")
    return out


def _penalised(est: Estimate) -> float:
    """chi^2 plus the pairing penalties (unexplained peaks, skipped modes) of the
    likelihood pairing, when there is one."""
    chi2 = sum(r["chi2"] for r in est.residuals.values())
    a = (est.fit or {}).get("assignment")
    if a is None:
        return chi2
    n_un = int(np.sum(a.index < 0))
    return chi2 + SPURIOUS * n_un + MISS_UNKNOWN * len(a.skipped)


def global_starts(ctx: FitContext, names: Sequence[str], start: Mapping[str, float],
                  fixed: Mapping[str, float] | None = None
                  ) -> tuple[list[dict[str, float]], str, list[dict[str, float]], Callable]:
    """Starts for the local fit from the cheap global stage (engine.identify.surrogate):
    candidates over +-50 % (log-uniform) of the constants modal data constrain best (E1,
    E2, G12; isotropic E, G) among ``names``, the others at the start, ranked by their
    penalised pairing cost; the given start first when it ranks as well. Up to
    N_GLOBAL_FITS distinct starts (more than 5 % apart), best first; also every candidate
    as a start, best first (for :func:`_rival_start`); and ``prepare(candidate)``, the
    candidate refined on the surrogate (the given start too, when it is fitted)."""
    fwd = ctx.modal_forward
    best_names = _best_constrained(ctx, names)
    if not best_names:
        return [dict(start)], "global stage: skipped (no E1, E2, G12 / E, G fitted)", [], dict
    elastic = ("E", "G") if ctx.isotropic else ("E1", "E2", "nu12", "G12", "G13", "G23")
    full = {k: v for k, v in ctx.nominal.items() if k in elastic}
    full.update({k: v for k, v in {**(fixed or {}), **start}.items() if k in elastic})
    mat = ctx.material_obj

    def check(p):
        mat.with_params(**p).check()

    try:
        sur = RitzSurrogate(fwd.model, full, best_names, fwd.n_solve, material=ctx.material,
                            solve=fwd.modes_at)   # memoised: the visibility below reuses the start's modes
    except (PhysicsError, ValueError, np.linalg.LinAlgError) as e:
        return [dict(start)], f"global stage: skipped ({e})", [], dict
    vis = None
    if fwd.response_points is not None and len(fwd.response_points):
        modes = fwd.modes_at(full)
        vis = visibility(fwd.model, modes, fwd.response_points, fwd.drive_points)
    cands = global_search(sur, best_names, fwd.observed, fwd.sigma_obs, visible=vis,
                          correction=fwd.correction, check=check)
    out: list[dict[str, float]] = []
    for cost, p in cands:
        st = {n: (p[n] if n in p else start[n]) for n in names}
        if all(max(abs(math.log(st[n] / o[n])) for n in best_names) > 0.05 for o in out):
            out.append(st)
        if len(out) == N_GLOBAL_FITS:
            break
    c0 = cands[0][0] if cands else math.nan
    if all(max(abs(math.log(start[n] / o[n])) for n in best_names) > 0.05 for o in out):
        out.append(dict(start))      # the given start last, as a fallback
    ranked = [{n: (p[n] if n in p else start[n]) for n in names} for _, p in cands]
    box = bounds(ctx)

    def prepare(st: Mapping[str, float]) -> dict[str, float]:
        """A candidate moved to the surrogate's own minimum over every fitted elastic constant
        (engine.identify.surrogate.refine), so that the FE fit starts near it; refined only
        when it is fitted (~0.1-0.3 s CPU each). Measured: the demo's modal-only fit from the
        datasheet start 37 -> 14 default-mesh solves (bench/RESULTS.md, issue 29 session 25)."""
        r = refine(sur, [n for n in names if n in elastic], {**full, **st}, fwd.observed, fwd.sigma_obs,
                   visible=vis, correction=fwd.correction, box=box, check=check)
        return dict(st) if r is None else {n: (r[n] if n in r else st[n]) for n in names}

    return out, (f"global stage: {len(cands)} candidates over +-50 % of "
                 f"{', '.join(best_names)} ranked by pairing cost (best {c0:.3g})"), ranked, prepare


#: re-pairing rounds of the likelihood pairing (each a refit from the last estimate)
MAX_REPAIR = 6
#: the pairing tolerance follows the fit: 3 robust stds of the paired peaks' relative misfit, in these bounds
TAU_RANGE = (0.003, 0.05)


def _paired_rms(ctx: FitContext, est: Estimate) -> float:
    fwd = ctx.modal_forward
    r = next(v for v in est.residuals.values() if v["kind"] == "modal")
    ok = fwd.assignment.index >= 0
    rel = np.asarray(r["relative"])[ok]
    # robust (median-based) spread: one wrongly paired or spurious peak must not widen the
    # tolerance that would let it stay paired
    return float(3.0 * 1.4826 * np.median(np.abs(rel))) if rel.size else 1.0


def _repair_loop(ctx: FitContext, est: Estimate, fit, start: Mapping[str, float]
                 ) -> tuple[Estimate, list[str]]:
    """Re-pair at each estimate (tolerance from its misfit) and refit until the assignment
    no longer changes; an assignment seen before (oscillation) stops the loop at the one
    of lowest penalised cost."""
    fwd = ctx.modal_forward
    seen: dict[tuple, tuple[float, Estimate]] = {}
    notes: list[str] = []
    iters = est.iterations
    for _ in range(MAX_REPAIR):
        tau = float(np.clip(_paired_rms(ctx, est), *TAU_RANGE))
        key = tuple(fwd.assignment.index.tolist())
        seen[key] = (fwd.assignment.cost, est)
        if not fwd.repair(est.params, tau):
            break
        new = tuple(fwd.assignment.index.tolist())
        if new in seen:   # oscillation: keep the assignment of lowest penalised cost
            best = min(seen, key=lambda k: seen[k][0])
            fwd.assignment = fwd.assignment._replace(index=np.array(best), cost=seen[best][0])
            fwd.repair_fixed(np.array(best))
            est = seen[best][1]
            notes.append("modal: pairing oscillated between assignments; kept the most likely")
            break
        e2 = fit(est.params)
        iters += e2.iterations
        est = replace(e2, start=dict(start), iterations=iters, history=est.history + e2.history)
    return est, notes


def pairing_report(ctx: FitContext, params: Mapping[str, float]) -> dict:
    """``pairing`` (per peak: peak number, measured_hz, mode_index (None: unexplained),
    family (engine.plate.labels), predicted_hz) and ``unpaired_modes`` (predicted in-band
    modes no peak explains: mode_index, family, predicted_hz, visibility)."""
    fwd = ctx.modal_forward
    sol = fwd.solve(params)
    fam = mode_families(fwd.model, sol.modes, ctx.length, ctx.width)
    fp = fwd.corrected_hz(sol.modes)
    a = fwd.assignment
    rows = []
    for i, (f, j) in enumerate(zip(fwd.observed, a.index)):
        j = int(j)
        rows.append({"peak": i, "measured_hz": float(f), "mode_index": j if j >= 0 else None,
                     "family": fam[j] if j >= 0 else None, "predicted_hz": float(fp[j]) if j >= 0 else None})
    vis = fwd.visible
    skipped = [{"mode_index": int(j), "family": fam[j], "predicted_hz": float(fp[j]),
                "visibility": None if vis is None else float(vis[j])} for j in a.skipped]
    return {"pairing": rows, "unpaired_modes": skipped}


#: discretisation corrections already computed (key -> (ratio, error_rel) of the most modes
#: asked), at most _DISC_KEPT: the demo's modal and combined identifications and the diagnosis'
#: estimate build the same problem; each fine-mesh solve costs ~0.8 s CPU (demo's CFRP, 56 modes)
_DISC_MEMO: dict[tuple, tuple] = {}
_DISC_KEPT = 4


def discretisation(laminate, length: float, width: float, masses, model, material: str | None, n: int,
                   params: Mapping[str, float] | None = None):
    """(correction, error_rel, note) of the first ``n`` modes of ``model`` from a mesh
    FINE_FACTOR x finer (with the same point ``masses``), both solved at ``params`` (None:
    the laminate's own constants). Memoised on the inputs and the
    coarse model's K and M (the result is deterministic); a request for fewer modes than a
    kept correction gets its first ``n`` (the diagnosis asks for the modes its peaks pair
    with: identify's own correction, not a second fine-mesh solve: 0.5 s CPU and 81 MiB)."""
    K, M = model.matrices(None, material)
    if material is None and len(laminate.materials) == 1:     # the one material, by its name
        material = next(iter(laminate.materials))
    key = (repr(laminate), float(length), float(width), repr([tuple(map(float, m)) for m in masses or ()]),
           material, None if params is None else tuple(sorted((k, float(v)) for k, v in params.items())),
           hashlib.sha1(np.ascontiguousarray(K.data).tobytes()
                                  + np.ascontiguousarray(M.data).tobytes()).hexdigest())
    n = min(int(n), int(0.4 * model.mesh.n_dof) - 12)
    hit = _DISC_MEMO.get(key)
    if hit is None or hit[0].size < n:
        hit = _discretisation(laminate, length, width, masses, model, material, n, params)
        _DISC_MEMO.pop(key, None)
        if len(_DISC_MEMO) >= _DISC_KEPT:
            _DISC_MEMO.pop(next(iter(_DISC_MEMO)))
        _DISC_MEMO[key] = hit
    ratio, err = hit[0][:n].copy(), hit[1][:n].copy()
    k = int(np.argmax(np.abs(ratio - 1)))
    note = (f"modal: discretisation of the plate mesh corrected from a {FINE_FACTOR:g}x finer mesh "
            f"(largest correction {100 * (ratio[k] - 1):+.3g} % at mode {k + 1}; remaining error "
            f"<= {100 * err.max():.2g} % added to the sigmas)")
    return ratio, err, note


def _discretisation(laminate, length: float, width: float, masses, model, material: str | None, n: int,
                    params: Mapping[str, float] | None = None):
    fine = PlateModel.build(laminate, length, width, finer_mesh(length, width, laminate.thickness, FINE_FACTOR))
    if masses:
        fine = fine.with_point_masses(masses)
    mc = mode_corrections(model, fine, n, params=params, material=material)
    # by rank, not by the shapes' MAC: the forward model applies the ratio to its i-th mode
    # whatever its shape, and in a cluster of close modes whose shapes mix differently on
    # each mesh the MAC pairing puts a neighbour's frequency into the ratio. Measured on a
    # 1 m CFRP plate (bench_independent_run.py, 33 hammer peaks from the 2x reference mesh):
    # three modes within 1.1 % near 124 Hz, MAC ratios 0.9975 / 0.99995 / 0.9826 against
    # 0.9941 / 0.9936 / 0.9923 by rank; with MAC one peak was 9.9 sigma off, by rank 0.4
    fine_hz = np.sort(np.asarray(mc.fine_hz, float))
    coarse_hz = np.asarray(mc.coarse_hz, float)
    r = (1.0 / FINE_FACTOR) ** ORDER
    err = np.maximum(np.asarray(mc.error_rel, float), np.abs(fine_hz - coarse_hz) * r / (1.0 - r) / fine_hz)
    return fine_hz / coarse_hz, err
