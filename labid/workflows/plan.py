"""``labid plan``: design the test before the plate is touched (issue 25, docs/plan.md).

From the specimen (the datasheet's constants, uncertain by a prior) and a rig (its hammer,
band, accelerometer count and masses), :func:`plan_test` recommends where the
accelerometers go and where to tap, whether guided waves are needed and how to measure
them, and predicts the std of every constant, for the recommended plan and for the user's
own rig (and any ``compare`` rigs). The numerics are ``engine.design``; this module reads
the inputs, runs the search, and lays the answer out as plain data (``PlanResult.to_dict``
is the ``--json`` document). Units SI; relative stds as fractions.

Which constants are fitted mirrors ``labid identify``'s rule: the wanted ones always, every
other one unless the data alone leave it above ``HOLD_REL`` (then it is held at its nominal
value and its prior uncertainty propagates into the others, a type-B input).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from engine.design import (DesignProblem, Layout, candidate_grid, criterion, evaluate, modal_set, optimise,
                           prior_draws, snap)
from engine.design import waves as dwaves
from engine.identify.stages import discretisation
from engine.plate import PlateModel, mode_families
from engine.wavefeatures.band import default_wavelet

from ..base.errors import Cancelled, UserError
from ..inputs.rig import Rig, load_rig
from ..inputs.specimen import Specimen
from .budget import uncertainty_table
from .plan_docs import held_misfit, key_modes, layout_doc, std_table, waves_doc
from .plan_figure import plan_png, save_plan_figure
from .plan_inputs import (PlanOptions, budget_columns, constant_names, material_of, measurement_of, parse_options,
                          rig_layout)
from .plan_rig import plan_rig_text, write_plan_rig
from .plan_summary import plan_text

__all__ = ["PlanResult", "plan_test", "parse_options", "material_of", "IDENTIFIED_REL", "HOLD_REL", "WAVE_RATE_HZ", "WAVE_NEAR_M"]

#: a constant is identifiable when its predicted relative std (all constants fitted, data
#: alone) is below this (the identification's own threshold, docs/identification.md)
IDENTIFIED_REL = 0.10
#: a constant that is not wanted is held at nominal when the data alone leave it above this
#: (``labid identify``'s default parameters rule)
HOLD_REL = 0.30
#: held constants whose priors add more than this to the fit's chi^2 per dof are flagged
MISFIT_CHI2 = 1.0
#: sample rate assumed for the wave device when the rig has none, Hz
WAVE_RATE_HZ = 2.0e6
#: the near wave sensor's distance from the source, m (as the built-in rig)
WAVE_NEAR_M = 0.05


@dataclass
class PlanResult:
    """The plan as data (``to_dict``: the ``--json`` document) plus what the figure and the
    rig writer need (the nominal model and modes, the key modes, the wave plan)."""

    doc: dict
    model: Any = field(repr=False, default=None)
    modes: Any = field(repr=False, default=None)
    key_modes: tuple[int, ...] = ()
    wave_plan: Any = None
    specimen: Specimen | None = field(repr=False, default=None)
    template: Rig | None = field(repr=False, default=None)

    def to_dict(self) -> dict:
        return self.doc

    def text(self) -> str:
        """The console summary (``labid.workflows.plan_summary``)."""
        return plan_text(self.doc)

    def rig_text(self) -> str:
        """The recommended rig file's text, validated (``labid.workflows.plan_rig``)."""
        return plan_rig_text(self)

    def write_rig(self, path) -> str:
        """Write the recommended rig file; its text."""
        return write_plan_rig(self, path)

    def figure_png(self) -> bytes:
        """The plan's figure, PNG (``labid.workflows.plan_figure``)."""
        return plan_png(self)

    def save_figure(self, path) -> None:
        """Write the plan's figure as PNG."""
        save_plan_figure(self, path)


@dataclass
class _Waves:
    plan: Any
    jac: np.ndarray
    jac_h: np.ndarray
    weight: np.ndarray
    rate_hz: float


@dataclass
class _Context:
    spec: Specimen
    options: PlanOptions
    names: tuple[str, ...]
    want: tuple[str, ...]
    prior: dict
    mset: Any
    meas: Any
    masses: np.ndarray
    model_error: np.ndarray | None = None

    def problem(self, fit: Sequence[int], waves: _Waves | None = None, inputs: dict | None = None,
                sensor_u: float = 0.0) -> DesignProblem:
        """The design problem fitting ``fit`` (indices), the other constants held (type-B)."""
        fixed = tuple(i for i in range(len(self.names)) if i not in fit and self.prior[self.names[i]] > 0)
        fixed_u = tuple(self.prior[self.names[i]] for i in fixed)
        inputs = dict(inputs or {})
        prob = DesignProblem(self.mset, self.meas, tuple(fit), fixed, fixed_u, model_error=self.model_error)
        if waves is not None:
            inputs, Xw = _wave_inputs(waves, fixed, inputs, self.spec, sensor_u)
            prob = replace(prob, wave_jac=waves.jac, wave_weight=waves.weight, wave_inputs=Xw)
        if inputs:
            shape = self.mset.freqs.shape
            prob = replace(prob, inputs={k: (np.zeros(shape) if c is None else c, u) for k, (c, u) in inputs.items()})
        return prob

    def fitted(self, layout: Layout, waves: _Waves | None = None) -> tuple[int, ...]:
        """The wanted constants and every other one the data alone give within HOLD_REL
        (the least determined is held, then the rest judged again); with ``fit = 'wanted'``
        the wanted ones only."""
        if self.options.fit == "wanted":
            return tuple(i for i, n in enumerate(self.names) if n in self.want)
        fit = list(range(len(self.names)))
        while True:
            ev = evaluate(self.problem(fit, waves), [list(layout.sensors)], [layout.tap], self.masses)
            sd = np.sqrt(np.mean(ev.type_a[:, 0, :] ** 2, axis=0))
            cand = [(sd[k], i) for k, i in enumerate(fit) if self.names[i] not in self.want]
            if not cand or max(cand)[0] <= HOLD_REL:
                return tuple(fit)
            fit.remove(max(cand)[1])


def _wave_inputs(w: _Waves, fixed: Sequence[int], inputs: dict, spec: Specimen, sensor_u: float
                 ) -> tuple[dict, np.ndarray]:
    """Wave columns of the held constants and of the budget's inputs (same order), plus one
    input per leg: its sensor spacing (two positions, each uncertain by ``sensor_u``)."""
    h, rho = spec.laminate.thickness, spec.laminate.mean_density
    L, W = spec.length, spec.width
    n = w.jac.shape[0]
    weighed = "mass" in inputs
    cols = [w.jac[:, i] for i in fixed]
    for name in inputs:
        if name == "thickness":
            c = w.jac_h[:, 0] / h + (0.5 / h if weighed else 0.0)
        elif name == "density":
            c = np.full(n, -0.5 / rho)
        elif name == "mass":
            c = np.full(n, -0.5 / (rho * L * W * h))
        elif name in ("length", "width") and weighed:
            c = np.full(n, 0.5 / (L if name == "length" else W))
        else:
            c = np.zeros(n)
        cols.append(c)
    new = dict(inputs)
    if sensor_u > 0:
        start = 0
        for k, leg in enumerate(w.plan.legs):
            c = np.zeros(n)
            c[start:start + len(leg.freqs)] = 1.0 / leg.spacing_m    # observed cg = spacing / delay
            start += len(leg.freqs)
            cols.append(c)
            new[f"wave_spacing_{k + 1}"] = (None, math.sqrt(2.0) * sensor_u)
    return new, (np.stack(cols, axis=1) if cols else np.zeros((n, 0)))


def _budget_table(spec: Specimen, budget: str) -> dict:
    """The ``[uncertainty]`` table (``labid.workflows.budget.uncertainty_table``, defaults as
    ``labid identify``) of the specimen itself ('specimen') or of a TOML file's."""
    if budget == "specimen":
        return uncertainty_table(spec)
    try:
        tab = tomllib.loads(Path(budget).read_text()).get("uncertainty", {})
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise UserError(f"cannot read an [uncertainty] table: {e}", file=budget, key="--budget") from None
    return uncertainty_table(replace(spec, uncertainty=tab, source=str(budget)))


def _setup_points(spec: Specimen, options: PlanOptions, template: Rig, baselines) -> tuple:
    grid = candidate_grid(spec.length, spec.width, options.grid, options.margin_m, template.supports,
                          options.keepout_m)
    extra, layouts, notes = [], [], []
    for r, label in baselines:
        pts_r, tap_r, m_r, nt = rig_layout(r, spec)
        notes += nt
        i0 = len(grid) + len(extra)
        extra += list(pts_r) + [tap_r]
        layouts.append((r, label, tuple(range(i0, i0 + len(pts_r))), i0 + len(pts_r), m_r))
    points = np.vstack([grid, np.array(extra)])
    allowed = np.zeros(len(points), bool)
    allowed[:len(grid)] = True
    return points, allowed, layouts, notes, len(grid)


def _plan_waves(ctx: _Context, template: Rig, say) -> _Waves | str:
    spec, options = ctx.spec, ctx.options
    wdev = template.device("wave")
    rate = wdev.timing.rate_hz if wdev is not None else WAVE_RATE_HZ
    band = dwaves.default_band(spec.laminate, rate)
    vel = dwaves.velocity_table(spec.laminate, np.geomspace(band[0], band[1], 60), modes=("A0",))
    mat_name, mat = material_of(spec)
    dirs = (0.0,) if mat.isotropic else (0.0, 90.0)
    try:
        wplan = dwaves.plan_geometry(vel, spec.length, spec.width, dirs, default_wavelet(spec.laminate),
                                     margin=options.margin_m, near=WAVE_NEAR_M, timing_s=options.wave_timing_s,
                                     floor_rel=options.wave_floor, band_hz=band)
    except ValueError as e:
        return str(e)
    Jw, Jh = dwaves.wave_jacobian(spec.laminate, ctx.names, mat.params(), wplan.legs, mat_name,
                                  thickness=options.budget != "none", progress=say)
    ww = np.concatenate([dwaves.leg_weights(l, options.wave_timing_s, options.wave_floor)
                         for l in wplan.legs if l.freqs])
    return _Waves(wplan, Jw, Jh, ww, rate)


def plan_test(spec: Specimen, rig: Rig | None = None, options: PlanOptions = PlanOptions(), *,
              compare: Sequence[Rig] = (), progress: Callable[[str], None] | None = None,
              should_stop: Callable[[], bool] | None = None) -> PlanResult:
    """Recommend a test of ``spec`` (module docstring). ``rig``: the user's rig (None: the
    built-in one, as template and baseline); ``compare``: candidate rigs to rank."""
    say = progress or (lambda msg: None)

    def check_stop():
        if should_stop is not None and should_stop():
            raise Cancelled("plan cancelled")

    mat_name, mat = material_of(spec)
    names = constant_names(mat)
    want = tuple(options.want or names)
    prior = {n: float((options.prior or {}).get(n, 0.10)) for n in names}
    template = rig if rig is not None else load_rig(None)
    meas = measurement_of(template, options)
    baselines = [(template, "your rig" if rig is not None else "built-in default rig")]
    baselines += [(r, f"compare {i + 1}") for i, r in enumerate(compare)]
    points, allowed, layouts, notes, n_grid = _setup_points(spec, options, template, baselines)
    user = layouts[0]
    n_sensors = options.sensors or len(user[2])
    masses = np.full(n_sensors, meas.mass_kg)
    try:
        model = PlateModel.build(spec.laminate, spec.length, spec.width)
    except ValueError as e:
        raise UserError(str(e), file=spec.source, key="layup") from None
    draws = prior_draws(mat, names, prior, options.draws, options.seed)
    if len(draws) < options.draws:
        notes.append(f"{options.draws - len(draws)} prior draw(s) gave inadmissible constants and were skipped")
    mset = modal_set(model, draws, names, points, options.max_modes, mat_name, progress=say)
    f_cap = float(mset.freqs[0, -1]) * (1.0 - 1e-3)
    if f_cap < meas.band_hz():   # the model holds fewer modes than the band: fit the peaks below its last
        meas = replace(meas, f_max_hz=f_cap)
        notes.append(f"the band holds more than the {options.max_modes} modes modelled: fit the peaks below "
                     f"{meas.f_max_hz:.0f} Hz (labid analyze --modal-fmax, or more --max-modes)")
    # the identification adds the plate mesh's remaining discretisation error to every peak's
    # sigma (Richardson estimate from a 1.5x finer mesh, at the nominal): so does the plan
    _, disc_err, _ = discretisation(spec.laminate, spec.length, spec.width, [], model, mat_name, options.max_modes)
    model_error = np.zeros(options.max_modes)
    model_error[:min(len(disc_err), options.max_modes)] = disc_err[:options.max_modes]
    ctx = _Context(spec, options, names, want, prior, mset, meas, masses, model_error)
    check_stop()
    # -- the modal layout ------------------------------------------------------------------
    starts = []
    if len(user[2]) == n_sensors:
        sn = [snap(points, points[i], allowed) for i in user[2]]
        tp = snap(points, points[user[3]], allowed)
        if len(set(sn + [tp])) == n_sensors + 1:
            starts.append(Layout(tuple(sn), tp))
    ref = starts[0] if starts else Layout(tuple(range(n_sensors)), n_sensors)
    fit = ctx.fitted(ref)
    prob = ctx.problem(fit)
    say("searching the layout")
    best, _ = optimise(prob, n_sensors, allowed, min_gap=options.min_gap_m, kind=options.criterion,
                       starts=starts, seed=options.seed, should_stop=should_stop)
    best = _keep_user(prob, best, user, n_sensors, options.criterion, notes)
    check_stop()
    fit = ctx.fitted(best)
    prob = ctx.problem(fit)
    modal_std = std_table(prob, evaluate(prob, [list(best.sensors)], [best.tap], masses), options.target_u, want)
    # -- guided waves: whether they pay --------------------------------------------------------
    need = [n for n in want if not modal_std[n]["meets_target"]]
    waves: _Waves | None = None
    wave_doc: dict = {"recommended": False, "needed_for": need}
    if options.waves == "yes" or (options.waves == "auto" and need):
        say("planning guided waves")
        got = _plan_waves(ctx, template, say)
        if isinstance(got, str):
            wave_doc["reason"] = got
        else:
            fit_w = ctx.fitted(best, got)
            prob_w = ctx.problem(fit_w, got)
            wstd = std_table(prob_w, evaluate(prob_w, [list(best.sensors)], [best.tap], masses),
                              options.target_u, want)
            say("with waves: " + ", ".join(f"{k} {100 * v['std_rel']:.2f}% (A {100 * v['type_a_rel']:.2f}%)" for k, v in wstd.items()) + f" fitted {fit_w}")
            pays = options.waves == "yes" or any(
                wstd[n]["meets_target"] or wstd[n]["std_rel"] <= 0.5 * modal_std[n]["std_rel"] for n in need)
            wave_doc.update(waves_doc(got, options.wave_timing_s, options.wave_floor, pays))
            if "nu12" in need and not wstd.get("nu12", {}).get("meets_target", True):
                notes.append("nu12: the A0 velocities planned here hardly inform it; S0 velocities do "
                             "(a symmetric source, e.g. a PZT pair driven 'symmetric', and labid analyze "
                             "--with-s0), which this plan does not model")
            if pays:
                waves, fit, prob = got, fit_w, prob_w
                say("searching the layout with the waves' information")
                best, _ = optimise(prob, n_sensors, allowed, min_gap=options.min_gap_m, kind=options.criterion,
                                   starts=[best], n_random=0, seed=options.seed, should_stop=should_stop)
                best = _keep_user(prob, best, user, n_sensors, options.criterion, notes)
            else:
                wave_doc["reason"] = ("the wave legs this plate allows neither bring " + ", ".join(need)
                                      + " to the target nor halve their std")
    check_stop()
    # -- the predictions (with the budget's type-B inputs when asked) ----------------------------
    fit_modal = ctx.fitted(best)
    if options.budget != "none":
        table = _budget_table(spec, options.budget)
        inputs = budget_columns(model, spec, draws, mat_name, table, options.max_modes, progress=say)
        su = table.get("sensor_position", (0.0, ""))[0]
        final = ctx.problem(fit, waves, inputs, su)
        modal_final = ctx.problem(fit_modal, None, inputs)
    else:
        final, modal_final = ctx.problem(fit, waves), ctx.problem(fit_modal)
    fams = mode_families(model, mset.first_modes, spec.length, spec.width)
    args = (options.target_u, want, options.criterion)
    say("the recommended layout with its accelerometers on the plate")
    (final_l, modal_l), idx = _loaded((final, modal_final), model, draws, best.sensors, best.tap, masses, mat_name)
    rec = layout_doc(final_l, *idx, masses, fams, *args)
    rec_modal = layout_doc(modal_l, *idx, masses, fams, *args)
    rigs_doc = []
    for r, label, sens, tap, m_r in layouts:
        m = measurement_of(r, options)
        say(f"{label} with its accelerometers on the plate")
        (prob_r,), idx = _loaded((replace(final, meas=replace(m, f_max_hz=min(m.f_max_hz, f_cap))),), model, draws,
                                 sens, tap, m_r, mat_name)
        d = layout_doc(prob_r, *idx, m_r, fams, *args)
        d.update({"label": label, "source": r.source, "name": r.name})
        rigs_doc.append(d)
    for rank, i in enumerate(sorted(range(1, len(rigs_doc)), key=lambda i: rigs_doc[i]["criterion"]), 1):
        rigs_doc[i]["rank"] = rank
    key = key_modes(final, best, masses)
    misfit = held_misfit(final, best, masses)
    if sum(misfit.values()) > MISFIT_CHI2:
        worst = max(misfit, key=misfit.get)
        notes.append(f"the held constants' priors add {sum(misfit.values()):.1f} to the fit's chi^2 per degree of "
                     f"freedom ({worst} {misfit[worst]:.1f}): expect inconsistent fits and wrong pairings, where this "
                     f"linear prediction does not hold; fit {worst} too (--want) or know it better (--prior)")
    out = {
        "specimen": spec.name,
        "plate": {"length_m": spec.length, "width_m": spec.width, "thickness_m": spec.laminate.thickness},
        "want": list(want), "target_u": options.target_u, "prior_rel": prior, "draws": len(draws),
        "criterion": options.criterion, "budget": options.budget,
        "fitted": [names[i] for i in fit], "held": {n: prior[n] for i, n in enumerate(names) if i not in fit},
        "held_chi2_per_dof": misfit,
        "measurement": {"sigma_rel": meas.sigma_rel, "v_ref": meas.v_ref, "v_min": meas.v_min,
                        "damping": meas.damping, "band_hz": meas.band_hz(), "contact_s": meas.contact_s,
                        "acquisition_band_hz": meas.f_max_hz, "resolution_hz": meas.resolution_hz,
                        "mass_u_rel": meas.mass_u_rel, "max_modes": options.max_modes},
        "grid": {"n": options.grid, "margin_m": options.margin_m, "keepout_m": options.keepout_m,
                 "candidates": n_grid},
        "recommended": rec, "recommended_modal_only": rec_modal, "rigs": rigs_doc,
        "waves": wave_doc,
        "constants": _identifiability(ctx, best, waves),
        "key_modes": [{"mode": int(i), "frequency_hz": float(mset.freqs[0, i]), "family": fams[i]} for i in key],
        "improvement_worst_std": rigs_doc[0]["worst_std_rel"] / rec["worst_std_rel"],
        "identify": "labid identify FEATURES.json --params " + ",".join(names[i] for i in fit),
        "notes": notes,
    }
    return PlanResult(out, model, mset.first_modes, tuple(key), waves.plan if waves else None, spec, template)


def _loaded(probs: Sequence[DesignProblem], model, draws, sensors, tap, masses, material: str | None):
    """``probs`` on the plate with the layout's accelerometers (``masses``, kg) attached: the modes
    re-solved at every draw (frequencies, sensitivities, shapes at the sensors and the tap), and
    (sensor indices, tap index) into the new points. The layout search uses the bare plate's
    modes and first-order mass effects (-m phi^2 / 2); the reported stds use these, since the
    mass's effect is not linear from zero: measured on the CFRP plan's layout (3 x 2 g,
    bench/RESULTS.md issue 25 session 25), d ln f / d m at 2 g is 0.69-0.84 x the bare
    plate's -phi^2 / 2 overall and, close modes mixing, off by more than 30 % on single modes;
    E1's std from the masses' 10 % was 0.32 % by the bare plate, is 0.16-0.19 % by the loaded
    one and 0.17 % over 60 simulated identifications."""
    pts = probs[0].mset.points
    xy = np.vstack([pts[list(sensors)], pts[[tap]]])
    loaded = model.with_point_masses([(float(x), float(y), float(m)) for (x, y), m in zip(xy[:-1], masses)])
    ms = modal_set(loaded, draws, probs[0].mset.names, xy, probs[0].mset.freqs.shape[1], material)
    return tuple(replace(p, mset=ms, pairs=None) for p in probs), (tuple(range(len(sensors))), len(sensors))


def _keep_user(prob: DesignProblem, best: Layout, user, n_sensors: int, kind: str, notes: list) -> Layout:
    """The user's own layout (exact positions, off the grid) when the search found nothing better."""
    if len(user[2]) != n_sensors:
        return best
    value = float(criterion(evaluate(prob, [list(user[2])], [user[3]]), kind)[0])
    if value <= best.value:
        if not any(n.startswith("your layout") for n in notes):
            notes.append("your layout is already the best the search found: keep it")
        return Layout(tuple(user[2]), user[3], value)
    return best


def _identifiability(ctx: _Context, best: Layout, waves: _Waves | None) -> dict:
    """Per constant, every constant fitted from the data alone: rms std with the plan's data
    and with modal data alone, identifiable (< IDENTIFIED_REL), the constant it correlates with
    most (what limits it)."""
    out: dict = {}
    full = tuple(range(len(ctx.names)))
    for label, w in (("plan", waves), ("modal", None)):
        ev = evaluate(ctx.problem(full, w), [list(best.sensors)], [best.tap], ctx.masses)
        rms = np.sqrt(np.mean(ev.type_a[:, 0, :] ** 2, axis=0))
        cov = ev.cov[0, 0]
        sd = np.sqrt(np.diag(cov))
        corr = cov / np.outer(sd, sd)
        for k, n in enumerate(ctx.names):
            d = out.setdefault(n, {})
            d[f"{label}_std_rel"] = float(rms[k])
            if label == "plan":
                c = np.abs(corr[k]).copy()
                c[k] = -1.0
                j = int(np.argmax(c))
                d["identifiable"] = bool(rms[k] < IDENTIFIED_REL)
                d["limited_by"] = ({"constant": ctx.names[j], "correlation": float(corr[k, j])}
                                   if len(ctx.names) > 1 else None)
    return out
