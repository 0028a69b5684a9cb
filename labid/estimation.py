"""The identification problem of a features document: data blocks, defaults, the estimate.

``problem_from_features`` turns a measured-features document (CONTRACT
section 2, parsed by ``labid.features.parse_features`` into
``engine.features.Features``) into the data blocks it holds (natural
frequencies -> plate FE, group velocities -> SAFE); ``run`` chooses the
parameters to identify and their start (the specimen's nominal constants
unless given) and runs one of the estimators of :mod:`engine.fit`, with the
Birge scaling and the data-set consistency check (``engine.fit.checks``).
The workflow's public face is :mod:`labid.identification`.

Units SI throughout (Pa, Hz, m/s, kg/m^3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from engine.features import Features
from engine.fit import (DataBlock, Estimate, IdentificationError, Prior, bayesian_update, checks, estimate,
                        nelder_mead_fit)
from engine.forward import modal_block, wave_block
from engine.laminate import PhysicsError
from engine.plate import PlateModel
from engine.plate.convergence import FINE_FACTOR, finer_mesh, mode_corrections

from .errors import UserError
from .features import parse_features
from .specimen import Specimen

__all__ = ["Problem", "problem_from_features", "default_params", "parse_assignments", "start_values", "run",
           "METHODS", "verdict", "admissibility", "RUNAWAY", "result_dict", "bounds", "boxed"]

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
                          modal_model=None, discretisation: bool = True) -> Problem:
    """Data blocks for whatever the features hold (modal, waves or both).

    Accelerometer masses of ``rig.accelerometers`` are added to the plate
    model as point masses. Wave points with a NaN group velocity (or sigma)
    are dropped. ``modal_model`` may pass a prebuilt ``PlateModel`` (same specimen,
    default mesh, with the rig's masses).

    ``discretisation``: the plate model's modes are also solved once, at the nominal
    constants, on a mesh 1.5x finer (``engine.plate.convergence``): every prediction is
    corrected by the ratio f_fine / f_model of its mode, and the remaining error
    (Richardson estimate) is added in quadrature to that mode's sigma, so that 40-60
    measured modes fit as well as the first 12 (issue 12).
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
        if discretisation:
            corr, err, note = _discretisation(spec, feats, modal_model, material, f.size + N_EXTRA_MODES)
            notes.append(note)
        try:
            blk, fwd = modal_block(modal_model, f, sig, points=md.points, shapes=md.shapes, material=material,
                                   correction=corr, model_error_rel=err)
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
    return Problem(spec, blocks, material, fwd, src, notes, replace(feats, material=material))


#: predicted modes beyond the measured count (corrections; pairing with missing modes)
N_EXTRA_MODES = 8


def _discretisation(spec: Specimen, feats: Features, model, material: str, n: int):
    """(correction, error_rel, note) of the first ``n`` modes of ``model`` from a finer mesh."""
    fine = PlateModel.build(spec.laminate, spec.length, spec.width,
                            finer_mesh(spec.length, spec.width, spec.laminate.thickness, FINE_FACTOR))
    masses = feats.rig.masses()
    if masses:
        fine = fine.with_point_masses(masses)
    n = min(n, int(0.4 * model.mesh.n_dof) - 12)
    mc = mode_corrections(model, fine, n, material=material)
    k = int(np.argmax(np.abs(mc.ratio - 1)))
    note = (f"modal: discretisation of the plate mesh corrected from a {FINE_FACTOR:g}x finer mesh "
            f"(largest correction {100 * (mc.ratio[k] - 1):+.3g} % at mode {k + 1}; remaining error "
            f"<= {100 * mc.error_rel.max():.2g} % added to the sigmas)")
    return mc.ratio, mc.error_rel, note


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
        scale_sigmas: bool = True, consistency: bool = True) -> Estimate:
    """Estimate ``names`` (default: :func:`default_params`) from ``problem``.

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
    names = tuple(names) if names else default_params(problem)
    _check_names(problem, names, "--params")
    st = start_values(problem, names, start)
    if method not in METHODS:
        raise UserError(f"method {method!r}: expected one of {list(METHODS)}", key="--method")
    if problem.modal_forward is not None:
        problem.modal_forward.reset_tracking()
    blocks = boxed(problem, problem.blocks)
    try:
        if method == "lm":
            est = estimate(blocks, names, st, prior=prior, max_iter=max_iter)
        elif method == "bayes":
            est = bayesian_update(blocks, names, st,
                                  prior_rel_std=0.5 if prior is None else prior, max_iter=max_iter)
        else:
            est = nelder_mead_fit(blocks, names, st, prior=prior)
    except IdentificationError as e:
        raise UserError(str(e), file=problem.source) from None
    scale_notes: list[str] = []
    if scale_sigmas and method == "lm":
        est, scale_notes = checks.birge_refit(blocks, est, names, st, prior, max_iter)
    if consistency and method == "lm" and len(problem.kinds) > 1:
        scale_notes += checks.consistency(blocks, est, names, prior, max_iter)
    warnings = list(est.warnings) + list(problem.notes) + scale_notes
    est, verdict_notes = verdict(problem, est, scale_sigmas=scale_sigmas)
    warnings += verdict_notes
    if problem.modal_forward is not None:
        warnings += problem.modal_forward.warnings
    return replace(est, warnings=tuple(warnings))


#: a fitted constant more than this factor from nominal is not identified (issue 12)
RUNAWAY = 10.0
#: the fit's box: moduli and density within this factor of nominal, Poisson ratios in (0, POISSON_MAX)
BOX = 20.0
POISSON_MAX = 1.0


def bounds(problem: Problem) -> dict[str, tuple[float, float]]:
    """The box the fit stays in ({name: (low, high)}, SI): moduli within BOX x of nominal,
    Poisson ratios in (0, POISSON_MAX); the positive-definite stiffness is checked by the
    forward models themselves (PhysicsError)."""
    out = {}
    for n, v in problem.nominal.items():
        out[n] = (0.0, POISSON_MAX) if n.startswith("nu") else (v / BOX, v * BOX)
    return out


def boxed(problem: Problem, blocks: Sequence[DataBlock]) -> list[DataBlock]:
    """``blocks`` whose predictions raise ValueError outside :func:`bounds` (the
    estimators then shorten the step: the fit stops at the bound, and is flagged)."""
    box = bounds(problem)

    def guard(fn):
        def wrapped(params, *a):
            for n, v in params.items():
                lo, hi = box.get(n, (-math.inf, math.inf))
                if not lo < v < hi:
                    raise ValueError(f"{n} = {v:.4g} outside the fit's box ({lo:.4g}, {hi:.4g})")
            return fn(params, *a)
        return wrapped

    return [replace(b, predict=guard(b.predict), jacobian=None if b.jacobian is None else guard(b.jacobian))
            for b in blocks]


def admissibility(problem: Problem, params: Mapping[str, float], rel: float = 0.02) -> dict[str, str]:
    """{name: reason} for constants more than RUNAWAY x from nominal, or at the edge of the
    admissible region (a change of ``rel`` in either direction makes the 3D stiffness
    non positive-definite or leaves a Poisson ratio's bounds)."""
    nominal = problem.nominal
    mat = problem.specimen.laminate.materials[problem.material]
    out: dict[str, str] = {}
    box = bounds(problem)
    for n, v in params.items():
        ratio = v / nominal[n]
        lo, hi = box[n]
        if v <= lo + rel * (hi - lo) * (n.startswith("nu")) or v >= hi / (1.0 + rel):
            out[n] = f"at the bound of the fit's box ({lo:.4g}, {hi:.4g})"
            continue
        if ratio > RUNAWAY or ratio < 1.0 / RUNAWAY:
            out[n] = f"moved {ratio:.3g}x from nominal (more than {RUNAWAY:g}x)"
            continue
        for f in (1.0 + rel, 1.0 / (1.0 + rel)):
            try:
                mat.with_params(**{**params, n: v * f}).check()
            except PhysicsError:
                out[n] = "at the edge of the admissible region (positive-definite stiffness, Poisson bounds)"
                break
    return out


def verdict(problem: Problem, est: Estimate, *, scale_sigmas: bool = True) -> tuple[Estimate, list[str]]:
    """(Estimate with the ``fit`` verdict, notes).

    ``fit``: chi2 and p-value against the sigmas as given (before any Birge scaling),
    dof, ``consistent`` (p >= 1e-3), ``std_scale`` (the stds are multiplied by
    sqrt(chi^2/nu) whenever chi^2/nu > 1: they grow monotonically with the misfit),
    ``flags`` ({parameter: reason}: runaway or at the admissible edge) and
    ``identified`` (consistent and every parameter identified). A constant is
    identified only when its relative std is below the threshold, it is not flagged and
    the fit is consistent.
    """
    fit = checks.goodness(est)
    scale = est.sigma_scale or {}
    chi2_scaled = fit["chi2"]
    if scale:   # the verdict judges the sigmas as stated, not as Birge-scaled
        chi2 = sum(r["chi2"] * scale.get(r["kind"], 1.0) ** 2 for r in est.residuals.values())
        fit = checks.goodness(replace(est, residuals={"all": {"chi2": chi2, "n": fit["n_points"],
                                                               "kind": "all"}}))
    notes: list[str] = []
    factor = math.sqrt(chi2_scaled / fit["dof"]) if scale_sigmas and chi2_scaled > fit["dof"] else 1.0
    est = checks.scale_uncertainty(est, factor)
    fit["std_scale"] = factor * math.sqrt(max([v * v for v in scale.values()] or [1.0]))
    flags = admissibility(problem, est.params)
    ident = dict(est.identifiability)
    params = {}
    for n, d in ident["parameters"].items():
        d = dict(d)
        if n in flags:
            d["identified"], d["reason"] = False, flags[n]
        elif not fit["consistent"]:
            d["identified"], d["reason"] = False, "inconsistent fit"
        elif not d["identified"]:
            d["reason"] = f"relative std above {ident['rel_threshold']:g}"
        params[n] = d
    ident["parameters"] = params
    ident["poorly_identified"] = [n for n in est.names if not params[n]["identified"]]
    fit["flags"] = flags
    fit["identified"] = bool(fit["consistent"] and not ident["poorly_identified"])
    if not fit["consistent"]:
        notes.append(f"INCONSISTENT fit: chi^2 = {fit['chi2']:.4g} for {fit['dof']} degrees of freedom "
                     f"(chi^2/nu = {fit['chi2_per_dof']:.3g}, p = {fit['p_value']:.2g} < 1e-3): a local "
                     "minimum, a wrong mode pairing, or a model/data mismatch (see labid diagnose); "
                     "no constant is reported as identified")
    for n, why in flags.items():
        notes.append(f"{n} {why}: not identified")
    if factor > 1.0:
        notes.append(f"stds scaled by sqrt(chi^2/nu) = {factor:.3g}")
    return replace(est, identifiability=ident, fit=fit), notes



def result_dict(est: Estimate) -> dict:
    """The ``labid identify`` JSON of an estimate (``Estimate.to_dict``): CONTRACT keys plus,
    with the verdict, ``identified`` per parameter (and ``reason`` when not), the top-level
    ``identified``, ``fit``, ``held`` and, when made, ``pairing`` / ``unpaired_modes``."""
    return est.to_dict()
