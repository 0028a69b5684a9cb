"""MCMC posterior (emcee) against an exactly Gaussian posterior."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("emcee")

from engine.fit import DataBlock, estimate, sample_posterior  # noqa: E402


@pytest.mark.slow
def test_mcmc_matches_exact_gaussian_posterior_in_log_parameters():
    """y = A log(p) + e: the posterior of log p (flat prior) is exactly
    N((A'WA)^-1 A'W y, (A'WA)^-1); the Laplace estimate is exact too."""
    rng = np.random.default_rng(5)
    A = rng.uniform(-1, 1, size=(12, 2))
    sigma = np.full(12, 0.05)
    names = ("a", "b")
    lp_true = np.log([3.0, 0.5])
    y = A @ lp_true + sigma * rng.standard_normal(12)

    def predict(p):
        return A @ np.log([p["a"], p["b"]])

    blk = DataBlock("lin-log", y, sigma, predict)
    est = estimate([blk], names, {"a": 2.0, "b": 1.0}, prior=None)
    W = np.diag(1 / sigma ** 2)
    cov = np.linalg.inv(A.T @ W @ A)
    mean = cov @ A.T @ W @ y
    np.testing.assert_allclose(np.log(est.values), mean, atol=1e-3 * np.sqrt(cov.diagonal()).min())

    post = sample_posterior([blk], est, n_steps=3000, seed=1)
    lsamp = np.log(post.samples)
    n_eff = len(lsamp) / np.nanmax(post.autocorr_steps)
    se = np.sqrt(np.diag(cov) / n_eff)
    assert 0.2 < post.acceptance < 0.9
    np.testing.assert_allclose(lsamp.mean(axis=0), mean, atol=5 * se.max())
    np.testing.assert_allclose(lsamp.std(axis=0), np.sqrt(np.diag(cov)), rtol=0.1)
    c = np.corrcoef(lsamp.T)[0, 1]
    assert c == pytest.approx(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]), abs=0.05)


def test_mcmc_respects_unphysical_region():
    """The model refuses b > 1: no sample may lie there."""
    sigma = np.full(5, 0.5)

    def predict(p):
        if p["b"] > 1.0:
            raise ValueError("b > 1 is unphysical")
        return np.full(5, p["a"] * p["b"])

    blk = DataBlock("bounded", np.full(5, 0.9), sigma, predict)
    est = estimate([blk], ("a", "b"), {"a": 1.0, "b": 0.9}, prior=0.5)
    post = sample_posterior([blk], est, prior=0.5, n_steps=600, seed=2)
    assert post.samples[:, 1].max() <= 1.0
