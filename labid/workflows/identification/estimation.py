"""The identification problem of a features document: data blocks, defaults, the estimate.

``problem_from_features`` turns a measured-features document (CONTRACT
section 2, parsed by ``labid.inputs.features.parse_features`` into
``engine.features.Features``) into the data blocks it holds (natural
frequencies -> plate FE, group velocities -> SAFE); ``run`` chooses the
parameters to identify and their start (the specimen's nominal constants
unless given) and runs one of the estimators of :mod:`engine.fit`, with the
Birge scaling and the data-set consistency check (``engine.fit.checks``).
The workflow's public face is :mod:`labid.workflows.identification`.

Units SI throughout (Pa, Hz, m/s, kg/m^3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from engine.features import Features
from engine.fit import DataBlock, Estimate, IdentificationError, Prior
from engine.identify.blocks import feature_blocks
from engine.identify.stages import (BOX, POISSON_MAX, RUNAWAY, FitContext, bounds, identifiable, fit_blocks,
                                    pairing_report)
from engine.identify.stages import admissibility as engine_admissibility
from engine.identify.stages import verdict as engine_verdict
from engine.identify import sufficiency
from engine.identify.stages import N_EXTRA_MODES
from engine.identify.stages import discretisation as discretisation_at
from engine.forward.modal import extra_modes
from engine.laminate import PhysicsError

from ...base.errors import UserError
from ...inputs.features import parse_features
from ...inputs.specimen import MODULI, Specimen, unit_slip

__all__ = ["Problem", "problem_from_features", "default_params", "default_names", "parse_assignments", "start_values", "run",
           "METHODS", "verdict", "admissibility", "RUNAWAY", "BOX", "POISSON_MAX", "bounds", "context",
           "pairing_report"]

METHODS = ("lm", "bayes", "nelder-mead")


@dataclass
class Problem:
    """Everything needed to estimate: specimen, data blocks and bookkeeping."""

    specimen: Specimen
    blocks: list[DataBlock]
    material: str
    modal_forward: Any = None
    source: str = "<features>"
    notes: list[str] = field(default_factory=list)
    features: Features | None = None
    #: params -> the problem with the discretisation correction computed at ``params``, or
    #: None when it agrees with this one within its own error (see :func:`run`)
    recorrect: Any = None

    @property
    def kinds(self) -> tuple[str, ...]:
        return tuple(sorted({b.kind for b in self.blocks}))

    @property
    def nominal(self) -> dict[str, float]:
        return self.specimen.laminate.materials[self.material].params()

    @property
    def isotropic(self) -> bool:
        return self.specimen.laminate.materials[self.material].isotropic


# ---------------------------------------------------------------------------
# the data blocks of a features document
# ---------------------------------------------------------------------------
def problem_from_features(doc: Mapping, *, base_dir: str | Path = ".", src: str = "<features>",
                          specimen: Specimen | None = None, material: str | None = None,
                          modal_model=None, discretisation: bool = True,
                          correction_at: Mapping[str, float] | None = None) -> Problem:
    """Data blocks for whatever the features hold (modal, waves or both).

    Accelerometer masses of ``rig.accelerometers`` are added to the plate
    model as point masses. Wave points with a NaN group velocity (or sigma)
    are dropped. ``modal_model`` may pass a prebuilt ``PlateModel`` (same specimen,
    default mesh, with the rig's masses).

    ``discretisation``: the plate model's modes are also solved once, at the nominal
    constants, on a mesh 1.5x finer (``engine.plate.convergence``): every prediction is
    corrected by the ratio f_fine / f_model of its mode, and the remaining error
    (Richardson estimate) is added in quadrature to that mode's sigma, so that 40-60
    measured modes fit as well as the first 12 (issue 12). ``correction_at``: the
    constants to solve both meshes at instead of the nominal ones (``Problem.recorrect``).
    """
    parsed = parse_features(doc, base_dir, src, specimen=specimen)
    spec, feats = parsed.specimen, parsed.features
    mats = spec.laminate.materials
    if material is None:
        if len(mats) != 1:
            raise UserError(f"laminate has materials {sorted(mats)}; expected a single material",
                            file=src, key="specimen")
        material = next(iter(mats))
    feats = replace(feats, material=material)
    if feats.modal is not None and feats.modal.frequency_hz.size == 0:
        raise UserError("expected a non-empty list of numbers", file=src, key="modal.frequencies_hz")
    for i, w in enumerate(feats.waves):
        if w.frequency_hz.size == 0:
            raise UserError("expected a non-empty list of numbers", file=src, key=f"waves[{i}].frequency_hz")
    drive = getattr(feats.rig, "hammer", None)   # not in the features yet: (x, y) m when it is
    try:
        blocks, notes, fwd = feature_blocks(feats, plate_model=modal_model, correct_discretisation=discretisation,
                                            drive_points=None if drive is None else [drive],
                                            correction_at=correction_at)
    except PhysicsError as e:
        raise UserError(str(e), file=src, key="specimen") from None
    except IdentificationError as e:
        raise UserError(str(e), file=src, key="modal") from None
    if not blocks:
        raise UserError("no modal frequencies and no wave velocities: nothing to identify",
                        file=src, key="modal/waves")
    recorrect = None
    md = feats.modal
    if discretisation and md is not None and fwd is not None:
        n = md.frequency_hz.size + extra_modes(md.frequency_hz.size, N_EXTRA_MODES)
        sig_rel = float(np.min(np.asarray(md.sigma_hz, float) / np.asarray(md.frequency_hz, float)))
        geometry = (spec.laminate, spec.length, spec.width, feats.rig.masses(), fwd.model, material, n)

        def recorrect_at(params: Mapping[str, float]) -> Problem | None:
            used = discretisation_at(*geometry, correction_at)[0]         # memoised: no solve
            c2, e2, _ = discretisation_at(*geometry, params)
            k = min(c2.size, used.size)
            # unchanged within its error and the finest measured sigma: the first fit stands
            if np.all(np.abs(c2[:k] / used[:k] - 1.0) <= np.hypot(e2[:k], sig_rel)):
                return None
            return problem_from_features(doc, base_dir=base_dir, src=src, specimen=specimen, material=material,
                                         modal_model=modal_model, correction_at=dict(params))
        recorrect = recorrect_at
    return Problem(spec, blocks, material, fwd, src, list(parsed.notes) + notes, feats, recorrect)


# ---------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------
def default_params(problem: Problem) -> tuple[str, ...]:
    """What the data of ``problem`` can reasonably identify (:func:`default_names`)."""
    return default_names(problem.kinds, problem.isotropic,
                         [b.name.partition(":")[2] for b in problem.blocks if b.kind == "waves"])


def default_names(kinds, isotropic: bool, wave_modes=()) -> tuple[str, ...]:
    """What data of ``kinds`` ('modal', 'waves') with wave ``modes`` measured can reasonably
    identify (no model is built: the panel asks before any fit).

    Isotropic: E, G. Orthotropic: the six elastic constants with modal data
    (alone or combined); waves only: E1, G13, G23 (paper Table 3), plus nu12
    when a symmetric (S) mode is measured.
    """
    if isotropic:
        return ("E", "G")
    if "modal" in kinds:
        return ("E1", "E2", "nu12", "G12", "G13", "G23")
    names = ["E1", "G13", "G23"]
    if any(str(m).startswith("S") for m in wave_modes):
        names.insert(1, "nu12")
    return tuple(names)


def parse_assignments(text: str | None, option: str = "--start") -> dict[str, float]:
    """'E1=85e9,G13=5.32e9' -> {'E1': 85e9, 'G13': 5.32e9} (UserError on bad syntax)."""
    out: dict[str, float] = {}
    if not text:
        return out
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        name, sep, val = item.partition("=")
        if not sep:
            raise UserError(f"item {item!r}: expected NAME=VALUE", key=option)
        try:
            out[name.strip()] = float(val)
        except ValueError:
            raise UserError(f"value {val!r} of {name.strip()}: expected a number (SI units)", key=option) from None
        if not math.isfinite(out[name.strip()]):
            raise UserError(f"value {val!r} of {name.strip()}: expected a finite number (SI units)", key=option)
        if name.strip() in MODULI:                 # GPa typed as Pa, named as such (issue 17)
            unit_slip(name.strip(), out[name.strip()], option)
    return out


def _check_names(problem: Problem, names: Sequence[str], option: str) -> None:
    allowed = problem.specimen.laminate.materials[problem.material].param_names
    bad = [n for n in names if n not in allowed]
    if bad:
        raise UserError(f"unknown parameter(s) {bad}: expected some of {list(allowed)}", key=option)
    if len(set(names)) != len(names):
        raise UserError(f"parameter listed twice in {list(names)}", key=option)


def start_values(problem: Problem, names: Sequence[str], start: Mapping[str, float] | None) -> dict[str, float]:
    """The full start of ``names``: given values, else nominal; checked (UserError on
    unknown names, non-positive or unphysical values)."""
    start = dict(start or {})
    _check_names(problem, list(start), "--start")
    for n, v in start.items():
        if not (math.isfinite(v) and v > 0):
            raise UserError(f"{n} = {v!r}: expected a positive value in SI units (Pa, kg/m^3)", key="--start")
    unused = set(start) - set(names)
    if unused:
        raise UserError(f"start given for {sorted(unused)}, which are not identified "
                        f"(parameters: {list(names)})", key="--start")
    nominal = problem.nominal
    full = {n: float(start.get(n, nominal[n])) for n in names}
    try:
        mat = problem.specimen.laminate.materials[problem.material].with_params(**full)
        mat.check()
    except PhysicsError as e:
        raise UserError(f"unphysical start: {e}", key="--start") from None
    return full


# ---------------------------------------------------------------------------
# estimation
# ---------------------------------------------------------------------------
def run(problem: Problem, names: Sequence[str] | None = None, start: Mapping[str, float] | None = None,
        *, method: str = "lm", prior: float | Prior | None = None, max_iter: int = 60,
        scale_sigmas: bool = True, consistency: bool = True, global_stage: bool = True,
        hold: bool = True) -> Estimate:
    """Estimate ``names`` (default: :func:`default_params`) from ``problem``.

    Without ``names``, the default constants the data cannot constrain from the start
    (relative std above 30 %, engine.identify.stages.identifiable) are held at their
    start value (nominal unless ``start`` gives one) with ``hold`` (issue 12), and the
    result says so (``fit["held"]``). The stages and the verdict:
    ``engine.identify.stages.fit_blocks`` (docs/identification.md).

    ``method``: ``lm`` (combined whitened least squares, Levenberg-Marquardt
    in log-parameters), ``bayes`` (Lai & Ip update, Eq. 20; ``prior`` is the
    relative prior std, default 0.5) or ``nelder-mead`` (Eq. 29). ``prior``
    for ``lm``: None (maximum likelihood, default) or the std of log p about
    the start.

    ``scale_sigmas`` (``lm`` only): a data set (modal, waves) whose chi^2 per
    point is significantly above 1 (by more than 3 sqrt(2/n)) but below 10 has
    its sigmas multiplied by sqrt(chi^2/n) (the Birge ratio) and the fit is
    repeated from the estimate: the stated sigmas were too small for the
    model/data agreement actually reached, and the uncertainty widens
    accordingly. Never shrinks sigmas; not applied to poor fits (local minima).

    ``consistency`` (``lm``, several data sets): each data set is also fitted
    alone (from the combined estimate); when the combined chi^2 exceeds the
    sum of the separate minima by more than chance allows (chi^2 test with k
    degrees of freedom, k = combinations every data set constrains, p < 0.05),
    the data sets disagree beyond their sigmas and a warning names the
    parameters they pull apart most: the combined std is then optimistic.
    """
    held = None
    if names:
        names = tuple(names)
        _check_names(problem, names, "--params")
        st = start_values(problem, names, start)
    else:   # the defaults, less what the data cannot constrain from this start (held)
        names = default_params(problem)
        st = start_values(problem, names, start)
        if hold:
            try:
                names, held = identifiable(problem.blocks, names, st)
            except (IdentificationError, ValueError):
                held = None
            st = {n: st[n] for n in names}
    if method not in METHODS:
        raise UserError(f"method {method!r}: expected one of {list(METHODS)}", key="--method")
    est = fit_blocks(context(problem), problem.blocks, names, st, method=method, prior=prior, max_iter=max_iter,
                     scale_sigmas=scale_sigmas, consistency=consistency, global_stage=global_stage,
                     notes=problem.notes, on_error=lambda e: UserError(str(e), file=problem.source), held=held)
    est, problem = _recorrected(problem, est, st, held, dict(method=method, prior=prior, max_iter=max_iter,
                                scale_sigmas=scale_sigmas, consistency=consistency))
    # issue 24: fewer independent points than constants is a verdict, not an estimate
    return sufficiency.apply(est, sufficiency.assess(sufficiency.datasets_of(problem.blocks, problem.features),
                                                     est.names))


#: an estimate this far (log) from the nominal constants has its discretisation correction
#: computed again there (the modes' order, hence which ratio belongs to which mode, moves
#: with the constants)
RECORRECT_LOG = 0.02


def _recorrected(problem: Problem, est: Estimate, st: Mapping[str, float], held, kw: dict
                 ) -> tuple[Estimate, Problem]:
    """(estimate, problem) refitted from ``est`` with the discretisation correction computed
    at ``est`` when it differs there from the nominal one by more than its own error and the
    finest measured sigma; else unchanged. Measured (bench_independent_run.py: 1 m CFRP
    plate, G13 / G23 30-40 % from the file): a correction computed at the file's constants
    put modes' ratios on their neighbours at the estimate (up to 0.85 % against a stated
    error of 0.1 %): modal chi^2 266 for 33 peaks, chi^2/nu 4.75; computed at the estimate,
    40 and 1.10."""
    nominal = problem.nominal
    moved = max((abs(math.log(v / nominal[n])) for n, v in est.params.items() if nominal.get(n)), default=0.0)
    if problem.recorrect is None or moved <= RECORRECT_LOG:
        return est, problem
    p2 = problem.recorrect(dict(est.params))        # the fitted constants; the others as the file's
    if p2 is None:
        return est, problem
    names = tuple(n for n in est.names if not held or n not in held)
    e2 = fit_blocks(context(p2), p2.blocks, names, {n: est.params[n] for n in names}, global_stage=False,
                    notes=list(problem.notes) + [n for n in p2.notes if "at the estimate" in n],
                    on_error=lambda e: UserError(str(e), file=p2.source), held=held, **kw)
    return replace(e2, start=dict(st), iterations=est.iterations + e2.iterations,
                   seconds=est.seconds + e2.seconds), p2


def context(problem: Problem) -> FitContext:
    """The engine's FitContext of a problem."""
    mat = problem.specimen.laminate.materials[problem.material]
    return FitContext(mat, problem.nominal, problem.isotropic, problem.specimen.length, problem.specimen.width,
                      problem.modal_forward, problem.material)


def verdict(problem: Problem, est: Estimate, *, scale_sigmas: bool = True) -> tuple[Estimate, list[str]]:
    """The verdict of ``est`` (engine.identify.stages.verdict) for ``problem``."""
    return engine_verdict(context(problem), est, scale_sigmas=scale_sigmas)


def admissibility(problem: Problem, params: Mapping[str, float], rel: float = 0.02) -> dict[str, str]:
    """{name: reason} of flagged constants (engine.identify.stages.admissibility)."""
    return engine_admissibility(context(problem), params, rel)

