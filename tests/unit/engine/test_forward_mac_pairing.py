"""Mode pairing: MAC, one-to-one assignment and the mode-switching check."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from engine.fit import estimate
from engine.forward import mac, modal_block, pair_by_mac
from engine.forward.pairing import match


def test_mac_definition():
    a = np.array([[1.0, 2.0, 3.0], [1.0, 0.0, 0.0]])
    b = np.array([[-2.0, -4.0, -6.0], [0.0, 1.0, 0.0]])
    M = mac(a, b)
    assert M[0, 0] == 1.0                       # same shape, any scaling/sign
    assert M[1, 1] == 0.0                       # orthogonal shapes
    assert np.isclose(M[1, 0], 4.0 / 56.0)       # |a.b|^2 / (|a|^2 |b|^2) = 2^2 / (1 * 56)


def test_pair_by_mac_is_one_to_one():
    rng = np.random.default_rng(0)
    pred = rng.standard_normal((6, 20))
    meas = pred[[4, 0, 2]] * np.array([[2.0], [-1.0], [0.5]]) + 0.05 * rng.standard_normal((3, 20))
    idx, val = pair_by_mac(meas, pred)
    assert idx.tolist() == [4, 0, 2] and np.all(val > 0.95)


def test_match_solves_the_textbook_assignment_and_leaves_costly_rows_unpaired():
    # the classic 3 x 3 example (Kuhn 1955 style; scipy's linear_sum_assignment docs): optimum 5
    cost = np.array([[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]])
    idx = match(cost)
    assert idx.tolist() == [1, 0, 2] and cost[np.arange(3), idx].sum() == 5.0
    # a row whose every pair costs more than leaving it unexplained stays unpaired (-1)
    cost2 = np.vstack([cost, [50.0, 60.0, 70.0]])
    assert match(cost2, unexplained=10.0).tolist() == [1, 0, 2, -1]
    # more rows than columns, no unexplained cost: the surplus row is -1, never garbage
    assert sorted(match(cost2).tolist()) == [-1, 0, 1, 2]


class _TwoModePlate:
    """Two modes with fixed shapes; f_a = a Hz, f_b = 2 Hz; they swap order at a = 2."""

    shapes_ab = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, -1.0]]).T   # (n_dof=3, 2)

    def solve(self, n, params=None, material=None):
        a = (params or {}).get("a", 1.0)
        f = np.array([a, 2.0])
        order = np.argsort(f)
        f = f[order]
        return SimpleNamespace(frequencies_hz=f, omega2=(2 * np.pi * f) ** 2,
                               shapes=self.shapes_ab[:, order], params=dict(params or {}))

    def eigen_sensitivities(self, modes, names, params=None, material=None):
        a = params["a"]
        d = np.where(np.isclose(modes.frequencies_hz, a), 2 * (2 * np.pi) ** 2 * a, 0.0)
        return d[:, None]

    def shapes_at(self, modes, points):
        return modes.shapes.T   # the 3 DOFs are the 3 "points"


def test_order_pairing_flags_mode_switching():
    plate = _TwoModePlate()
    blk, fwd = modal_block(plate, [1.5, 2.0], [0.01, 0.01])
    blk.predict({"a": 1.5})
    assert fwd.warnings == []
    blk.predict({"a": 2.5})          # the a-mode is now the second one
    assert any("mode switching" in w for w in fwd.warnings)


def test_mac_pairing_follows_the_mode_across_a_crossing():
    """Measured: a-mode at 2.5 Hz listed first (with its shape). MAC pairing fits a = 2.5
    exactly although, in frequency order, the a-mode is the second predicted mode."""
    plate = _TwoModePlate()
    shapes = plate.shapes_ab.T           # rows: a-mode, b-mode
    blk, fwd = modal_block(plate, [2.5, 2.0], [0.01, 0.01], points=np.zeros((3, 2)), shapes=shapes,
                           n_extra=0)
    est = estimate([blk], ("a",), {"a": 1.2}, prior=None)
    assert est.converged and abs(est.params["a"] - 2.5) < 1e-6
    assert fwd.pairing.tolist() == [1, 0]
