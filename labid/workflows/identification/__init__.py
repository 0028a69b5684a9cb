"""Identification workflow: features file or document -> estimate (the public face).

The entry points the command line, the panel and the services use:
``load_features``, ``load_problem``, ``problem_from_features``, ``run``,
``identify``, ``identify_variants``, ``default_params``, ``parse_assignments``,
``start_values``, ``random_starts``, ``multi_start``, ``plot_multi_start``,
``synthetic_features``. The work is done in :mod:`labid.workflows.identification.estimation` (problem,
defaults, estimate), :mod:`labid.workflows.identification.multistart` (multi-start studies, paper
Fig. 3), :mod:`labid.workflows.identification.synthetic` and :mod:`labid.report.plots`.

Units SI throughout (Pa, Hz, m/s, kg/m^3).
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

from engine.fit import Estimate

from .estimation import (METHODS, Problem, default_params, parse_assignments, problem_from_features,
                         result_dict, run, start_values)
from ...inputs.features import DEFAULT_MODAL_SIGMA_REL, DEFAULT_WAVE_SIGMA_REL, parse_features, read_features
from .multistart import distinct_minima, minima_summary, multi_start, random_starts
from ...report.plots import plot_multi_start
from ...inputs.specimen import Specimen
from .synthetic import synthetic_features

__all__ = ["Problem", "load_problem", "problem_from_features", "default_params", "parse_assignments",
           "identify", "run", "start_values", "METHODS", "identify_variants", "load_features",
           "multi_start", "random_starts", "plot_multi_start", "synthetic_features",
           "DEFAULT_MODAL_SIGMA_REL", "DEFAULT_WAVE_SIGMA_REL", "result_dict", "distinct_minima",
           "minima_summary"]


def load_features(path: str | Path) -> dict:
    """Read and validate a features JSON file (``labid.inputs.features``)."""
    return read_features(path)


def load_problem(path: str | Path) -> Problem:
    """Problem from a features JSON file (specimen path relative to it)."""
    p = Path(path)
    return problem_from_features(load_features(p), base_dir=p.parent, src=str(p))


def identify(features: str | Path | Mapping, names: Sequence[str] | None = None,
             start: Mapping[str, float] | None = None, **kw) -> Estimate:
    """Features file (path) or document (mapping, specimen inline or by path) -> Estimate."""
    if isinstance(features, Mapping):
        problem = problem_from_features(features)
    else:
        problem = load_problem(features)
    return run(problem, names, start, **kw)


def identify_variants(doc: Mapping, *, specimen: Specimen | None = None, base_dir: str | Path = ".",
                      start: Mapping[str, float] | None = None, modal_model=None, method: str = "lm",
                      prior: float | None = None) -> dict[str, Estimate]:
    """Modal only, waves only and combined estimates from one features document
    (each with its default parameters; only the variants the data allow).

    ``start`` values are used for the parameters each variant identifies.
    Returns ``{"modal": Estimate, "waves": Estimate, "combined": Estimate}``.
    """
    spec = specimen if specimen is not None else parse_features(doc, base_dir, "<features>").specimen
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
