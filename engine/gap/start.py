"""The estimate the diagnosis starts from: the one ``labid identify`` reports.

:class:`StartEstimate` carries what the identification decided (parameters
and their values, prior, pairing, convergence) into :func:`engine.gap.diagnose`;
the labid layer fills it from ``labid identify``'s estimator
(``labid.workflows.diagnosis.start_estimate``), so the gap test judges the same fit.
:func:`own_estimate` is the engine-only stand-in (callers without the labid
layer, e.g. tests on a coarse mesh): the same estimator identify runs by
default (``engine.fit.estimate``, maximum likelihood, log-parameters, from the
nominal constants, 60 iterations).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..fit import estimate
from .residuals import GapError, GapFit

__all__ = ["StartEstimate", "own_estimate"]


@dataclass(frozen=True)
class StartEstimate:
    """The identified constants the diagnosis starts from.

    ``names``/``params``: identified constants (SI); ``std``: their stds;
    ``prior_rel_std``: std of log p about ``prior_mean`` (None: maximum
    likelihood, identify's default); ``pairing``: ``"order"`` or ``"mac"``
    (how identify paired the measured modes) or ``"identify"`` with
    ``mode_index`` (identify's own assignment: a predicted elastic-mode index
    per peak, None for an unexplained peak); ``source``: who produced it.
    """

    names: tuple[str, ...]
    params: Mapping[str, float]
    std: Mapping[str, float]
    converged: bool
    message: str
    iterations: int = 0
    prior_rel_std: float | None = None
    prior_mean: Mapping[str, float] = field(default_factory=dict)
    pairing: str = "order"
    source: str = "engine.fit.estimate"
    warnings: tuple[str, ...] = ()
    mode_index: tuple | None = None
    #: identify's pairing findings (missing modes, unexplained peaks) for ``where``
    findings: tuple = ()
    #: identify's own verdict on its fit (``fit.consistent``)
    consistent: bool = True


def identify_pairing(modal) -> str:
    """How ``labid identify`` pairs measured modes: MAC when shapes are given, else by order."""
    return "mac" if modal is not None and modal.shapes is not None else "order"


def own_estimate(F: GapFit, names: Sequence[str] | None = None, start: Mapping[str, float] | None = None,
                 prior_rel_std: float | None = None, max_iter: int = 60) -> StartEstimate:
    """Maximum-likelihood estimate (``engine.fit.estimate``) on the blocks of ``F`` (no model
    allowance: the measured sigmas, as identify), from ``start`` (default nominal)."""
    names = tuple(names or F.names)
    nominal = F.problem.material_obj.params()
    st = {n: float((start or {}).get(n, nominal[n])) for n in names}
    try:
        est = estimate(F.blocks(raw=True), names, st, prior=prior_rel_std, max_iter=max_iter)
    except np.linalg.LinAlgError as exc:
        raise GapError(f"identification of the constants failed ({exc})") from None
    return StartEstimate(names, dict(est.params), {n: float(s) for n, s in zip(names, est.std)},
                         bool(est.converged), est.message, int(getattr(est, "iterations", 0) or 0),
                         prior_rel_std, st, identify_pairing(F.problem.modal))
