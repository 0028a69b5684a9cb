"""Identification workflow: features file -> forward models -> estimate.

``identify(features)`` reads a measured-features document (CONTRACT section 2),
builds the data blocks it holds (natural frequencies -> plate FE, group
velocities -> SAFE), chooses the parameters to identify and their start
(the specimen's nominal constants unless given), and runs one of the
estimators of :mod:`engine.fit`. ``multi_start`` repeats it from many
initial guesses through any ``concurrent.futures`` executor (the paper's
Fig. 3) and ``plot_multi_start`` draws the scatter plots.

Units SI throughout (Pa, Hz, m/s, kg/m^3).
"""
from __future__ import annotations

import json
import math
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from engine.fit import (DataBlock, Estimate, IdentificationError, Prior, bayesian_update, checks, estimate,
                        nelder_mead_fit)
from engine.forward import modal_block, wave_block
from engine.laminate import PhysicsError

from . import threads
from .errors import UserError
from .features import read_features, specimen_of, validate_features
from .specimen import Specimen, load_specimen

__all__ = ["Problem", "load_problem", "problem_from_features", "default_params", "parse_assignments",
           "identify", "run", "multi_start", "random_starts", "plot_multi_start", "METHODS",
           "identify_variants", "synthetic_features", "load_features",
           "DEFAULT_MODAL_SIGMA_REL", "DEFAULT_WAVE_SIGMA_REL"]

METHODS = ("lm", "bayes", "nelder-mead")
#: sigmas assumed when a features file gives none (relative to the value)
DEFAULT_MODAL_SIGMA_REL = 1e-3
DEFAULT_WAVE_SIGMA_REL = 1e-2


@dataclass
class Problem:
    """Everything needed to estimate: specimen, data blocks and bookkeeping."""

    specimen: Specimen
    blocks: list[DataBlock]
    material: str
    modal_forward: Any = None
    source: str = "<features>"
    notes: list[str] = field(default_factory=list)

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
# reading the features document
# ---------------------------------------------------------------------------
def _array(doc: Mapping, key: str, src: str, where: str, *, positive=True) -> np.ndarray:
    if key not in doc:
        raise UserError("missing key; expected a list of numbers", file=src, key=where + key)
    try:
        a = np.asarray(doc[key], dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"value {doc[key]!r:.60}: expected a list of numbers", file=src, key=where + key) from None
    if a.ndim == 0:
        a = a[None]
    if a.ndim != 1 or a.size == 0:
        raise UserError("expected a non-empty list of numbers", file=src, key=where + key)
    if positive and not np.all(np.isfinite(a) & (a > 0) | np.isnan(a)):
        raise UserError("expected positive values", file=src, key=where + key)
    return a


def _sigma(doc: Mapping, key: str, values: np.ndarray, default_rel: float, src: str, where: str,
           notes: list[str]) -> np.ndarray:
    if key not in doc or doc[key] is None:
        notes.append(f"{where}{key} absent: assuming {default_rel:.1%} of the values")
        return default_rel * values
    s = _array(doc, key, src, where)
    if s.size == 1:
        s = np.full(values.shape, s[0])
    if s.shape != values.shape:
        raise UserError(f"{s.size} values: expected one or {values.size}", file=src, key=where + key)
    return s


def _specimen(doc: Mapping, base: Path, src: str) -> Specimen:
    return specimen_of(doc, base, src)


def load_features(path: str | Path) -> dict:
    """Read and validate a features JSON file (``labid.features``)."""
    return read_features(path)


def _nan_to_null(v: Any) -> Any:
    """JSON view of a (possibly already validated) document: NaN -> None."""
    if isinstance(v, Mapping):
        return {k: _nan_to_null(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_nan_to_null(x) for x in v]
    if isinstance(v, np.ndarray):
        return _nan_to_null(v.tolist())
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


def problem_from_features(doc: Mapping, *, base_dir: str | Path = ".", src: str = "<features>",
                          specimen: Specimen | None = None, material: str | None = None,
                          modal_model=None) -> Problem:
    """Data blocks for whatever the features hold (modal, waves or both).

    Accelerometer masses of ``rig.accelerometers`` are added to the plate
    model as point masses. Wave points with a NaN group velocity are dropped.
    ``modal_model`` may pass a prebuilt ``PlateModel`` (same specimen).
    """
    notes: list[str] = []
    doc = validate_features(_nan_to_null(doc), src)
    spec = specimen if specimen is not None else _specimen(doc, Path(base_dir), src)
    mats = spec.laminate.materials
    if material is None:
        if len(mats) != 1:
            raise UserError(f"laminate has materials {sorted(mats)}; expected a single material",
                            file=src, key="specimen")
        material = next(iter(mats))
    blocks: list[DataBlock] = []
    fwd = None
    modal = doc.get("modal")
    if modal:
        if not isinstance(modal, Mapping):
            raise UserError("expected an object", file=src, key="modal")
        f = _array(modal, "frequencies_hz", src, "modal.")
        if np.any(np.isnan(f)):
            raise UserError("expected finite frequencies", file=src, key="modal.frequencies_hz")
        sig = _sigma(modal, "sigma_hz", f, DEFAULT_MODAL_SIGMA_REL, src, "modal.", notes)
        points = shapes = None
        ms = modal.get("mode_shapes")
        if ms:
            try:
                points = np.asarray(ms["points"], float)
                shapes = np.asarray(ms["values"], float)
            except (KeyError, TypeError, ValueError):
                raise UserError("expected {points: [[x, y], ...], values: [[...], ...]}", file=src,
                                key="modal.mode_shapes") from None
            if points.ndim != 2 or points.shape[1] != 2 or shapes.shape != (f.size, len(points)):
                raise UserError(f"values of shape {shapes.shape}: expected ({f.size}, {len(points)}) "
                                "with points [[x, y], ...]", file=src, key="modal.mode_shapes")
        if modal_model is None:
            from engine.plate_fe import PlateModel  # noqa: PLC0415
            try:
                modal_model = PlateModel.build(spec.laminate, spec.length, spec.width)
            except PhysicsError as e:
                raise UserError(str(e), file=src, key="specimen") from None
            acc = (doc.get("rig") or {}).get("accelerometers") or []
            masses = [(a["x"], a["y"], a["mass_kg"]) for a in acc
                      if isinstance(a, Mapping) and a.get("mass_kg")]
            if masses:
                modal_model = modal_model.with_point_masses(masses)
                notes.append(f"modal model includes {len(masses)} accelerometer mass(es)")
        try:
            blk, fwd = modal_block(modal_model, f, sig, points=points, shapes=shapes, material=material)
        except IdentificationError as e:
            raise UserError(str(e), file=src, key="modal") from None
        blocks.append(blk)
    waves = doc.get("waves")
    if waves:
        if not isinstance(waves, list):
            raise UserError("expected a list of wave records", file=src, key="waves")
        for i, w in enumerate(waves):
            where = f"waves[{i}]."
            if not isinstance(w, Mapping):
                raise UserError("expected an object", file=src, key=f"waves[{i}]")
            fr = _array(w, "frequency_hz", src, where)
            cg = _array(w, "group_velocity_m_s", src, where)
            if fr.shape != cg.shape:
                raise UserError(f"{cg.size} velocities for {fr.size} frequencies: expected equal lengths",
                                file=src, key=where + "group_velocity_m_s")
            sig = _sigma(w, "sigma_m_s", cg, DEFAULT_WAVE_SIGMA_REL, src, where, notes)
            ok = np.isfinite(fr) & np.isfinite(cg) & np.isfinite(sig)
            if not ok.all():
                notes.append(f"{where}: {int((~ok).sum())} point(s) without a velocity dropped")
            if ok.sum() == 0:
                continue
            mode = str(w.get("mode", "A0"))
            d = float(w.get("direction_deg", 0.0))
            blocks.append(wave_block(spec.laminate, fr[ok], cg[ok], sig[ok], mode=mode, direction_deg=d,
                                     material=material, name=f"waves[{i}]:{mode}@{d:g}deg"))
    if not blocks:
        raise UserError("no modal frequencies and no wave velocities: nothing to identify",
                        file=src, key="modal/waves")
    return Problem(spec, blocks, material, fwd, src, notes)


def load_problem(path: str | Path) -> Problem:
    """Problem from a features JSON file (specimen path relative to it)."""
    p = Path(path)
    return problem_from_features(load_features(p), base_dir=p.parent, src=str(p))


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


def _start(problem: Problem, names: Sequence[str], start: Mapping[str, float] | None) -> dict[str, float]:
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
    st = _start(problem, names, start)
    if method not in METHODS:
        raise UserError(f"method {method!r}: expected one of {list(METHODS)}", key="--method")
    if problem.modal_forward is not None:
        problem.modal_forward.reset_tracking()
    try:
        if method == "lm":
            est = estimate(problem.blocks, names, st, prior=prior, max_iter=max_iter)
        elif method == "bayes":
            est = bayesian_update(problem.blocks, names, st,
                                  prior_rel_std=0.5 if prior is None else prior, max_iter=max_iter)
        else:
            est = nelder_mead_fit(problem.blocks, names, st, prior=prior)
    except IdentificationError as e:
        raise UserError(str(e), file=problem.source) from None
    scale_notes: list[str] = []
    if scale_sigmas and method == "lm":
        est, scale_notes = checks.birge_refit(problem.blocks, est, names, st, prior, max_iter)
    if consistency and method == "lm" and len(problem.kinds) > 1:
        scale_notes += checks.consistency(problem.blocks, est, names, prior, max_iter)
    warnings = list(est.warnings) + list(problem.notes) + scale_notes
    chi2 = sum(r["chi2"] for r in est.residuals.values())
    n = sum(r["n"] for r in est.residuals.values())
    if chi2 > 10.0 * n:
        warnings.append(f"poor fit: chi^2/n = {chi2 / n:.3g} (expected ~1 with the stated sigmas): "
                        "a local minimum, or a model/data mismatch (see labid diagnose)")
    if problem.modal_forward is not None:
        warnings += problem.modal_forward.warnings
    return replace(est, warnings=tuple(warnings))


def identify(features: str | Path | Mapping, names: Sequence[str] | None = None,
             start: Mapping[str, float] | None = None, **kw) -> Estimate:
    """Features file (path) or document (mapping, specimen inline or by path) -> Estimate."""
    if isinstance(features, Mapping):
        problem = problem_from_features(features)
    else:
        problem = load_problem(features)
    return run(problem, names, start, **kw)


# ---------------------------------------------------------------------------
# multi-start study (paper Fig. 3)
# ---------------------------------------------------------------------------
_WORKER_CACHE: dict[str, Problem] = {}


def _job(spec: tuple) -> dict:
    """One start of a multi-start study (runs in a worker process)."""
    key, doc, specimen, names, start, method, prior, n_threads = spec
    threads.worker_init(n_threads)   # Dask workers start with their own settings
    problem = _WORKER_CACHE.get(key)
    if problem is None:
        problem = problem_from_features(doc, specimen=specimen)
        _WORKER_CACHE.clear()
        _WORKER_CACHE[key] = problem
    try:
        # no data-set consistency check: it only adds a warning (not returned here)
        # at the cost of one extra fit per data set
        est = run(problem, names, start, method=method, prior=prior, consistency=False)
    except UserError as e:  # a start that is unphysical: record, do not stop the study
        return {"start": dict(start), "error": str(e)}
    chi2 = sum(r["chi2"] for r in est.residuals.values())
    n = sum(r["n"] for r in est.residuals.values())
    return {"start": dict(start), "values": est.params, "std": dict(zip(est.names, est.std.tolist())),
            "converged": est.converged, "chi2_per_point": chi2 / n, "iterations": est.iterations,
            "residual": est.residual_summary(), "seconds": est.seconds}


def random_starts(nominal: Mapping[str, float], names: Sequence[str], n: int, *,
                  spread: float | Mapping[str, tuple[float, float]] = 0.5, seed: int = 0,
                  problem: Problem | None = None) -> list[dict[str, float]]:
    """``n`` random initial guesses: log-uniform within a factor (1 +- spread) of
    nominal, or uniform within explicit ``{name: (low, high)}`` bounds. With
    ``problem``, unphysical draws (e.g. G < E/3 for an isotropic plate) are
    redrawn."""
    rng = np.random.default_rng(seed)
    out: list[dict[str, float]] = []
    for _ in range(100 * n):
        if len(out) == n:
            break
        st = {}
        for nm in names:
            if isinstance(spread, Mapping):
                lo, hi = spread[nm]
                st[nm] = float(rng.uniform(lo, hi))
            else:
                st[nm] = float(nominal[nm] * np.exp(rng.uniform(np.log(1 - spread), np.log(1 + spread))))
        if problem is not None:
            try:
                _start(problem, names, st)
            except UserError:
                continue
        out.append(st)
    return out


def multi_start(doc: Mapping, starts: Sequence[Mapping[str, float]], names: Sequence[str], *,
                specimen: Specimen | None = None, base_dir: str | Path = ".", method: str = "lm",
                prior: float | None = None, executor: Executor | None = None,
                max_workers: int = 2) -> list[dict]:
    """Run the estimate from every start, in parallel through ``executor``.

    ``executor`` is any ``concurrent.futures.Executor`` (for instance a Dask
    ``Client.get_executor()``); by default a ``ProcessPoolExecutor`` with
    ``max_workers`` processes. Each worker builds the forward models once and
    reuses them for its starts. Returns one dict per start, in order.
    """
    spec = specimen if specimen is not None else _specimen(doc, Path(base_dir), "<features>")
    doc = dict(doc)
    doc.pop("specimen", None)
    key = json.dumps(doc, sort_keys=True, default=str) + repr(spec)
    # one BLAS thread per worker process unless the user said otherwise (labid.threads)
    n_threads = threads.for_workers()
    jobs = [(key, doc, spec, tuple(names), dict(s), method, prior, n_threads) for s in starts]
    if executor is not None:
        return list(executor.map(_job, jobs))
    if max_workers <= 1:
        return [_job(j) for j in jobs]
    with ProcessPoolExecutor(max_workers=max_workers, initializer=threads.worker_init,
                             initargs=(n_threads,)) as ex:
        # one start per task: starts differ in cost (local minima take 2x longer), so
        # larger chunks leave a worker idle at the end; a task costs ~1 ms to send
        return list(ex.map(_job, jobs, chunksize=1))


def plot_multi_start(results: Sequence[Mapping], names: Sequence[str], path: str | Path, *,
                     truth: Mapping[str, float] | None = None, title: str = "") -> Path:
    """Scatter of each identified parameter (and its start) against the start
    number, one panel per parameter (paper Fig. 3). PNG/PDF by extension."""
    import matplotlib  # noqa: PLC0415
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    k = len(names)
    cols = min(3, k)
    rows = math.ceil(k / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.0 * rows), squeeze=False)
    idx = np.arange(1, len(results) + 1)
    for ax, n in zip(axes.ravel(), names):
        unit, scale = ("", 1.0) if n.startswith("nu") else (("kg/m$^3$", 1.0) if n == "density" else ("GPa", 1e-9))
        st = np.array([r["start"].get(n, np.nan) for r in results]) * scale
        val = np.array([r.get("values", {}).get(n, np.nan) for r in results]) * scale
        ok = np.array([bool(r.get("converged")) for r in results])
        ax.plot(idx, st, "x", color="0.6", ms=4, label="start")
        ax.plot(idx[ok], val[ok], "o", color="C0", ms=4, label="identified")
        if (~ok).any():
            ax.plot(idx[~ok], val[~ok], "o", mfc="none", color="C3", ms=4, label="not converged")
        if truth and n in truth:
            ax.axhline(truth[n] * scale, color="k", lw=0.8, ls="--", label="true")
        ax.set_xlabel("start number")
        ax.set_ylabel(f"{n} [{unit}]" if unit else n)
    for ax in axes.ravel()[k:]:
        ax.set_visible(False)
    axes.ravel()[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------
# synthetic features (tests, benchmarks, demo)
# ---------------------------------------------------------------------------
def synthetic_features(specimen: str | Specimen = "cfrp", *, n_modes: int | None = 10,
                       modal_sigma_rel: float = DEFAULT_MODAL_SIGMA_REL,
                       waves: Sequence[tuple[str, float, float, int]] = (("A0", 0.0, 200e3, 20),),
                       wave_sigma_rel: float = DEFAULT_WAVE_SIGMA_REL, noise: bool = False,
                       seed: int = 0, with_shapes: bool = False, params: Mapping[str, float] | None = None,
                       modal_model=None) -> dict:
    """A features document computed by the forward models (CONTRACT section 2).

    ``waves``: (mode, direction_deg, fmax_hz, n) records on the grid
    ``f_i = i fmax / n``. With ``noise``, Gaussian noise of the stated sigmas
    is added (seeded). ``params`` changes the true constants. The specimen is
    inlined as the built-in name when given by name.
    """
    spec = load_specimen(specimen) if isinstance(specimen, str) else specimen
    lam = spec.laminate
    if params:
        lam = lam.with_params(dict(params))
    rng = np.random.default_rng(seed)
    doc: dict = {"specimen": specimen if isinstance(specimen, str) else None}
    if n_modes:
        from engine.plate_fe import PlateModel  # noqa: PLC0415
        model = modal_model or PlateModel.build(spec.laminate, spec.length, spec.width)
        modes = model.solve(n_modes, params=dict(params) if params else None)
        f = modes.frequencies_hz
        sig = modal_sigma_rel * f
        doc["modal"] = {"frequencies_hz": (f + (sig * rng.standard_normal(f.size) if noise else 0)).tolist(),
                        "sigma_hz": sig.tolist()}
        if with_shapes:
            pts = np.array([[x, y] for x in np.linspace(0.1, 0.9, 4) * spec.length
                            for y in np.linspace(0.1, 0.9, 4) * spec.width])
            doc["modal"]["mode_shapes"] = {"points": pts.tolist(),
                                           "values": model.shapes_at(modes, pts).tolist()}
    if waves:
        from engine.safe import group_velocity  # noqa: PLC0415
        doc["waves"] = []
        for mode, d, fmax, n in waves:
            fr = np.arange(1, n + 1) * fmax / n
            cg = group_velocity(lam, fr, mode=mode, direction_deg=d)
            sig = wave_sigma_rel * cg
            doc["waves"].append({"mode": mode, "direction_deg": d, "frequency_hz": fr.tolist(),
                                 "group_velocity_m_s": (cg + (sig * rng.standard_normal(n) if noise else 0)).tolist(),
                                 "sigma_m_s": sig.tolist()})
    return doc


def identify_variants(doc: Mapping, *, specimen: Specimen | None = None, base_dir: str | Path = ".",
                      start: Mapping[str, float] | None = None, modal_model=None, method: str = "lm",
                      prior: float | None = None) -> dict[str, Estimate]:
    """Modal only, waves only and combined estimates from one features document
    (each with its default parameters; only the variants the data allow).

    ``start`` values are used for the parameters each variant identifies.
    Returns ``{"modal": Estimate, "waves": Estimate, "combined": Estimate}``.
    """
    spec = specimen if specimen is not None else _specimen(validate_features(doc), Path(base_dir), "<features>")
    has_modal, has_waves = bool(doc.get("modal")), bool(doc.get("waves"))
    variants = {}
    if has_modal:
        variants["modal"] = {k: v for k, v in doc.items() if k != "waves"}
    if has_waves:
        variants["waves"] = {k: v for k, v in doc.items() if k != "modal"}
    if has_modal and has_waves:
        variants["combined"] = dict(doc)
    out: dict[str, Estimate] = {}
    for name, d in variants.items():
        prob = problem_from_features(d, specimen=spec, modal_model=modal_model)
        if prob.modal_forward is not None and modal_model is None:
            modal_model = prob.modal_forward.model     # build the plate model once
        names = default_params(prob)
        st = {k: v for k, v in (start or {}).items() if k in names}
        out[name] = run(prob, names, st, method=method, prior=prior)
    return out
