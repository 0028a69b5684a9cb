"""The identification's memoised forward calls (h2 speed work): a repeated parameter set is
not solved again, and what comes back is what a fresh solve gives."""
from __future__ import annotations

import numpy as np

from engine.fit import DataBlock
from engine.identify.stages import discretisation
from engine.forward.modal import MODES_KEPT, ModalForward
from engine.identify.verdict import FitContext, boxed
from engine.plate import PlateModel
from labid.inputs.specimen import load_specimen

SPEC = load_specimen("cfrp")
MAT = next(iter(SPEC.laminate.materials))
NOMINAL = SPEC.laminate.materials[MAT].params()


class CountingModel:
    """A PlateModel proxy counting its eigen-solves."""

    def __init__(self, model):
        self.inner, self.solves = model, 0

    def solve(self, *a, **k):
        self.solves += 1
        return self.inner.solve(*a, **k)

    def __getattr__(self, name):
        return getattr(self.inner, name)


def _model():
    return PlateModel.build(SPEC.laminate, SPEC.length, SPEC.width, mesh=(6, 6))


def test_modal_forward_reuses_modes_of_recent_parameter_sets():
    m = CountingModel(_model())
    fwd = ModalForward(m, 6, material=MAT)
    p1, p2 = dict(NOMINAL), {**NOMINAL, "E1": NOMINAL["E1"] * 1.1}
    f1 = fwd.predict(p1)
    fwd.predict(p2)
    again = fwd.predict(p1)          # the one-entry cache alone would solve again
    assert m.solves == 2
    np.testing.assert_array_equal(again, f1)
    fresh = m.inner.solve(fwd.n_solve, params=p1, material=MAT).frequencies_hz[:6]
    np.testing.assert_array_equal(again, fresh)
    for k in range(MODES_KEPT):      # older sets are dropped: a bounded memory
        fwd.predict({**NOMINAL, "G12": NOMINAL["G12"] * (1.0 + 0.01 * (k + 1))})
    fwd.predict(p2)
    assert m.solves == 2 + MODES_KEPT + 1


def test_boxed_difference_blocks_evaluate_each_parameter_set_once():
    calls = []

    def predict(p):
        calls.append(dict(p))
        return np.array([p["E1"] * 1e-9, p["G12"] * 1e-9])

    blk = DataBlock("waves:test", np.array([1.0, 2.0]), np.array([0.1, 0.1]), predict, None, kind="waves")
    ctx = FitContext(SPEC.laminate.materials[MAT], NOMINAL, False, SPEC.length, SPEC.width)
    (b,) = boxed(ctx, [blk])
    y1 = b.predict(dict(NOMINAL))
    y1[0] = -1.0                      # the caller's copy: the memo is not changed
    y2 = b.predict(dict(NOMINAL))
    assert len(calls) == 1
    np.testing.assert_array_equal(y2, [NOMINAL["E1"] * 1e-9, NOMINAL["G12"] * 1e-9])
    b.predict({**NOMINAL, "E1": NOMINAL["E1"] * 1.01})
    assert len(calls) == 2


def test_discretisation_memo_returns_the_computed_correction():
    model = _model()
    r1, e1, n1 = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [], model, MAT, 8)
    r1[:] = 0.0                       # the caller's copy: the memo is not changed
    r2, e2, n2 = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [], _model(), MAT, 8)
    assert n1 == n2 and np.all(r2 > 0.9) and np.all(r2 <= 1.0 + 1e-9)
    heavier = _model().with_point_masses([(0.05, 0.05, 0.01)])    # another model: not the memo's entry
    r3, _, _ = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [(0.05, 0.05, 0.01)], heavier, MAT, 8)
    assert not np.allclose(r3, r2, rtol=1e-12, atol=0.0)


def test_discretisation_memo_serves_fewer_modes_from_the_kept_correction(monkeypatch):
    """The diagnosis asks for the modes its peaks pair with (fewer than identify solved): it
    gets the first n of identify's correction, without a second fine-mesh model."""
    r8, e8, _ = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [], _model(), MAT, 8)
    again = _model()
    builds = []
    monkeypatch.setattr(PlateModel, "build", classmethod(lambda *a, **k: builds.append(a) or None))
    r5, e5, note = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [], again, MAT, 5)
    assert not builds
    np.testing.assert_array_equal(r5, r8[:5])
    np.testing.assert_array_equal(e5, e8[:5])
    assert "at mode" in note and int(note.split("at mode ")[1].split(";")[0]) <= 5


def test_discretisation_memo_serves_the_unnamed_one_material(monkeypatch):
    """Identify names the laminate's one material, the diagnosis' peak corrections pass None:
    the same K and M (checked here), so the same kept correction, without a second fine mesh."""
    assert len(SPEC.laminate.materials) == 1
    K1, M1 = _model().matrices(None, MAT)
    K0, M0 = _model().matrices(None, None)
    assert abs(K1 - K0).max() == 0.0 and abs(M1 - M0).max() == 0.0
    r8, e8, _ = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [], _model(), MAT, 8)
    again = _model()
    builds = []
    monkeypatch.setattr(PlateModel, "build", classmethod(lambda *a, **k: builds.append(a) or None))
    r6, e6, _ = discretisation(SPEC.laminate, SPEC.length, SPEC.width, [], again, None, 6)
    assert not builds
    np.testing.assert_array_equal(r6, r8[:6])
    np.testing.assert_array_equal(e6, e8[:6])
