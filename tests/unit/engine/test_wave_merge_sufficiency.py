"""engine.wavefeatures.merge (curves of several wavelets or tone-burst runs) and
engine.identify.sufficiency (the insufficient_data verdict): exact bookkeeping."""
from __future__ import annotations

import numpy as np
import pytest

from engine import waves
from engine.identify.sufficiency import VERDICT, DataSet, assess
from engine.wavefeatures import merge


def _curve(v, valid):
    f = np.array([50e3, 60e3, 70e3, 80e3])
    v = np.asarray(v, float)
    return waves.GroupVelocity(f, v, np.full(4, 1.0), np.asarray(valid, bool))


def test_merge_takes_the_longest_valid_wavelet_per_frequency():
    long_, short = waves.Wavelet(2.0, 5.0), waves.Wavelet(2.0, 1.0)
    g, which = merge.merge({short: _curve([1, 2, 3, 4], [1, 1, 1, 1]), long_: _curve([10, 20, 30, 40], [0, 1, 0, 1])})
    assert list(g.velocity_m_s) == [1, 20, 3, 40]
    assert which == [short, long_, short, long_]
    assert merge.by_length([short, long_]) == [long_, short]


def test_independent_points_use_each_points_own_resolution():
    """With one wavelet the rule is waves.independent_points'; a long wavelet's points may be
    closer (its frequency std is smaller)."""
    f = np.linspace(40e3, 200e3, 161)
    ok = np.ones(f.size, bool)
    w1 = waves.Wavelet(2.0, 1.0)
    same = merge.independent_mask(f, ok, [w1] * f.size)
    assert np.array_equal(same, waves.independent_points(f, ok, w1))
    longer = merge.independent_mask(f, ok, [waves.Wavelet(2.0, 5.0)] * f.size)
    assert longer.sum() > 3 * same.sum()


def test_merge_runs_averages_coincident_points_and_keeps_their_disagreement():
    """Two bursts at one frequency: the inverse-variance mean, sigma not below half their
    difference; the other points keep their own."""
    a = (np.array([100e3, 150e3]), np.array([1000.0, 1500.0]), np.array([3.0, 4.0]))
    b = (np.array([150e3, 200e3]), np.array([1510.0, 1600.0]), np.array([4.0, 5.0]))
    runs: list = []
    f, v, s, n = merge.merge_runs([a, b], runs_out=runs)
    assert list(f) == [100e3, 150e3, 200e3] and list(n) == [1, 2, 1]
    assert runs == [[0], [0, 1], [1]]                                       # which bursts made each point
    assert v[1] == pytest.approx(1505.0) and s[1] == pytest.approx(5.0)      # max(4/sqrt2, 10/2)
    assert (v[0], s[0], v[2], s[2]) == (1000.0, 3.0, 1600.0, 5.0)


def test_a_point_off_a_smooth_curve_is_flagged():
    f = np.linspace(50e3, 250e3, 12)
    v = 1200 + 800 * np.sqrt(f / 250e3)
    s = np.full(f.size, 2.0)
    assert not merge.off_curve(f, v, s).any()
    v[5] *= 1.05
    assert list(np.flatnonzero(merge.off_curve(f, v, s))) == [5]


def test_a_wrong_ridge_is_flagged_whatever_its_own_sigma():
    """Session 24's sweep outlier: one point 11.8 % off with a 3.9 % sigma (3 sigma) among
    points that scatter by 0.1 %: the curve through the others cannot support it; points
    0.1 % off (noise) are kept."""
    f = np.linspace(40e3, 280e3, 30)
    v = 1000 + 240 * np.log(f / 40e3) / np.log(7.0)
    rng = np.random.default_rng(1)
    v = v * (1 + 1e-3 * rng.standard_normal(f.size))
    s = 1e-3 * v
    assert not merge.off_curve(f, v, s).any()
    v[12] *= 1.118
    s[12] = 0.039 * v[12]
    assert list(np.flatnonzero(merge.off_curve(f, v, s))) == [12]


def test_one_wave_point_for_four_constants_is_insufficient_data():
    """The case of issue 24: one point, four constants fitted: never a verdict on the fit."""
    r = assess([DataSet("waves", 1, "A0", 0.0, (180e3, 180e3))], ("E1", "E2", "G13", "G23"))
    assert not r.enough and r.verdict == VERDICT == "insufficient_data"
    assert r.message.startswith("insufficient data: 1 independent point for 4 constants")
    assert any("another direction" in h for h in r.help) and any("S0" in h for h in r.help)
    assert any("wider band" in h for h in r.help) and any("resonances" in h for h in r.help)


def test_enough_points_pass_and_modal_counts():
    r = assess([DataSet("modal", 10), DataSet("waves", 8, "A0", 0.0, (20e3, 200e3)),
                DataSet("waves", 6, "A0", 90.0, (20e3, 200e3))], ("E1", "E2", "G12", "G13", "G23", "nu12"))
    assert r.enough and r.verdict is None and r.n_points == 24 and r.n_params == 6


def test_points_that_scatter_beyond_their_sigmas_are_not_a_curve():
    """Session 24, real Yeum et al. S0 from (A + C) / 2: 5 points 5066-5559 m/s (4 % scatter)
    each claiming 0.02-0.7 %: not a curve. A smooth A0 curve with 0.1 % noise is one."""
    f = np.array([140e3, 158e3, 177e3, 199e3, 223e3])
    v = np.array([5559.0, 5066.0, 5435.0, 5131.0, 5328.0])
    s = np.array([3.0, 35.0, 38.0, 1.0, 1.0])
    assert "scatter by" in merge.scattered(f, v, s)
    g = np.linspace(40e3, 280e3, 20)
    a0 = (1000 + 240 * np.log(g / 40e3) / np.log(7.0)) * (1 + 1e-3 * np.random.default_rng(2).standard_normal(20))
    assert merge.scattered(g, a0, 1e-3 * a0) == ""
    # the same scatter with sigmas that own it is a noisy curve, not a wrong one
    assert merge.scattered(f, v, 0.05 * v) == ""


def test_one_wrong_point_of_a_short_curve_goes_alone():
    """Session 24's known defect: a 6-point burst curve (A0 by the thin-plate law, 0.05 % noise)
    with one pick 5 % off on another ridge was withheld whole by ``scattered``; the leave-one-out
    drops that point only. Two wrong points, or the real Yeum et al. S0 zigzag, have no single
    odd point: the curve stays withheld."""
    g = np.array([60e3, 75e3, 92e3, 110e3, 130e3, 150e3])
    a0 = 1000 * np.sqrt(g / 60e3) ** 0.5 * (1 + 5e-4 * np.random.default_rng(3).standard_normal(6))
    assert merge.odd_one(g, a0, 1e-3 * a0) is None
    for k in range(6):         # withheld whole before (an end point the parabola absorbs: never withheld)
        w = a0.copy()
        w[k] *= 1.05
        assert (merge.odd_one(g, w, 1e-3 * w) == k) if merge.scattered(g, w, 1e-3 * w) else k in (0, 5)
        assert k in (0, 5) or merge.scattered(g, w, 1e-3 * w)
    w = a0.copy()
    w[2] *= 1.05
    w[3] *= 0.95
    assert merge.odd_one(g, w, 1e-3 * w) is None
    f = np.array([140e3, 158e3, 177e3, 199e3, 223e3])
    v = np.array([5559.0, 5066.0, 5435.0, 5131.0, 5328.0])
    assert merge.odd_one(f, v, np.array([3.0, 35.0, 38.0, 1.0, 1.0])) is None


def _a0_like(f):
    """A smooth, dispersive curve (A0's low-frequency law, c_g ~ sqrt(f)): numpy-made, no model."""
    return 40.0 * np.sqrt(np.asarray(f, float))


def test_merge_runs_combines_points_closer_than_the_runs_resolution():
    """Two bursts whose own points lie 10 % apart: their points 1.5 % and 4 % apart are one
    point each (weighted mean frequency and velocity, on the curve to first order; the curve's
    own dispersion between them does not inflate the sigma), points 12 % apart stay two."""
    fa = np.array([100e3, 110e3, 121e3, 133.1e3])
    fb = np.array([123e3, 138.4e3, 152.2e3])        # 1.65 % above 121, 3.98 % above 133.1
    a = (fa, _a0_like(fa), np.full(4, 2.0))
    b = (fb, _a0_like(fb), np.full(3, 2.0))
    assert merge.run_resolution(fa) == pytest.approx(10e3 / 110e3)
    f, v, s, n = merge.merge_runs([a, b])
    assert list(n) == [1, 1, 2, 2, 1]
    assert f[2] == pytest.approx(122e3) and f[3] == pytest.approx(0.5 * (133.1e3 + 138.4e3))
    # first order: the chord's midpoint of sqrt lies below the curve by ~ (df/f)^2 / 32
    assert np.all(np.abs(v / _a0_like(f) - 1) < 1e-4)
    assert s[2] == pytest.approx(2.0 / np.sqrt(2.0), rel=1e-3) and s[3] < 2.0
    f1, v1, s1, n1 = merge.merge_runs([a, (fb, _a0_like(fb) * np.array([1.02, 1.0, 1.0]), np.full(3, 2.0))])
    assert n1[2] == 2 and s1[2] >= 0.5 * 0.02 * _a0_like(123e3) * 0.99    # they disagree: it says so


def test_merge_runs_one_point_run_takes_the_others_resolution():
    fa = np.array([100e3, 110e3, 121e3])
    a = (fa, _a0_like(fa), np.full(3, 2.0))
    lone = (np.array([113e3]), _a0_like([113e3]), np.array([2.0]))     # 2.7 % above 110: one point
    far = (np.array([140e3]), _a0_like([140e3]), np.array([2.0]))      # 15.7 % above 121: its own
    f, v, s, n = merge.merge_runs([a, lone, far])
    assert list(n) == [1, 2, 1, 1]


def test_a_frequency_one_shot_of_several_measured_is_not_a_point():
    """The end of a reassigned range that one shot alone reached (its noise moved its
    instantaneous frequency) is not the shots' point; frequencies most shots measured are."""
    from engine.wavefeatures.pipeline import combine_shots
    f = np.array([90e3, 95e3, 100e3, 105e3])
    good = [waves.GroupVelocity(f, np.array([np.nan, 9000.0, 9001.0, 9002.0]), np.array([np.nan, 90.0, 90, 90]),
                                np.array([0, 1, 1, 1], bool)) for _ in range(2)]
    lone = waves.GroupVelocity(f, np.array([9650.0, 9010.0, 9005.0, np.nan]), np.full(4, 90.0),
                               np.array([1, 1, 1, 0], bool))
    g = combine_shots(good + [lone])
    assert list(g.valid) == [False, True, True, True]          # 1 of 3 at 90 kHz; 2 of 3 at 105 kHz
    assert g.velocity_m_s[1] == pytest.approx(9010 / 3 + 6000) and np.isnan(g.velocity_m_s[0])
    one = combine_shots([lone])                                  # a single shot is its own point
    assert list(one.valid) == [True, True, True, False]
