"""Full posterior of the elastic constants by MCMC (emcee's affine-invariant ensemble).

The log-posterior is the same misfit the least-squares estimators minimise:
``-1/2 sum_b |(y_b(p) - obs_b)/sigma_b|^2 - 1/2 |w (log p - log p_prior)|^2``
over ``theta = log p`` (a flat prior in log p where no prior is given).
Unphysical points (the forward model raises ``ValueError``) have zero
density. Walkers start in a small Gaussian ball drawn from the Laplace
covariance of a previous :class:`~engine.fit.uncertainty.Estimate`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .problem import Coords, DataBlock, IdentificationError, Prior, Problem, prior_arrays
from .uncertainty import Estimate

__all__ = ["Posterior", "sample_posterior"]


@dataclass(frozen=True)
class Posterior:
    """MCMC samples (n, k) in parameter units (SI), after burn-in and thinning."""

    names: tuple[str, ...]
    samples: np.ndarray
    acceptance: float
    autocorr_steps: np.ndarray   # integrated autocorrelation time per parameter (steps); NaN if unreliable

    @property
    def mean(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.samples.mean(axis=0))}

    @property
    def std(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.samples.std(axis=0, ddof=1))}

    def quantiles(self, q: Sequence[float] = (0.025, 0.5, 0.975)) -> dict[str, list[float]]:
        return {n: np.quantile(self.samples[:, j], q).tolist() for j, n in enumerate(self.names)}

    def to_dict(self) -> dict:
        return {"names": list(self.names), "mean": self.mean, "std": self.std,
                "quantiles_2.5_50_97.5": self.quantiles(), "acceptance": self.acceptance,
                "autocorr_steps": self.autocorr_steps.tolist(), "n_samples": int(len(self.samples))}


def sample_posterior(blocks: Sequence[DataBlock], est: Estimate, *, prior: Prior | float | None = None,
                     n_walkers: int | None = None, n_steps: int = 1000, burn: int | None = None,
                     thin: int = 1, seed: int = 0, ball: float = 0.1) -> Posterior:
    """Sample the posterior around ``est`` (its names and values; its Laplace
    covariance, scaled by ``ball``, spreads the initial walkers).

    ``prior`` as in :func:`engine.fit.estimate`, centred on ``est.start``.
    Needs the ``emcee`` package.
    """
    try:
        import emcee  # noqa: PLC0415 - heavy, needed only for MCMC (labid identify --mcmc)
    except ImportError:  # pragma: no cover - dependency declared in pyproject
        raise IdentificationError("MCMC needs the 'emcee' package (pip install emcee)") from None
    names = tuple(est.names)
    k = len(names)
    p_start = np.array([est.start[n] for n in names])
    coords = Coords(names, p_start, "log")
    prob = Problem(blocks, coords)
    tp, w = prior_arrays(prior, coords, p_start)
    theta_hat = coords.theta(est.values)

    def log_post(th: np.ndarray) -> float:
        if not np.all(np.isfinite(th)):
            return -np.inf
        try:
            r = prob.residual(th)
        except ValueError:
            return -np.inf
        pr = w * (th - tp)
        return float(-0.5 * (r @ r + pr @ pr))

    nw = n_walkers or max(4 * k, 16)
    nw += nw % 2
    rng = np.random.default_rng(seed)
    cov_t = est.cov / np.outer(est.values, est.values)      # covariance of log p
    cov_t = np.where(np.isfinite(cov_t), cov_t, 0.0)
    sd = np.sqrt(np.clip(np.diag(cov_t), 1e-12, 1.0))
    L = np.linalg.cholesky(cov_t + np.diag((1e-6 * sd) ** 2)) if np.all(np.diag(cov_t) > 0) else np.diag(sd)
    p0 = []
    while len(p0) < nw:
        cand = theta_hat + ball * (L @ rng.standard_normal(k))
        if np.isfinite(log_post(cand)):
            p0.append(cand)
    sampler = emcee.EnsembleSampler(nw, k, log_post)
    sampler.random_state = np.random.mtrand.RandomState(seed).get_state()   # reproducible
    sampler.run_mcmc(np.array(p0), n_steps, progress=False)
    burn = n_steps // 3 if burn is None else burn
    chain = sampler.get_chain(discard=burn, thin=thin, flat=True)
    try:
        tau = sampler.get_autocorr_time(discard=burn, quiet=True)
    except Exception:  # noqa: BLE001 - emcee raises its own error class for short chains
        tau = np.full(k, np.nan)
    samples = coords.scale * np.exp(chain) if coords.space == "log" else chain
    return Posterior(names, samples, float(np.mean(sampler.acceptance_fraction)), np.asarray(tau, float))
