"""Estimator core on analytic models (exact answers known in closed form)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.fit import (DataBlock, IdentificationError, Prior, bayesian_update, estimate, linearised_block,
                        nelder_mead_fit)


def _linear_problem(seed=0):
    rng = np.random.default_rng(seed)
    A = rng.uniform(0.5, 2.0, size=(8, 3))
    p_true = np.array([2.0, 3.0, 5.0])
    sigma = rng.uniform(0.05, 0.2, size=8)
    y = A @ p_true + sigma * rng.standard_normal(8)
    return A, p_true, sigma, y


def _linear_block(A, sigma, y, names=("a", "b", "c")):
    def predict(p):
        return A @ np.array([p[n] for n in names])

    def jac(p, nm):
        return predict(p), A[:, [names.index(n) for n in nm]]

    return DataBlock("lin", y, sigma, predict, jac, kind="modal")


def _exact_posterior(A, sigma, y, m, s):
    """Gaussian posterior of y = A p + e, e ~ N(0, sigma^2), p ~ N(m, s^2)."""
    W = np.diag(1 / sigma ** 2)
    P = np.diag(1 / s ** 2)
    cov = np.linalg.inv(A.T @ W @ A + P)
    mean = cov @ (A.T @ W @ y + P @ m)
    return mean, cov


def test_linear_gaussian_lm_matches_exact_posterior():
    A, p_true, sigma, y = _linear_problem()
    names = ("a", "b", "c")
    start = {"a": 1.5, "b": 4.0, "c": 4.0}
    s_abs = np.array([0.5, 0.5, 1.0])
    m = np.array([start[n] for n in names])
    prior = Prior(mean=start, rel_std={n: sa / start[n] for n, sa in zip(names, s_abs)})
    est = estimate([_linear_block(A, sigma, y)], names, start, prior=prior, space="linear")
    mean, cov = _exact_posterior(A, sigma, y, m, s_abs)
    assert est.converged
    # converged: remaining error ~ sqrt(1e-9 chi^2) posterior standard deviations
    np.testing.assert_allclose(est.values, mean, atol=3e-4 * np.sqrt(np.diag(cov)).min())
    np.testing.assert_allclose(est.cov, cov, rtol=1e-9)
    np.testing.assert_allclose(est.std, np.sqrt(np.diag(cov)), rtol=1e-9)
    d = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(est.corr, cov / np.outer(d, d), atol=1e-12)


def test_bayesian_update_eq20_is_exact_in_one_step_for_linear_model():
    A, p_true, sigma, y = _linear_problem(1)
    names = ("a", "b", "c")
    start = {"a": 2.2, "b": 2.8, "c": 5.3}
    rel = 0.3
    m = np.array([start[n] for n in names])
    est = bayesian_update([_linear_block(A, sigma, y)], names, start, prior_rel_std=rel,
                          max_rel_step=10.0)
    mean, cov = _exact_posterior(A, sigma, y, m, rel * m)
    assert est.converged
    np.testing.assert_allclose(list(est.history[1]["params"].values()), mean, rtol=1e-10)
    np.testing.assert_allclose(est.values, mean, rtol=1e-10)
    np.testing.assert_allclose(est.cov, cov, rtol=1e-9)


def _decay_block(t, p_true, sigma, noise=None, name="decay"):
    """y = a exp(-b t): d y/d a = exp(-b t), d y/d b = -a t exp(-b t)."""
    def predict(p):
        return p["a"] * np.exp(-p["b"] * t)

    def jac(p, nm):
        e = np.exp(-p["b"] * t)
        cols = {"a": e, "b": -p["a"] * t * e}
        return predict(p), np.column_stack([cols[n] for n in nm])

    y = predict(p_true) + (0 if noise is None else noise)
    return DataBlock(name, y, sigma, predict, jac, kind="waves"), DataBlock(name, y, sigma, predict, None, kind="waves")


def test_nonlinear_noise_free_recovery_and_fisher_covariance():
    t = np.linspace(0, 3, 25)
    truth = {"a": 4.0, "b": 1.3}
    blk, blk_fd = _decay_block(t, truth, 0.01)
    for b in (blk, blk_fd):
        est = estimate([b], ("a", "b"), {"a": 1.0, "b": 0.2}, prior=None)
        assert est.converged
        np.testing.assert_allclose(est.values, [4.0, 1.3], rtol=1e-7)
        # exact Fisher information at the truth
        e = np.exp(-1.3 * t)
        J = np.column_stack([e, -4.0 * t * e]) / 0.01
        np.testing.assert_allclose(est.cov, np.linalg.inv(J.T @ J), rtol=1e-4)
        assert est.residual_summary()["waves_rms_rel"] < 1e-7
        assert est.residual_summary()["modal_rms_rel"] is None


def test_nelder_mead_eq29_recovers_truth():
    t = np.linspace(0, 3, 25)
    blk, _ = _decay_block(t, {"a": 4.0, "b": 1.3}, 0.01)
    est = nelder_mead_fit([blk], ("a", "b"), {"a": 2.0, "b": 0.5})
    assert est.converged
    np.testing.assert_allclose(est.values, [4.0, 1.3], rtol=1e-5)


def test_identifiability_report_names_the_constraining_block():
    t = np.linspace(0.1, 1.0, 10)

    def make(name, key, kind):
        def predict(p):
            return p[key] * t
        return DataBlock(name, predict({key: 2.0}), 0.01 * np.ones_like(t), predict, None, kind=kind)

    # a third parameter c that neither block sees
    blocks = [make("A-only", "a", "modal"), make("B-only", "b", "waves")]
    est = estimate(blocks, ("a", "b", "c"), {"a": 1.0, "b": 3.0, "c": 1.0}, prior=1.0)
    rep = est.identifiability["parameters"]
    assert rep["a"]["constrained_by"] == ["modal"]
    assert rep["b"]["constrained_by"] == ["waves"]
    assert rep["c"]["constrained_by"] == [] and not rep["c"]["identified"]
    assert est.identifiability["poorly_identified"] == ["c"]
    # unseen parameter keeps the prior: value = start, std = prior (log-sd 1 -> p*1)
    assert est.params["c"] == pytest.approx(1.0)
    assert est.std[2] == pytest.approx(1.0, rel=1e-9)


def test_product_only_is_flagged_by_correlation_and_singular_values():
    """y = a*b: only the product is identifiable; log-coordinates perfectly anti-correlated."""
    t = np.linspace(1, 2, 6)

    def predict(p):
        return p["a"] * p["b"] * t

    blk = DataBlock("prod", predict({"a": 2.0, "b": 3.0}), 0.001 * np.ones(6), predict)
    est = estimate([blk], ("a", "b"), {"a": 1.0, "b": 1.0}, prior=1.0)
    assert est.params["a"] * est.params["b"] == pytest.approx(6.0, rel=1e-6)
    assert est.params["a"] == pytest.approx(est.params["b"], rel=1e-6)  # symmetric prior split
    assert est.corr[0, 1] == pytest.approx(-1.0, abs=1e-3)
    sv = est.identifiability["data_sets"]["data"]["singular_values"]
    assert sv[1] < 1e-8 * sv[0]
    w = est.identifiability["weakest_direction"]
    assert abs(w["a"]) == pytest.approx(abs(w["b"]), rel=1e-6)
    assert set(est.identifiability["poorly_identified"]) == {"a", "b"}


def test_unphysical_region_is_avoided():
    """The model raises ValueError for b > 2; the truth is near the border."""
    t = np.linspace(0, 3, 25)
    _, blk = _decay_block(t, {"a": 4.0, "b": 1.9}, 0.01)

    def guarded(p):
        if p["b"] > 2.0:
            raise ValueError("b too large")
        return blk.predict(p)

    g = DataBlock("g", blk.observed, blk.sigma, guarded)
    est = estimate([g], ("a", "b"), {"a": 1.0, "b": 0.5}, prior=None)
    np.testing.assert_allclose(est.values, [4.0, 1.9], rtol=1e-7)


def test_linearised_block_reproduces_first_order_model():
    t = np.linspace(0, 3, 25)
    blk, _ = _decay_block(t, {"a": 4.0, "b": 1.3}, 0.01)
    lin = linearised_block(blk, {"a": 4.0, "b": 1.3}, ("a", "b"))
    p = {"a": 4.0 * np.exp(1e-3), "b": 1.3 * np.exp(-2e-3)}
    y_lin = lin.predict(p)
    np.testing.assert_allclose(y_lin, blk.predict(p), atol=1e-5 * 4)


@pytest.mark.parametrize("start,msg", [({"a": -1.0, "b": 1.0}, "positive"),
                                      ({"a": 1.0}, "no start value")])
def test_bad_starts_raise(start, msg):
    t = np.linspace(0, 3, 5)
    blk, _ = _decay_block(t, {"a": 4.0, "b": 1.3}, 0.01)
    with pytest.raises(IdentificationError, match=msg):
        estimate([blk], ("a", "b"), start)


def test_uncertainty_is_calibrated_on_nonlinear_model():
    """Truth within 2 std in ~95 % of seeded noisy repeats (binomial bound)."""
    t = np.linspace(0, 3, 30)
    truth = {"a": 4.0, "b": 1.3}
    sigma = 0.05
    rng = np.random.default_rng(42)
    n, hits = 200, np.zeros(2)
    for _ in range(n):
        blk, _ = _decay_block(t, truth, sigma, noise=sigma * rng.standard_normal(t.size))
        est = estimate([blk], ("a", "b"), {"a": 3.0, "b": 1.0}, prior=None)
        hits += np.abs(est.values - [4.0, 1.3]) <= 2 * est.std
    # P(within 2 sd) = 0.9545; with n=200 the 3-sigma band is [0.91, 1.0]
    assert np.all(hits / n >= 0.91)


def test_lm_follows_the_curved_rosenbrock_valley():
    """Rosenbrock's least-squares problem r = (10 (y - x^2), 1 - x) from the
    classic start (-1.2, 1): the damping must carry the fit along the curved
    valley to the exact minimum (1, 1). Parameters a = x + 2, b = y + 2 (kept
    positive), with an analytic Jacobian and with finite differences."""
    def predict(p):
        x, y = p["a"] - 2.0, p["b"] - 2.0
        return np.array([10.0 * (y - x * x), 1.0 - x])

    def jac(p, nm):
        x = p["a"] - 2.0
        d = {"a": np.array([-20.0 * x, -1.0]), "b": np.array([10.0, 0.0])}
        return predict(p), np.column_stack([d[n] for n in nm])

    for j in (jac, None):
        blk = DataBlock("rosenbrock", np.zeros(2), np.ones(2), predict, j)
        est = estimate([blk], ("a", "b"), {"a": 0.8, "b": 3.0}, prior=None, max_iter=200)
        assert est.converged
        np.testing.assert_allclose(est.values, [3.0, 3.0], atol=1e-5)


def test_laplace_keeps_the_variance_of_a_parameter_outside_the_null_space():
    """J = [[2, 0, 0], [0, 1, 1]]: p0 is measured alone with weight 2 (variance exactly 1/4);
    p1 and p2 are seen only as their sum (a null direction): infinite variance. Before
    session 26 the null direction's inf x 0 made p0's variance 0 (a perfectly known constant)."""
    from engine.fit import laplace
    cov = laplace([np.array([[2.0, 0.0, 0.0], [0.0, 1.0, 1.0]])], np.zeros(3))
    assert cov[0, 0] == pytest.approx(0.25, rel=1e-12)
    assert np.isinf(cov[1, 1]) and np.isinf(cov[2, 2])
    # with a prior of weight 1 on each the matrix is regular: the exact inverse
    A = np.array([[5.0, 0, 0], [0, 2, 1], [0, 1, 2]])
    np.testing.assert_allclose(laplace([np.array([[2.0, 0, 0], [0, 1, 1]])], np.ones(3)), np.linalg.inv(A),
                               rtol=1e-12, atol=1e-15)
