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
from engine.forward import modal_block, wave_block
from engine.identify.stages import (BOX, N_EXTRA_MODES, POISSON_MAX, RUNAWAY, FitContext, bounds,
                                    identifiable, fit_blocks, pairing_report)
from engine.identify.stages import admissibility as engine_admissibility
from engine.identify.stages import discretisation as discretisation_error
from engine.identify.stages import verdict as engine_verdict
from engine.identify import sufficiency
from engine.forward.modal import MIN_MAC_POINTS, extra_modes
from engine.laminate import PhysicsError
from engine.plate import PlateModel

from ...base.errors import UserError
from ...inputs.features import parse_features
from ...inputs.specimen import MODULI, Specimen, unit_slip

__all__ = ["Problem", "problem_from_features", "default_params", "parse_assignments", "start_values", "run",
           "METHODS", "verdict", "admissibility", "RUNAWAY", "BOX", "POISSON_MAX", "result_dict", "bounds", "context",
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
    notes = list(parsed.notes)
    mats = spec.laminate.materials
    if material is None:
        if len(mats) != 1:
            raise UserError(f"laminate has materials {sorted(mats)}; expected a single material",
                            file=src, key="specimen")
        material = next(iter(mats))
    blocks: list[DataBlock] = []
    fwd = None
    md = feats.modal
    if md is not None:
        f, sig = md.frequency_hz, md.sigma_hz
        sig_rel = float(np.min(np.asarray(sig, float) / np.asarray(f, float))) if f.size else 0.0
        if f.size == 0:
            raise UserError("expected a non-empty list of numbers", file=src, key="modal.frequencies_hz")
        if modal_model is None:
            try:
                modal_model = PlateModel.build(spec.laminate, spec.length, spec.width)
            except PhysicsError as e:
                raise UserError(str(e), file=src, key="specimen") from None
            masses = feats.rig.masses()
            if masses:
                modal_model = modal_model.with_point_masses(masses)
                notes.append(f"modal model includes {len(masses)} accelerometer mass(es)")
        corr = err = None
        n_extra = extra_modes(f.size, N_EXTRA_MODES)
        if discretisation:
            corr, err, note = discretisation_error(spec.laminate, spec.length, spec.width, feats.rig.masses(),
                                                   modal_model, material, f.size + n_extra, correction_at)
            notes.append(note if correction_at is None else
                         note.replace("corrected from", "corrected (again, at the estimate) from"))
        pairing = "order" if md.pairing == "order" else "likelihood"
        resp = feats.rig.accelerometers or (md.points if md.points is not None else None)
        drive = getattr(feats.rig, "hammer", None)   # not in the features yet: (x, y) m when it is
        labels = feats.mode_index                    # optional peak labels (features modal.mode_index, 0-based)
        # MAC pairing needs enough shape points (as engine.forward.model's 'auto'); with
        # fewer (e.g. three accelerometers) the likelihood pairing is more reliable
        use_mac = (md.shapes is not None and md.points is not None and len(md.points) >= MIN_MAC_POINTS
                   and md.pairing in ("auto", "mac"))
        try:
            blk, fwd = modal_block(modal_model, f, sig, points=md.points if use_mac else None,
                                   shapes=md.shapes if use_mac else None, material=material,
                                   correction=corr, model_error_rel=err, pairing=pairing,
                                   response_points=resp, drive_points=None if drive is None else [drive],
                                   labels=labels, n_extra=n_extra)
        except IdentificationError as e:
            raise UserError(str(e), file=src, key="modal") from None
        blocks.append(blk)
    for i, w in enumerate(feats.waves):
        where = f"waves[{i}]."
        fr, cg, sig = w.frequency_hz, w.group_velocity_m_s, w.sigma_m_s
        if fr.size == 0:
            raise UserError("expected a non-empty list of numbers", file=src, key=where + "frequency_hz")
        ok = np.isfinite(fr) & np.isfinite(cg) & np.isfinite(sig)
        if not ok.all():
            notes.append(f"{where}: {int((~ok).sum())} point(s) without a velocity dropped")
        if ok.sum() == 0:
            continue
        mode, d = w.mode, w.direction_deg
        blocks.append(wave_block(spec.laminate, fr[ok], cg[ok], sig[ok], mode=mode, direction_deg=d,
                                 material=material, name=f"waves[{i}]:{mode}@{d:g}deg"))
    if not blocks:
        raise UserError("no modal frequencies and no wave velocities: nothing to identify",
                        file=src, key="modal/waves")
    recorrect = None
    if discretisation and md is not None:
        def recorrect(params: Mapping[str, float]) -> Problem | None:
            c2, e2, _ = discretisation_error(spec.laminate, spec.length, spec.width, feats.rig.masses(),
                                             modal_model, material, f.size + n_extra, params)
            k = min(c2.size, corr.size)
            # unchanged within its error and the finest measured sigma: the first fit stands
            if np.all(np.abs(c2[:k] / corr[:k] - 1.0) <= np.hypot(e2[:k], sig_rel)):
                return None
            return problem_from_features(doc, base_dir=base_dir, src=src, specimen=specimen, material=material,
                                         modal_model=modal_model, correction_at=dict(params))
    return Problem(spec, blocks, material, fwd, src, notes, replace(feats, material=material), recorrect)


# ---------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------
def default_params(problem: Problem) -> tuple[str, ...]:
    """What the data can reasonably identify.

    Isotropic: E, G. Orthotropic: the six elastic constants with modal data
    (alone or combined); waves only: E1, G13, G23 (paper Table 3), plus nu12
    when a symmetric (S) mode is measured.
    """
    if problem.isotropic:
        return ("E", "G")
    if "modal" in problem.kinds:
        return ("E1", "E2", "nu12", "G12", "G13", "G23")
    names = ["E1", "G13", "G23"]
    if any(b.kind == "waves" and ":S" in b.name for b in problem.blocks):
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
    at ``est`` when it differs there from the nominal one by more than its own error; else
    unchanged. Measured (bench_independent_run.py: 1 m CFRP plate, G13 / G23 30-40 % from
    the file): a correction computed at the file's constants put modes' ratios on their
    neighbours at the estimate (up to 0.85 % against a stated error of 0.1 %): modal chi^2
    266 for 33 peaks; computed at the estimate, 40."""
    nominal = problem.nominal
    moved = max((abs(math.log(v / nominal[n])) for n, v in est.params.items() if nominal.get(n)), default=0.0)
    if problem.recorrect is None or moved <= RECORRECT_LOG:
        return est, problem
    p2 = problem.recorrect({**nominal, **est.params})
    if p2 is None:
        return est, problem
    names = tuple(n for n in est.names if not held or n not in held)
    e2 = fit_blocks(context(p2), p2.blocks, names, {n: est.params[n] for n in names}, global_stage=False,
                    notes=list(problem.notes) + [n for n in p2.notes if "at the estimate" in n], on_error=lambda e: UserError(str(e), file=p2.source), held=held, **kw)
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



def result_dict(est: Estimate) -> dict:
    """The ``labid identify`` JSON of an estimate (``Estimate.to_dict``): CONTRACT keys plus,
    with the verdict, ``identified`` per parameter (and ``reason`` when not), the top-level
    ``identified``, ``fit``, ``held`` and, when made, ``pairing`` / ``unpaired_modes``."""
    return est.to_dict()
