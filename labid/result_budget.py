"""The GUM uncertainty budget of an identification result dict (the panel's).

``labid identify`` computes ``uncertainty_budget`` from its fitted problem and estimate
(``labid.budget.identify_budget``); the panel's identification (``services.
run_identification``) returns only the estimate's dict. :func:`budget_of_result`
rebuilds the fitted problem from the same features and specimen, and the estimate from
the dict (values, std, correlation, sigma scale, method), and hands them to
``labid.budget.budget_of_problem``: the same budget, same units (SI).
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from engine.fit import Estimate

from .budget import budget_of_problem
from .estimation import problem_from_features
from .specimen import Specimen

__all__ = ["estimate_of_result", "budget_of_result"]


def estimate_of_result(result: Mapping) -> Estimate:
    """The ``Estimate`` an identification dict was written from (what a budget needs:
    names, values, std, covariance = corr x std std^T, sigma scale, method)."""
    params = result["parameters"]
    names = tuple(params)
    values = np.array([float(params[n]["value"]) for n in names])
    std = np.array([float(params[n]["std"]) for n in names])
    corr_doc = result.get("correlation") or {}
    order = list(corr_doc.get("names") or names)
    m = np.asarray(corr_doc.get("matrix") if corr_doc.get("matrix") is not None else np.eye(len(names)), float)
    idx = [order.index(n) for n in names]
    corr = m[np.ix_(idx, idx)]
    cov = corr * np.outer(std, std)
    return Estimate(names, values, std, cov, corr, bool(result.get("converged")), int(result.get("iterations") or 0),
                    int(result.get("n_evaluations") or 0), (), {}, dict(result.get("identifiability") or {}),
                    dict(result.get("start") or {}), str(result.get("method") or "levenberg-marquardt"),
                    sigma_scale=dict(result.get("sigma_scale") or {}))


def budget_of_result(doc: Mapping, result: Mapping, *, specimen: Specimen | None = None,
                     base_dir: str | Path = ".", src: str = "<features>") -> dict:
    """The ``uncertainty_budget`` JSON of ``result`` identified from features ``doc``
    (``specimen`` as the identification used it; its ``[uncertainty]`` table is read from
    the specimen ``doc`` names, else the defaults apply)."""
    problem = problem_from_features(doc, base_dir=base_dir, src=src, specimen=specimen)
    return budget_of_problem(problem, estimate_of_result(result), doc, base_dir)
