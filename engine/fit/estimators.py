"""Estimators of the elastic constants over :class:`~engine.fit.problem.DataBlock` s.

* :func:`estimate` -- Levenberg-Marquardt on the whitened residuals
  ``(y_model - y) / sigma`` of all blocks at once (the combined misfit), with
  an optional Gaussian prior on the fitted parameters. Parameters are fitted
  as logarithms (``space="log"``, kept positive) or as ratios to the start
  (``space="linear"``). Blocks without an analytic Jacobian (SAFE) get
  forward differences with Broyden updates in between; a weak or absent
  prior is approached by continuation from a firmer one; convergence is
  judged on the Newton decrement, with the forward models' own noise floor
  (the iterations: :mod:`engine.fit.lm`).
* :func:`bayesian_update` -- the Lai & Ip update of the paper (Eqs. 15-20):
  ``p = p0 + (C_P + S^T C_R S)^-1 S^T C_R (r~ - r - S (p0 - p))`` iterated to
  convergence, with a step control (step halving on a cost increase and a
  bound on the relative step).
* :func:`nelder_mead_fit` -- the paper's high-frequency estimator: minimise
  the relative misfit of Eq. 29, ``sum(((y - y_model) / y_model)^2)``, with
  scipy's Nelder-Mead on log-parameters.

Every estimator returns an :class:`~engine.fit.uncertainty.Estimate`.
"""
from __future__ import annotations

import math
import time
from typing import Callable, Mapping, Sequence

import numpy as np

from .lm import STALLED, levenberg_marquardt
from .problem import (Coords, DataBlock, IdentificationError, Params, Prior, Problem, check_start,
                      prior_arrays)
from .uncertainty import Estimate, finish_estimate

__all__ = ["estimate", "bayesian_update", "nelder_mead_fit", "MU_RELAXED", "STOP_CHI2"]

#: initial damping of the relaxed stage of the continuation (it starts where the firm stage
#: converged, near the minimum). Measured on the demo's features (bench/RESULTS.md, issue 29
#: session 25): from mu0 = 1e-3 the damping, cut at most 3x per accepted step, held the steps
#: along the weak directions (the held nu12, G23) short for 5-7 steps (one plate solve each)
#: that gained 0.08 of a cost of 2.4; from 1e-7 the same minimum (cost within 3e-5) in 2-3
MU_RELAXED = 1e-7
#: ``dtol`` of the identification fits (engine.identify.stages): stop when the undamped
#: Gauss-Newton step would lower the chi^2 by less than this, i.e. the constants are within
#: sqrt(1e-4) = 0.01 std (the fit's own covariance) of the minimum. At the default 1e-12 the
#: stop sat at the forward models' noise (eigenvalues to 1e-10): 1e-9 changes of the solver
#: moved the iteration count (demo features: 4 iterations, 3 with this; bench/RESULTS.md,
#: issue 29 session 26). The default stays for exact (noise-free) recoveries
STOP_CHI2 = 1e-4


def estimate(blocks: Sequence[DataBlock], names: Sequence[str], start: Params, *,
             prior: Prior | float | None = 1.0, space: str = "log", max_iter: int = 50,
             xtol: float = 1e-9, max_step: float = 0.7, rel_threshold: float = 0.1,
             dtol: float = 1e-12, mu0: float = 1e-3, continuation: bool = True, broyden: bool = True,
             callback: Callable[[dict], None] | None = None, give_up: float | None = None) -> Estimate:
    """Combined weighted least squares (Levenberg-Marquardt) with Laplace covariance.

    Minimises ``sum_b |(y_b(p) - obs_b) / sigma_b|^2 + |w (theta - theta_prior)|^2``
    over ``theta`` (log-parameters by default). ``prior`` is a :class:`Prior`,
    a number (std of log p, centred on the start; default 1.0, i.e. weak) or
    None. ``max_step`` bounds each step in theta (0.7 ~ factor 2); ``mu0`` is
    the initial Marquardt damping (relative to diag(J^T J)), updated by
    Nielsen's rule (gain ratio; factor 2, 4, 8, ... on rejected trials).
    Converged when the undamped Gauss-Newton step is below ``xtol`` in every
    coordinate or would lower the chi^2 by less than ``dtol`` (then the
    remaining error is below sqrt(dtol) standard deviations; identification of measured data
    uses STOP_CHI2). With ``continuation`` and a prior weaker than 0.3 (or none),
    the fit is first converged loosely with the prior firmed to 0.3, and the
    prior is then relaxed: nearly unidentifiable directions cannot run away
    while the well-identified ones are still far from their values. With
    ``broyden``, blocks without analytic Jacobian (finite differences) get
    rank-one Broyden updates between fresh difference Jacobians (refreshed
    when steps fail and always before declaring convergence). ``give_up``: a chi^2 above
    which a stalled descent stops early, not converged (``engine.fit.lm.STALLED``: a
    candidate start in the wrong basin need not be fitted to the end).
    """
    t0 = time.perf_counter()
    p_start = check_start(names, start)
    coords = Coords(names, p_start, space)
    prob = Problem(blocks, coords)
    tp, w = prior_arrays(prior, coords, p_start)
    theta = coords.theta(p_start)

    history: list[dict] = []
    warnings: list[str] = []
    # continuation: with a weak (or no) prior, first converge with a firmer one
    # so that nearly unidentifiable directions cannot run away, then relax it.
    stages = [w]
    if continuation and np.any(w < 1.0 / 0.3):
        firm = np.maximum(w, 1.0 / 0.3)
        stages = [firm, w]
    total_it, converged, message = 0, False, ""
    for si, ws in enumerate(stages):
        last = si == len(stages) - 1
        theta, converged, n_it, message = levenberg_marquardt(prob, theta, tp, ws, xtol if last else max(xtol, 1e-3),
                                              dtol if last else -1.0,
                                              max_iter - total_it, max_step, mu0 if si == 0 else min(mu0, MU_RELAXED),
                                              history, total_it,
                                              callback, broyden, None if give_up is None else 0.5 * give_up)
        total_it += n_it
        if total_it >= max_iter or message == STALLED:
            break
    return finish_estimate(prob, theta, tp, w, converged, total_it, history, dict(zip(names, p_start)),
                   f"levenberg-marquardt/{space}", message, warnings, t0, rel_threshold)



# ---------------------------------------------------------------------------
# Lai & Ip Bayesian update (paper Eqs. 15-20)
# ---------------------------------------------------------------------------
def bayesian_update(blocks: Sequence[DataBlock], names: Sequence[str], start: Params, *,
                    prior_rel_std: float | Mapping[str, float] = 0.5, max_iter: int = 50,
                    xtol: float = 1e-9, max_rel_step: float = 0.5,
                    rel_threshold: float = 0.1) -> Estimate:
    """Iterated Bayesian update of Lai & Ip (paper Eq. 20) with step control.

    ``p0`` is the start (the prior mean), ``C_P = diag(1/delta^2(p0))`` with
    ``delta(p0) = prior_rel_std * p0``; ``C_R = diag(1/sigma^2)`` from the
    blocks' sigmas (the paper's r are eigenvalues: pass blocks in
    eigenvalues with sigma_lambda = 2 lambda sigma_f / f, or frequencies; the
    update is the same to first order). Parameters are scaled by p0
    (theta = p / p0) for conditioning. Each update
    ``p = p0 + (C_P + S^T C_R S)^-1 S^T C_R (r~ - r - S (p0 - p))`` is taken as a
    direction from the current p; the step is halved while it raises
    ``e(r, p)`` (Eq. 15) or leaves the physical domain, and limited to
    ``max_rel_step`` relative change per parameter.
    """
    t0 = time.perf_counter()
    p0 = check_start(names, start)
    coords = Coords(names, p0, "linear")
    prob = Problem(blocks, coords)
    if isinstance(prior_rel_std, Mapping):
        sd = np.array([float(prior_rel_std[n]) for n in names])
    else:
        sd = np.full(len(names), float(prior_rel_std))
    if np.any(~(sd > 0)):
        raise IdentificationError("prior_rel_std must be positive (C_P = diag(1/delta^2))")
    CP = np.diag(1.0 / sd ** 2)          # in theta = p/p0 units
    theta0 = np.ones(len(names))
    w = 1.0 / sd

    def e_cost(th: np.ndarray) -> float:
        r = prob.residual(th)
        return float(r @ r + ((th - theta0) * w) @ ((th - theta0) * w))

    theta = theta0.copy()
    cost = e_cost(theta)
    history = [{"iteration": 0, "cost": cost, "params": coords.as_dict(theta)}]
    converged, message, it = False, "maximum iterations reached", 0
    for it in range(1, max_iter + 1):
        preds, jacs = prob.block_jacobians(theta)
        S = np.vstack(jacs)                                       # whitened: C_R^(1/2) S
        rt = np.concatenate([(b.observed - y) / b.sigma for b, y in zip(prob.blocks, preds)])
        # Eq. 20 (whitened):  theta_new = theta0 + (CP + S^T S)^-1 S^T (r~ - r - S (theta0 - theta))
        theta_new = theta0 + np.linalg.solve(CP + S.T @ S, S.T @ (rt - S @ (theta0 - theta)))
        step = theta_new - theta
        big = np.max(np.abs(step) / np.abs(theta))
        if big > max_rel_step:
            step *= max_rel_step / big
        lam, accepted = 1.0, False
        for _ in range(40):
            trial = theta + lam * step
            try:
                c_new = e_cost(trial) if np.all(trial > 0) else math.inf
            except ValueError:
                c_new = math.inf
            if c_new <= cost:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            converged = float(np.max(np.abs(step))) < 1e3 * xtol
            message = "step control: no decrease of e(r, p)"
            break
        dmax = float(np.max(np.abs(lam * step)))
        theta, cost = trial, c_new
        history.append({"iteration": it, "cost": cost, "params": coords.as_dict(theta),
                        "step": dmax, "step_factor": lam})
        if dmax < xtol:
            converged, message = True, "step below tolerance"
            break
    return finish_estimate(prob, theta, theta0, w, converged, it, history, dict(zip(names, p0)),
                   "bayesian-update (Lai & Ip, Eq. 20)", message, [], t0, rel_threshold)


# ---------------------------------------------------------------------------
# Nelder-Mead on the relative misfit (paper Eq. 29)
# ---------------------------------------------------------------------------
def nelder_mead_fit(blocks: Sequence[DataBlock], names: Sequence[str], start: Params, *,
                    xatol: float = 1e-7, fatol: float = 1e-16, max_iter: int = 2000,
                    initial_simplex_step: float = 0.1, rel_threshold: float = 0.1,
                    prior: Prior | float | None = None) -> Estimate:
    """The paper's estimator: minimise Eq. 29, ``c = sum(((y - y_model)/y_model)^2)``.

    Nelder-Mead (scipy) on log-parameters (scaled and positive). Unphysical
    trial points cost +inf. The uncertainty reported is still the Laplace
    covariance of the sigma-whitened problem at the minimum (``prior`` as in
    :func:`estimate`, default none).
    """
    # here, not at the top: scipy.optimize costs ~0.15-0.3 s CPU to import and the default
    # (Levenberg-Marquardt) path does not use it (bench/RESULTS.md, issue 29 session 27)
    from scipy.optimize import minimize  # noqa: PLC0415

    t0 = time.perf_counter()
    p_start = check_start(names, start)
    coords = Coords(names, p_start, "log")
    prob = Problem(blocks, coords)
    history: list[dict] = []

    def c(th: np.ndarray) -> float:
        try:
            preds = prob.predict(th)
        except ValueError:
            return math.inf
        return float(sum(np.sum(((b.observed - y) / y) ** 2) for b, y in zip(prob.blocks, preds)))

    def cb(xk: np.ndarray) -> None:
        history.append({"iteration": len(history) + 1, "params": coords.as_dict(xk)})

    k = len(names)
    sim = np.vstack([np.zeros(k)] + [initial_simplex_step * np.eye(k)[i] for i in range(k)])
    res = minimize(c, np.zeros(k), method="Nelder-Mead", callback=cb,
                   options={"xatol": xatol, "fatol": fatol, "maxiter": max_iter,
                            "maxfev": 4 * max_iter, "initial_simplex": sim})
    for h in history:
        h["cost"] = None
    history.insert(0, {"iteration": 0, "params": dict(zip(names, map(float, p_start))), "cost": None})
    tp, w = prior_arrays(prior, coords, p_start)
    return finish_estimate(prob, res.x, tp, w, bool(res.success), int(res.nit), history,
                   dict(zip(names, p_start)), "nelder-mead (Eq. 29)", str(res.message), [], t0,
                   rel_threshold)
