"""Estimation of elastic constants from measured data, with uncertainty.

Generic over forward models: every data set is a :class:`DataBlock` holding
observations ``y`` (any unit), their standard deviations ``sigma`` and a
forward function ``predict(params) -> y_model`` (optionally with an analytic
Jacobian). Parameters are plain dicts ``{name: value}`` in SI units.

Estimators
----------
* :func:`estimate` -- Levenberg-Marquardt on the whitened residuals
  ``(y_model - y) / sigma`` of all blocks at once (the combined misfit), with
  an optional Gaussian prior on the fitted parameters. Parameters are fitted
  as logarithms (``space="log"``, kept positive) or as ratios to the start
  (``space="linear"``). Blocks without an analytic Jacobian (SAFE) get
  forward differences with Broyden updates in between; a weak or absent
  prior is approached by continuation from a firmer one; convergence is
  judged on the Newton decrement, with the forward models' own noise floor.
* :func:`bayesian_update` -- the Lai & Ip update of the paper (Eqs. 15-20):
  ``p = p0 + (C_P + S^T C_R S)^-1 S^T C_R (r~ - r - S (p0 - p))`` iterated to
  convergence, with a step control (step halving on a cost increase and a
  bound on the relative step).
* :func:`nelder_mead_fit` -- the paper's high-frequency estimator: minimise
  the relative misfit of Eq. 29, ``sum(((y - y_model) / y_model)^2)``, with
  scipy's Nelder-Mead on log-parameters.

Every estimator returns an :class:`Estimate`: values, standard deviations and
correlations from the Gauss-Newton (Laplace) covariance
``(J^T J + P)^-1`` of the whitened problem, an identifiability report built
from the singular values of each block's whitened sensitivities, relative
residuals per block, the converged flag and the iteration history.
:mod:`engine.identify_models` builds the plate-FE and SAFE blocks;
:mod:`engine.identify_mcmc` samples the full posterior (emcee).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import minimize

__all__ = [
    "DataBlock", "Estimate", "IdentificationError", "Prior",
    "estimate", "bayesian_update", "nelder_mead_fit", "laplace",
    "linearised_block", "whitened_jacobian",
]

Params = Mapping[str, float]


class IdentificationError(ValueError):
    """Bad estimator input (unknown parameter, non-positive start, empty data...)."""


# ---------------------------------------------------------------------------
# data and results
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class DataBlock:
    """One data set: observations, their sigmas and a forward model.

    ``predict(params)`` returns the model values (same shape and unit as
    ``observed``). ``jacobian(params, names)``, if given, returns
    ``(predicted, dpred/dp)`` with the derivative in linear parameter units,
    shape ``(n, len(names))``; otherwise forward differences in
    log-parameters are used. ``kind`` groups blocks in the residual report
    (``"modal"`` or ``"waves"``). Forward models may raise ``ValueError``
    for unphysical parameters; the estimators then shorten the step.
    """

    name: str
    observed: np.ndarray
    sigma: np.ndarray
    predict: Callable[[Params], np.ndarray]
    jacobian: Callable[[Params, Sequence[str]], tuple[np.ndarray, np.ndarray]] | None = None
    kind: str = "data"

    def __post_init__(self) -> None:
        y = np.atleast_1d(np.asarray(self.observed, dtype=float))
        s = np.broadcast_to(np.asarray(self.sigma, dtype=float), y.shape).copy()
        if y.ndim != 1 or y.size == 0:
            raise IdentificationError(f"block {self.name!r}: expected a non-empty 1-D array of observations")
        if not np.all(np.isfinite(y)):
            raise IdentificationError(f"block {self.name!r}: observations must be finite")
        if not np.all(np.isfinite(s) & (s > 0)):
            raise IdentificationError(f"block {self.name!r}: sigmas must be positive and finite")
        object.__setattr__(self, "observed", y)
        object.__setattr__(self, "sigma", s)


@dataclass(frozen=True)
class Prior:
    """Independent Gaussian prior on the fitted coordinates.

    ``mean`` in parameter units; ``rel_std`` is the standard deviation of
    log(p) (``space="log"``) or of p / p_start (``space="linear"``): 0.5
    means roughly +-50 %. ``None`` for a parameter means no prior on it.
    """

    mean: Mapping[str, float]
    rel_std: Mapping[str, float | None]


@dataclass(frozen=True)
class Estimate:
    """Result of an estimation. Values and std in parameter units (SI)."""

    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    cov: np.ndarray
    corr: np.ndarray
    converged: bool
    iterations: int
    n_evaluations: int
    history: tuple[dict, ...]
    residuals: dict
    identifiability: dict
    start: dict
    method: str
    message: str = ""
    warnings: tuple[str, ...] = ()
    seconds: float = 0.0
    sigma_scale: dict = None  # per data kind, when sigmas were inflated (Birge ratio)

    @property
    def params(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.values)}

    @property
    def rel_std(self) -> dict[str, float]:
        return {n: float(s / abs(v)) if v else math.inf for n, v, s in zip(self.names, self.values, self.std)}

    def residual_summary(self) -> dict[str, float | None]:
        """CONTRACT residual: rms of relative residuals over modal and wave blocks."""
        out: dict[str, float | None] = {}
        for kind in ("modal", "waves"):
            rel = [r["relative"] for r in self.residuals.values() if r["kind"] == kind]
            out[f"{kind}_rms_rel"] = (float(np.sqrt(np.mean(np.concatenate(rel) ** 2)))
                                      if rel else None)
        return out

    def to_dict(self) -> dict:
        """JSON-ready summary (CONTRACT section 3 keys plus the details)."""
        return {
            "parameters": {n: {"value": float(v), "std": float(s)}
                           for n, v, s in zip(self.names, self.values, self.std)},
            "converged": bool(self.converged),
            "residual": self.residual_summary(),
            "method": self.method,
            "iterations": int(self.iterations),
            "n_evaluations": int(self.n_evaluations),
            "seconds": float(self.seconds),
            "start": dict(self.start),
            "correlation": {"names": list(self.names), "matrix": self.corr.tolist()},
            "identifiability": self.identifiability,
            "blocks": {k: {kk: (vv.tolist() if isinstance(vv, np.ndarray) else vv)
                           for kk, vv in v.items()} for k, v in self.residuals.items()},
            "warnings": list(self.warnings),
            "sigma_scale": dict(self.sigma_scale or {}),
            "message": self.message,
            "history": list(self.history),
        }


# ---------------------------------------------------------------------------
# parameter maps
# ---------------------------------------------------------------------------
class _Coords:
    """theta <-> p: log(p / scale) or p / scale, per parameter."""

    def __init__(self, names: Sequence[str], scale: np.ndarray, space: str):
        if space not in ("log", "linear"):
            raise IdentificationError(f"space={space!r}: expected 'log' or 'linear'")
        self.names, self.scale, self.space = tuple(names), np.asarray(scale, float), space

    def p(self, theta: np.ndarray) -> np.ndarray:
        return self.scale * (np.exp(theta) if self.space == "log" else theta)

    def theta(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        return np.log(p / self.scale) if self.space == "log" else p / self.scale

    def dp_dtheta(self, theta: np.ndarray) -> np.ndarray:
        return self.p(theta) if self.space == "log" else self.scale.copy()

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.p(theta))}


def _check_start(names: Sequence[str], start: Params) -> np.ndarray:
    if not names:
        raise IdentificationError("no parameters to identify")
    if len(set(names)) != len(names):
        raise IdentificationError(f"parameters {list(names)} listed twice")
    missing = [n for n in names if n not in start]
    if missing:
        raise IdentificationError(f"no start value for parameter(s) {missing}")
    p0 = np.array([float(start[n]) for n in names])
    bad = [n for n, v in zip(names, p0) if not (np.isfinite(v) and v > 0)]
    if bad:
        raise IdentificationError(f"start value of {bad} = {[start[n] for n in bad]}: expected positive finite values")
    return p0


def _prior_arrays(prior: Prior | float | None, coords: _Coords, p_start: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(theta_mean, sqrt precision) of the prior; precision 0 means none."""
    k = len(coords.names)
    if prior is None:
        return np.zeros(k), np.zeros(k)
    if isinstance(prior, (int, float)):
        prior = Prior(mean=dict(zip(coords.names, p_start)), rel_std={n: float(prior) for n in coords.names})
    mean = np.array([float(prior.mean.get(n, p)) for n, p in zip(coords.names, p_start)])
    if np.any(mean <= 0):
        raise IdentificationError("prior means must be positive")
    sd = np.array([prior.rel_std.get(n) or 0.0 for n in coords.names], float)
    if np.any(sd < 0):
        raise IdentificationError("prior rel_std must be positive")
    w = np.where(sd > 0, 1.0 / np.where(sd > 0, sd, 1.0), 0.0)
    return coords.theta(mean), w


# ---------------------------------------------------------------------------
# residuals and Jacobians
# ---------------------------------------------------------------------------
class _Problem:
    """Whitened residual vector and Jacobian over all blocks (theta coords)."""

    def __init__(self, blocks: Sequence[DataBlock], coords: _Coords, fd_step: float = 1e-5):
        if not blocks:
            raise IdentificationError("no data to fit")
        self.blocks, self.coords, self.fd_step = tuple(blocks), coords, fd_step
        self.n_eval = 0
        self._last: tuple[np.ndarray, list[np.ndarray]] | None = None
        # quasi-Newton (Broyden) state of finite-difference blocks: theta, y, dy/dtheta
        self._fd_state: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.quasi_used = False

    def predict(self, theta: np.ndarray) -> list[np.ndarray]:
        par = self.coords.as_dict(theta)
        self.n_eval += 1
        out = []
        for b in self.blocks:
            y = np.asarray(b.predict(par), float)
            if y.shape != b.observed.shape or not np.all(np.isfinite(y)):
                raise ValueError(f"block {b.name!r}: model returned {y.shape} / non-finite values")
            out.append(y)
        self._last = (np.array(theta, float), out)
        return out

    def _cached(self, theta: np.ndarray) -> list[np.ndarray] | None:
        if self._last is not None and np.array_equal(self._last[0], theta):
            return self._last[1]
        return None

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return np.concatenate([(y - b.observed) / b.sigma for b, y in zip(self.blocks, self.predict(theta))])

    def block_jacobians(self, theta: np.ndarray, quasi: bool = False
                        ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Predictions and whitened Jacobians d((y-obs)/sigma)/dtheta per block.

        Blocks without an analytic Jacobian use forward differences (backward
        at the edge of the physical domain); with ``quasi`` their previous
        Jacobian is instead updated by Broyden's rank-one formula from the
        change of predictions (no extra model evaluations).
        """
        par = self.coords.as_dict(theta)
        dpdt = self.coords.dp_dtheta(theta)
        names = self.coords.names
        preds, jacs = [], []
        fd_blocks = []
        cached = self._cached(theta)
        for i, b in enumerate(self.blocks):
            if b.jacobian is not None:
                y, dy = b.jacobian(par, names)
                y, dy = np.asarray(y, float), np.asarray(dy, float).reshape(len(b.observed), len(names))
                preds.append(y); jacs.append(dy * dpdt[None, :] / b.sigma[:, None])
            else:
                preds.append(None); jacs.append(None); fd_blocks.append(i)
        self.n_eval += 1
        self.quasi_used = False
        if not fd_blocks:
            return preds, jacs
        if cached is not None:
            base = {i: cached[i] for i in fd_blocks}
        else:
            base = {i: np.asarray(self.blocks[i].predict(par), float) for i in fd_blocks}
        if quasi and all(i in self._fd_state for i in fd_blocks):
            for i in fd_blocks:
                t0, y0, J0 = self._fd_state[i]
                dt = theta - t0
                nrm = float(dt @ dt)
                J = J0 if nrm == 0 else J0 + np.outer(base[i] - y0 - J0 @ dt, dt) / nrm
                self._fd_state[i] = (theta.copy(), base[i], J)
                preds[i] = base[i]
                jacs[i] = J / self.blocks[i].sigma[:, None]
            self.quasi_used = True
            return preds, jacs
        h = self.fd_step if self.coords.space == "log" else self.fd_step * np.abs(theta).clip(1e-3)
        h = np.broadcast_to(h, theta.shape)
        cols: dict[int, list[np.ndarray]] = {i: [] for i in fd_blocks}
        for j in range(len(theta)):
            for sgn in (1.0, -1.0):   # backward difference at the edge of the physical domain
                t = theta.copy(); t[j] += sgn * h[j]
                pj = self.coords.as_dict(t)
                self.n_eval += 1
                try:
                    ys = [np.asarray(self.blocks[i].predict(pj), float) for i in fd_blocks]
                    if not all(np.all(np.isfinite(y)) for y in ys):
                        raise ValueError("non-finite model values")
                    break
                except ValueError:
                    if sgn < 0:
                        raise
            for i, y in zip(fd_blocks, ys):
                cols[i].append((y - base[i]) / (sgn * h[j]))
        for i in fd_blocks:
            J = np.column_stack(cols[i])
            self._fd_state[i] = (theta.copy(), base[i], J)
            preds[i] = base[i]
            jacs[i] = J / self.blocks[i].sigma[:, None]
        return preds, jacs


def whitened_jacobian(blocks: Sequence[DataBlock], params: Params, names: Sequence[str],
                      space: str = "log") -> dict[str, np.ndarray]:
    """Whitened sensitivities d((y - obs)/sigma)/d theta per block at ``params``.

    With ``space="log"``, theta = log p, so column j is p_j dy/dp_j / sigma.
    """
    p = _check_start(names, params)
    coords = _Coords(names, p, space)
    prob = _Problem(blocks, coords)
    _, jacs = prob.block_jacobians(coords.theta(p))
    return {b.name: J for b, J in zip(blocks, jacs)}


def linearised_block(block: DataBlock, params: Params, names: Sequence[str],
                     observed: np.ndarray | None = None) -> DataBlock:
    """A block whose model is ``block`` linearised in log-parameters at ``params``.

    ``y(p) = y(p*) + dY/dlog p (log p - log p*)``: exact Gauss-Markov setting
    for calibration studies; ``observed`` replaces the observations.
    """
    J = whitened_jacobian([block], params, names)[block.name] * block.sigma[:, None]
    y0 = np.asarray(block.predict(dict(params)), float)
    lp0 = np.log([params[n] for n in names])

    def predict(par: Params) -> np.ndarray:
        return y0 + J @ (np.log([par[n] for n in names]) - lp0)

    def jacobian(par: Params, nm: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        idx = [list(names).index(n) for n in nm]
        pv = np.array([par[n] for n in nm])
        return predict(par), J[:, idx] / pv[None, :]

    return DataBlock(block.name, block.observed if observed is None else observed, block.sigma,
                     predict, jacobian, block.kind)


# ---------------------------------------------------------------------------
# uncertainty and identifiability
# ---------------------------------------------------------------------------
def _safe_inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric PSD matrix; null directions get infinite variance."""
    w, V = np.linalg.eigh(A)
    tol = max(w.max(initial=0.0), 0.0) * 1e-13
    inv_w = np.where(w > tol, 1.0 / np.where(w > tol, w, 1.0), np.inf)
    with np.errstate(invalid="ignore"):
        C = (V * inv_w) @ V.T
    # a parameter touching a null direction has infinite variance
    null = w <= tol
    if np.any(null):
        touched = np.any(np.abs(V[:, null]) > 1e-8, axis=1)
        C = np.where(np.isfinite(C), C, 0.0)
        C[touched, :] = np.where(np.eye(len(w), dtype=bool)[touched, :], np.inf, C[touched, :])
    return C


def laplace(jacs: Sequence[np.ndarray], prior_w: np.ndarray) -> np.ndarray:
    """Gauss-Newton (Laplace) covariance (sum J_b^T J_b + diag(w^2))^-1 in theta."""
    k = len(prior_w)
    A = np.diag(prior_w ** 2).astype(float)
    for J in jacs:
        A = A + J.T @ J
    return _safe_inverse(A) if k else np.zeros((0, 0))


def _identifiability(names: Sequence[str], blocks: Sequence[DataBlock], jacs: Sequence[np.ndarray],
                     prior_w: np.ndarray, cov_theta: np.ndarray, rel_threshold: float) -> dict:
    """Which data set constrains which parameter.

    Per parameter: the marginal relative std and the conditional one (if all
    the other parameters were known: 1/sqrt of the diagonal information), so
    that a parameter the data see but cannot separate from another shows a
    small conditional and a large marginal std. For each data set (blocks of
    one kind: modal, waves) alone, with the prior, the posterior std of each
    coordinate. A data set "constrains" a parameter when alone it gives a std
    below ``rel_threshold`` (and below half the prior std), or when the
    parameter is identified and leaving that data set out would more than
    double its std. Singular values per block and per data set. Singular values of the
    whitened block Jacobians and the weakest combined direction are reported.
    """
    std_all = np.sqrt(np.diag(cov_theta))
    info = sum((J.T @ J for J in jacs), np.diag(prior_w ** 2))
    with np.errstate(divide="ignore"):
        cond_std = 1.0 / np.sqrt(np.diag(info))
    per_block: dict[str, dict] = {}
    prior_sd = np.where(prior_w > 0, 1.0 / np.where(prior_w > 0, prior_w, 1.0), np.inf)
    for b, J in zip(blocks, jacs):
        per_block[b.name] = {
            "kind": b.kind,
            "singular_values": np.linalg.svd(J, compute_uv=False).tolist(),
            "rel_std": {n: float(v) for n, v in zip(names, np.sqrt(np.diag(laplace([J], prior_w))))},
        }
    # data sets = blocks grouped by kind (all wave records together, ...)
    constrained: dict[str, list[str]] = {n: [] for n in names}
    per_kind: dict[str, dict] = {}
    for kind in dict.fromkeys(b.kind for b in blocks):
        Jk = [J for b, J in zip(blocks, jacs) if b.kind == kind]
        sd = np.sqrt(np.diag(laplace(Jk, prior_w)))
        per_kind[kind] = {"singular_values": np.linalg.svd(np.vstack(Jk), compute_uv=False).tolist(),
                          "rel_std": {n: float(v) for n, v in zip(names, sd)}}
        others = [J for b, J in zip(blocks, jacs) if b.kind != kind]
        sd_wo = np.sqrt(np.diag(laplace(others, prior_w))) if others else prior_sd
        per_kind[kind]["rel_std_without"] = {n: float(v) for n, v in zip(names, sd_wo)}
        for n, v, vw, va, ps in zip(names, sd, sd_wo, std_all, prior_sd):
            alone = v < rel_threshold and v < 0.5 * ps
            needed = va < rel_threshold and vw > 2.0 * va
            if alone or needed:
                constrained[n].append(kind)
    Jall = np.vstack(list(jacs)) if jacs else np.zeros((0, len(names)))
    _, s, Vt = np.linalg.svd(Jall, full_matrices=False)
    weakest = {n: float(v) for n, v in zip(names, Vt[-1])} if len(s) else {}
    params = {}
    for j, n in enumerate(names):
        params[n] = {
            "rel_std": float(std_all[j]),
            "conditional_rel_std": float(cond_std[j]),
            "identified": bool(std_all[j] < rel_threshold),
            "constrained_by": constrained[n],
        }
    return {
        "rel_threshold": rel_threshold,
        "parameters": params,
        "data_sets": per_kind,
        "blocks": per_block,
        "singular_values": s.tolist(),
        "condition_number": float(s[0] / s[-1]) if len(s) and s[-1] > 0 else math.inf,
        "weakest_direction": weakest,
        "poorly_identified": [n for n in names if not params[n]["identified"]],
    }


def _finish(prob: _Problem, theta: np.ndarray, prior_mean: np.ndarray, prior_w: np.ndarray,
            converged: bool, iterations: int, history: list[dict], start: Params, method: str,
            message: str, warnings: Sequence[str], t0: float, rel_threshold: float) -> Estimate:
    coords = prob.coords
    preds, jacs = prob.block_jacobians(theta)
    cov_t = laplace(jacs, prior_w)
    d = coords.dp_dtheta(theta)
    with np.errstate(invalid="ignore"):
        cov = cov_t * np.outer(d, d)
    sd_t = np.sqrt(np.diag(cov_t))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov_t / np.outer(sd_t, sd_t)
    corr = np.where(np.isfinite(corr), corr, np.nan)
    np.fill_diagonal(corr, 1.0)
    p = coords.p(theta)
    if coords.space == "log":
        std = p * sd_t
    else:
        std = coords.scale * sd_t
    residuals = {}
    for b, y in zip(prob.blocks, preds):
        rel = (b.observed - y) / y
        w = (y - b.observed) / b.sigma
        residuals[b.name] = {"kind": b.kind, "predicted": y, "observed": b.observed,
                             "relative": rel, "rms_rel": float(np.sqrt(np.mean(rel ** 2))),
                             "chi2": float(w @ w), "n": int(len(y))}
    ident = _identifiability(coords.names, prob.blocks, jacs, prior_w, cov_t, rel_threshold)
    if coords.space == "linear":  # report relative std consistently
        for n, v, s_ in zip(coords.names, p, std):
            ident["parameters"][n]["rel_std"] = float(s_ / abs(v))
            ident["parameters"][n]["identified"] = bool(s_ / abs(v) < rel_threshold)
        ident["poorly_identified"] = [n for n in coords.names if not ident["parameters"][n]["identified"]]
    return Estimate(coords.names, p, std, cov, corr, bool(converged), iterations, prob.n_eval,
                    tuple(history), residuals, ident, dict(start), method, message,
                    tuple(warnings), time.perf_counter() - t0)


# ---------------------------------------------------------------------------
# Levenberg-Marquardt on the combined whitened misfit
# ---------------------------------------------------------------------------
def estimate(blocks: Sequence[DataBlock], names: Sequence[str], start: Params, *,
             prior: Prior | float | None = 1.0, space: str = "log", max_iter: int = 50,
             xtol: float = 1e-9, max_step: float = 0.7, rel_threshold: float = 0.1,
             dtol: float = 1e-12, mu0: float = 1e-3, continuation: bool = True, broyden: bool = True,
             callback: Callable[[dict], None] | None = None) -> Estimate:
    """Combined weighted least squares (Levenberg-Marquardt) with Laplace covariance.

    Minimises ``sum_b |(y_b(p) - obs_b) / sigma_b|^2 + |w (theta - theta_prior)|^2``
    over ``theta`` (log-parameters by default). ``prior`` is a :class:`Prior`,
    a number (std of log p, centred on the start; default 1.0, i.e. weak) or
    None. ``max_step`` bounds each step in theta (0.7 ~ factor 2); ``mu0`` is
    the initial Marquardt damping (relative to diag(J^T J)), updated by
    Nielsen's rule (gain ratio; factor 2, 4, 8, ... on rejected trials).
    Converged when the undamped Gauss-Newton step is below ``xtol`` in every
    coordinate or would lower the chi^2 by less than ``dtol`` (then the
    remaining error is below sqrt(dtol) standard deviations). With ``continuation`` and a prior weaker than 0.3 (or none),
    the fit is first converged loosely with the prior firmed to 0.3, and the
    prior is then relaxed: nearly unidentifiable directions cannot run away
    while the well-identified ones are still far from their values. With
    ``broyden``, blocks without analytic Jacobian (finite differences) get
    rank-one Broyden updates between fresh difference Jacobians (refreshed
    when steps fail and always before declaring convergence).
    """
    t0 = time.perf_counter()
    p_start = _check_start(names, start)
    coords = _Coords(names, p_start, space)
    prob = _Problem(blocks, coords)
    tp, w = _prior_arrays(prior, coords, p_start)
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
        theta, converged, n_it, message = _lm(prob, theta, tp, ws, xtol if last else max(xtol, 1e-3),
                                              dtol if last else -1.0,
                                              max_iter - total_it, max_step, mu0, history, total_it,
                                              callback, broyden)
        total_it += n_it
        if total_it >= max_iter:
            break
    return _finish(prob, theta, tp, w, converged, total_it, history, dict(zip(names, p_start)),
                   f"levenberg-marquardt/{space}", message, warnings, t0, rel_threshold)


def _gn_step(A: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, float]:
    """Undamped Gauss-Newton step and its Newton decrement (inf if not computable)."""
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(g))):
        return np.full_like(g, np.inf), np.inf
    try:
        gn = -np.linalg.lstsq(A, g, rcond=1e-14)[0]
    except np.linalg.LinAlgError:
        return np.full_like(g, np.inf), np.inf
    return gn, float(-g @ gn)


def _lm(prob: _Problem, theta: np.ndarray, tp: np.ndarray, w: np.ndarray, xtol: float, dtol: float,
        max_iter: int, max_step: float, mu0: float, history: list[dict], it0: int,
        callback=None, broyden: bool = True) -> tuple[np.ndarray, bool, int, str]:
    """Levenberg-Marquardt iterations on whitened residuals plus prior rows."""
    coords = prob.coords

    def full_residual(th: np.ndarray) -> np.ndarray:
        return np.concatenate([prob.residual(th), w * (th - tp)])

    def full_jac(th: np.ndarray, quasi: bool = False) -> tuple[np.ndarray, np.ndarray]:
        preds, jacs = prob.block_jacobians(th, quasi=quasi and broyden)
        r = np.concatenate([(y - b.observed) / b.sigma for b, y in zip(prob.blocks, preds)]
                           + [w * (th - tp)])
        return r, np.vstack(jacs + [np.diag(w)])

    r, J = full_jac(theta)
    cost = 0.5 * r @ r
    if not history:
        history.append({"iteration": 0, "cost": float(cost), "params": coords.as_dict(theta)})
    mu, stalled, stall_refreshed = mu0, 0, False
    nu = 2.0
    for it in range(1, max_iter + 1):
        A, g = J.T @ J, J.T @ r
        dmax = max(float(np.diag(A).max()), 1e-300)
        D = np.diag(np.maximum(np.diag(A), 1e-6 * dmax))
        gn, decrement = _gn_step(A, g)   # undamped GN step, expected chi^2 reduction
        # the decrement has a floor set by Jacobian errors (finite differences,
        # eigen-solver tolerance) times the misfit: allow 1e-7 chi^2 on top
        # (a remaining error of ~3e-4 sqrt(chi^2) standard deviations)
        # dtol < 0: loose stage (continuation): stop when the full GN step would
        # lower the misfit by less than half of itself
        tol = 0.5 * cost if dtol < 0 else dtol + 2e-7 * cost
        if np.max(np.abs(gn)) < xtol or decrement < tol or cost == 0.0:
            if not prob.quasi_used:
                return theta, True, it - 1, "Gauss-Newton step below tolerance"
            r, J = full_jac(theta)          # confirm with a fresh finite-difference Jacobian
            A, g = J.T @ J, J.T @ r
            gn, decrement = _gn_step(A, g)
            if np.max(np.abs(gn)) < xtol or decrement < tol:
                return theta, True, it - 1, "Gauss-Newton step below tolerance"
        # the misfit itself carries solver noise (eigen/root tolerances): when
        # accepted steps no longer lower it, stop; the fit counts as converged
        # if the full GN step would gain < 1e-3 chi^2 (~0.03 sd) more
        negligible = decrement < 1e-3 + 2e-5 * cost
        if stalled >= 2:
            if prob.quasi_used and not stall_refreshed:   # maybe a poor quasi-Newton model
                r, J = full_jac(theta)
                A, g = J.T @ J, J.T @ r
                D = np.diag(np.maximum(np.diag(A), 1e-6 * max(float(np.diag(A).max()), 1e-300)))
                gn, decrement = _gn_step(A, g)
                negligible = decrement < 1e-3 + 2e-5 * cost
                stalled, stall_refreshed = 0, True
            else:
                # last check: a line search along the GN direction; no decrease at any
                # scale means the remaining "decrement" is below the model's noise
                for t in 0.5 ** np.arange(0, 14):
                    trial = theta + t * np.clip(gn, -max_step, max_step)
                    try:
                        rt = full_residual(trial)
                    except ValueError:
                        continue
                    if 0.5 * rt @ rt < cost - 1e-8 * cost - 1e-12:
                        break
                else:
                    return theta, True, it - 1, "misfit at the noise level of the forward models"
                theta, cost, stalled, stall_refreshed = trial, 0.5 * rt @ rt, 0, False
                r, J = full_jac(theta)
                continue

        accepted = False
        for trial_no in range(40):
            if trial_no == 3 and prob.quasi_used:   # poor quasi-Newton model: refresh it
                r, J = full_jac(theta)
                A, g = J.T @ J, J.T @ r
                D = np.diag(np.maximum(np.diag(A), 1e-6 * max(float(np.diag(A).max()), 1e-300)))
            try:
                step = -np.linalg.solve(A + mu * D, g)
            except np.linalg.LinAlgError:
                mu *= 10.0
                continue
            step = np.clip(step, -max_step, max_step)   # box trust region in theta
            trial = theta + step
            try:
                r_new = full_residual(trial)
            except ValueError:  # unphysical trial point (e.g. PhysicsError)
                mu *= 10.0
                continue
            c_new = 0.5 * r_new @ r_new
            if c_new <= cost:
                accepted = True
                break
            mu *= nu           # Nielsen: growing factor over consecutive failures
            nu *= 2.0
        if not accepted:
            small = float(np.max(np.abs(gn))) < 1e3 * xtol or negligible
            return theta, small, it, "no decrease of the misfit in 40 damping trials"
        if cost - c_new <= 1e-8 * cost + 1e-12:   # gain below solver noise
            stalled += 1
        else:
            stalled, stall_refreshed = 0, False
        # Nielsen's damping update from the gain ratio rho (actual / predicted
        # decrease): a good quadratic model (rho ~ 1) lowers mu by up to 3, a
        # poor one keeps it; fewer rejected trials (model solves) than a fixed
        # /10 after every success, which oscillates in curved valleys
        pred = -(g @ step) - 0.5 * step @ (A @ step)
        rho = (cost - c_new) / pred if pred > 0 else 0.0
        mu = max(mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-12)
        nu = 2.0
        theta, cost = trial, c_new
        history.append({"iteration": it0 + it, "cost": float(cost), "params": coords.as_dict(theta),
                        "step": float(np.max(np.abs(step))), "mu": float(mu)})
        if callback:
            callback(history[-1])
        r, J = full_jac(theta, quasi=True)
    return theta, False, max_iter, "maximum iterations reached"


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
    p0 = _check_start(names, start)
    coords = _Coords(names, p0, "linear")
    prob = _Problem(blocks, coords)
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
    return _finish(prob, theta, theta0, w, converged, it, history, dict(zip(names, p0)),
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
    t0 = time.perf_counter()
    p_start = _check_start(names, start)
    coords = _Coords(names, p_start, "log")
    prob = _Problem(blocks, coords)
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
    tp, w = _prior_arrays(prior, coords, p_start)
    return _finish(prob, res.x, tp, w, bool(res.success), int(res.nit), history,
                   dict(zip(names, p_start)), "nelder-mead (Eq. 29)", str(res.message), [], t0,
                   rel_threshold)
