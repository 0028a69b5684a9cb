"""Checks of a combined estimate against its data sets (blocks grouped by ``kind``).

* :func:`birge_refit` -- a data set whose chi^2 per point is significantly
  above 1 (by more than 3 sqrt(2/n)) but below 10 has its sigmas multiplied by
  sqrt(chi^2/n) (the Birge ratio) and the fit is repeated from the estimate.
* :func:`consistency` -- each data set's own minimum (Gauss-Newton model at the
  combined estimate); a combined chi^2 above the sum of the separate minima by
  more than chance allows means the data sets disagree beyond their sigmas.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np

from .estimators import estimate
from .problem import Coords, DataBlock, IdentificationError, Prior, Problem, check_start, prior_arrays
from .chisq import chi2_sf
from .uncertainty import Estimate, laplace

__all__ = ["birge_refit", "consistency", "goodness", "scale_uncertainty", "P_CONSISTENT"]

#: a fit whose chi^2 has a p-value below this is inconsistent with its sigmas (issue 12)
P_CONSISTENT = 1e-3


def goodness(est: Estimate, excluded: int = 0, chi2: float | None = None) -> dict:
    """The fit verdict: ``chi2`` (whitened misfit of all data, prior rows excluded; or as
    given), ``dof`` (points - ``excluded`` points set aside - fitted parameters, at least
    1), ``chi2_per_dof``, ``p_value`` (chi^2 survival function) and ``consistent``
    (p >= P_CONSISTENT)."""
    if chi2 is None:
        chi2 = float(sum(r["chi2"] for r in est.residuals.values()))
    n = int(sum(r["n"] for r in est.residuals.values())) - int(excluded)
    dof = max(n - len(est.names), 1)
    p = chi2_sf(chi2, dof)
    return {"chi2": chi2, "dof": dof, "n_points": n, "chi2_per_dof": chi2 / dof, "p_value": p,
            "consistent": bool(p >= P_CONSISTENT)}


def scale_uncertainty(est: Estimate, factor: float) -> Estimate:
    """``est`` with std (and covariance) multiplied by ``factor`` (>= 1), and the
    identifiability report's relative stds with it."""
    if not factor > 1.0:
        return est
    ident = dict(est.identifiability)
    params = {}
    for n, d in ident["parameters"].items():
        d = dict(d)
        d["rel_std"] = d["rel_std"] * factor
        d["identified"] = bool(d["identified"] and d["rel_std"] < ident["rel_threshold"])
        params[n] = d
    ident["parameters"] = params
    ident["poorly_identified"] = [n for n in est.names if not params[n]["identified"]]
    return replace(est, std=est.std * factor, cov=est.cov * factor ** 2, identifiability=ident)


def birge_refit(blocks: Sequence[DataBlock], est: Estimate, names: Sequence[str],
                start: Mapping[str, float], prior: float | Prior | None, max_iter: int
                ) -> tuple[Estimate, list[str]]:
    """(Estimate refitted with Birge-scaled sigmas, notes); ``est`` unchanged when no data
    set needs it. Never shrinks sigmas; not applied to poor fits (chi^2/n >= 10)."""
    scales: dict[str, float] = {}
    for kind in dict.fromkeys(b.kind for b in blocks):
        chi2 = sum(r["chi2"] for r in est.residuals.values() if r["kind"] == kind)
        n = sum(r["n"] for r in est.residuals.values() if r["kind"] == kind)
        ratio = chi2 / n
        if 1.0 + 3.0 * math.sqrt(2.0 / n) < ratio < 10.0:
            scales[kind] = math.sqrt(ratio)
    if not scales:
        return est, []
    blocks = [replace(b, sigma=b.sigma * scales.get(b.kind, 1.0)) for b in blocks]
    if isinstance(prior, (int, float)):   # keep the prior centred on the original start
        prior = Prior(mean=dict(start), rel_std={n: float(prior) for n in names})
    est2 = estimate(blocks, names, est.params, prior=prior, max_iter=max_iter)
    est2 = replace(est2, start=dict(start), iterations=est.iterations + est2.iterations,
                   history=est.history + est2.history, sigma_scale=scales,
                   seconds=est.seconds + est2.seconds)
    notes = [f"{k}: chi^2 per point {s * s:.3g} > 1: sigmas scaled by {s:.3g} (Birge ratio) and refitted"
             for k, s in scales.items()]
    return est2, notes


def consistency(blocks: Sequence[DataBlock], est: Estimate, names: Sequence[str],
                prior: float | Prior | None, max_iter: int = 0) -> list[str]:
    """Warnings (empty or one) when the data sets disagree beyond their sigmas.

    Chi^2 test with k degrees of freedom (k = combinations every data set
    constrains), p < 0.05; the warning names the parameters the data sets pull
    apart most: the combined std is then optimistic.

    Each data set's own minimum is that of the Gauss-Newton model of its whitened
    residual at the combined estimate (with the same prior): no new nonlinear fit.
    Measured on the demo's combined identification: the two nonlinear fits it replaced
    cost 22 plate solves and 36 SAFE predictions (3.6 s CPU, 13 % of the identification);
    on data linear in log p the two are the same (tests/integration/test_identify_cli.py).
    ``max_iter`` is not used (kept for the callers).
    """
    scale = est.sigma_scale or {}
    blocks = [replace(b, sigma=b.sigma * scale.get(b.kind, 1.0)) for b in blocks]
    chi2_all = sum(r["chi2"] for r in est.residuals.values())
    try:
        p = check_start(names, est.params)
        coords = Coords(names, p, "log")
        preds, jacs = Problem(blocks, coords).block_jacobians(np.zeros(len(names)))
        tp, w = prior_arrays(prior, coords, p)
    except (IdentificationError, ValueError):
        return []
    chi2_sep, sep = 0.0, {}
    for kind in dict.fromkeys(b.kind for b in blocks):
        sel = [i for i, b in enumerate(blocks) if b.kind == kind]
        r = np.concatenate([(preds[i] - blocks[i].observed) / blocks[i].sigma for i in sel])
        J = np.vstack([jacs[i] for i in sel])
        # min |r + J d|^2 + |w (d - tp)|^2 over the log-parameter change d
        A = np.vstack([J, np.diag(w)])
        d = np.linalg.lstsq(A, -np.concatenate([r, -w * tp]), rcond=None)[0]
        chi2_sep += float(np.sum((r + J @ d) ** 2))
        sd = np.sqrt(np.diag(laplace([J], w)))      # log-parameter std of this data set alone
        sep[kind] = (d, sd)
    # degrees of freedom of the excess: the combinations every data set sees
    # (whitened singular values above 1, i.e. constrained better than a factor e)
    k = min(sum(1 for sv in est.identifiability["data_sets"][kind]["singular_values"] if sv > 1.0)
            for kind in sep)
    excess = chi2_all - chi2_sep
    if k == 0:
        return []
    pval = chi2_sf(excess, k)
    if pval >= 0.05:
        return []
    # which parameters the data sets pull apart: difference in units of the combined std
    # where: separate estimates away from the combined one, in their own marginal std
    # (only where that std is meaningful, < 50 %)
    pulls = []
    for j, n in enumerate(names):
        d = [abs(dk[j]) / sd[j] for dk, sd in sep.values() if sd[j] < 0.5]
        if d:
            pulls.append((max(d), n))
    pulls.sort(reverse=True)
    where = ", ".join(f"{n} ({d:.1f} std of one data set alone)" for d, n in pulls[:3] if d > 1
                      ) or "no single parameter"
    return [f"data sets disagree: combined chi^2 exceeds the separate fits by {excess:.3g} "
            f"(~{k} expected, p = {pval:.2g}); pulled apart: {where}; the combined std is optimistic"]
