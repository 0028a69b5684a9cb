"""Uncertainty of an estimate: Laplace covariance, identifiability report, the Estimate.

Values, standard deviations and correlations come from the Gauss-Newton
(Laplace) covariance ``(J^T J + P)^-1`` of the whitened problem; the
identifiability report from the singular values of each block's whitened
sensitivities; relative residuals per block.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .problem import DataBlock, Params, Problem

__all__ = ["Estimate", "laplace", "identifiability", "finish_estimate"]


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
    fit: dict = None          # the verdict (engine.fit.checks.goodness, plus flags), when made

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
        out = {
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
        if self.fit is not None:   # the verdict (labid.workflows.identification.estimation.verdict): spread over the keys
            fit = dict(self.fit)
            ident = self.identifiability["parameters"]
            for n, d in out["parameters"].items():
                d["identified"] = bool(ident[n]["identified"])
                if not d["identified"]:
                    d["reason"] = ident[n].get("reason", "poorly identified")
            out["identified"] = bool(fit.get("identified", False))
            out["held"] = fit.pop("held", {})
            for key in ("pairing", "unpaired_modes"):
                if key in fit:
                    out[key] = fit.pop(key)
            out["fit"] = fit
        return out



def _safe_inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric PSD matrix; null directions get infinite variance."""
    w, V = np.linalg.eigh(A)
    tol = max(w.max(initial=0.0), 0.0) * 1e-13
    null = w <= tol
    # the inverse on the range (a parameter outside every null direction keeps its finite
    # variance there: inf x 0 from a null direction made it 0 before session 26)
    C = (V[:, ~null] / w[~null]) @ V[:, ~null].T
    if np.any(null):    # a parameter touching a null direction has infinite variance
        touched = np.any(np.abs(V[:, null]) > 1e-8, axis=1)
        C[touched, :] = np.where(np.eye(len(w), dtype=bool)[touched, :], np.inf, C[touched, :])
    return C


def laplace(jacs: Sequence[np.ndarray], prior_w: np.ndarray) -> np.ndarray:
    """Gauss-Newton (Laplace) covariance (sum J_b^T J_b + diag(w^2))^-1 in theta."""
    k = len(prior_w)
    A = np.diag(prior_w ** 2).astype(float)
    for J in jacs:
        A = A + J.T @ J
    return _safe_inverse(A) if k else np.zeros((0, 0))


def identifiability(names: Sequence[str], blocks: Sequence[DataBlock], jacs: Sequence[np.ndarray],
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


def finish_estimate(prob: Problem, theta: np.ndarray, prior_mean: np.ndarray, prior_w: np.ndarray,
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
    ident = identifiability(coords.names, prob.blocks, jacs, prior_w, cov_t, rel_threshold)
    if coords.space == "linear":  # report relative std consistently
        for n, v, s_ in zip(coords.names, p, std):
            ident["parameters"][n]["rel_std"] = float(s_ / abs(v))
            ident["parameters"][n]["identified"] = bool(s_ / abs(v) < rel_threshold)
        ident["poorly_identified"] = [n for n in coords.names if not ident["parameters"][n]["identified"]]
    return Estimate(coords.names, p, std, cov, corr, bool(converged), iterations, prob.n_eval,
                    tuple(history), residuals, ident, dict(start), method, message,
                    tuple(warnings), time.perf_counter() - t0)
