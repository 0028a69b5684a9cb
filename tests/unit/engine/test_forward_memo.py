"""Memory of the forward models (issue 29): caches do not keep dead models alive, and models
on equal meshes share one sparse pattern without changing a result."""
from __future__ import annotations

import gc
import weakref

import numpy as np

from engine.forward.memo import method_lru
from engine.forward.modal import ModalForward
from engine.plate import PlateModel
from engine.plate.mesh import Mesh
from engine.plate.model import mesh_parts
from engine.plate.sparse import Pattern
from labid.inputs.specimen import load_specimen

SPEC = load_specimen("cfrp")
MAT = next(iter(SPEC.laminate.materials))
NOMINAL = SPEC.laminate.materials[MAT].params()


class Owner:
    def __init__(self):
        self.calls = 0
        self.f = method_lru(self.double, 2)

    def double(self, x):
        self.calls += 1
        return 2 * x


def test_method_lru_memoises_and_frees_its_owner_without_the_cyclic_collector():
    o = Owner()
    assert o.f(3) == 6 and o.f(3) == 6 and o.calls == 1
    o.f(4), o.f(5), o.f(3)
    assert o.calls == 4                # maxsize 2: 3 was evicted
    gc.disable()
    try:
        r = weakref.ref(o)
        del o
        assert r() is None             # freed by reference counting, no gc.collect()
    finally:
        gc.enable()


def test_a_solved_modal_forward_and_its_plate_model_are_freed_at_once():
    model = PlateModel.build(SPEC.laminate, SPEC.length, SPEC.width, mesh=(4, 4))
    fwd = ModalForward(model.with_point_masses([(0.05, 0.05, 0.002)]), 4, material=MAT)
    f = fwd.predict(NOMINAL)
    assert f.size == 4 and np.all(np.diff(f) > 0)
    gc.disable()
    try:
        rf, rm = weakref.ref(fwd), weakref.ref(fwd.model)
        del fwd
        assert rf() is None and rm() is None
    finally:
        gc.enable()


def test_models_on_equal_meshes_share_the_pattern_and_solve_alike():
    mesh_parts.cache_clear()
    a = PlateModel.build(SPEC.laminate, SPEC.length, SPEC.width, mesh=(4, 4))
    b = PlateModel.build(SPEC.laminate, SPEC.length, SPEC.width, mesh=(4, 4))
    assert mesh_parts.cache_info().hits == 1
    fresh = Pattern.build(Mesh(4, 4, SPEC.length, SPEC.width))
    pa = mesh_parts(Mesh(4, 4, SPEC.length, SPEC.width))[0]
    for name in ("indptr", "indices", "elem_pos", "m_mask", "cross"):
        assert np.array_equal(getattr(pa, name), getattr(fresh, name))
    fa = a.solve(8, params=NOMINAL, material=MAT).frequencies_hz
    fb = b.solve(8, params=NOMINAL, material=MAT).frequencies_hz
    assert np.array_equal(fa, fb)


def test_modal_jacobian_reuses_the_sensitivities_of_the_same_solve():
    """The eigenvalue sensitivities are computed once per (constants, names) and solve; the
    Jacobian equals central differences of the frequencies (not the memo's own output), also
    from the memo; other names or constants are computed afresh."""
    model = PlateModel.build(SPEC.laminate, SPEC.length, SPEC.width, mesh=(4, 4))
    fwd = ModalForward(model, 4, material=MAT)
    calls = []
    orig = model.eigen_sensitivities

    def counted(*a, **k):
        calls.append(1)
        return orig(*a, **k)
    model.eigen_sensitivities = counted
    names = ["E1", "G12"]
    f1, J1 = fwd.jacobian(NOMINAL, names)
    f2, J2 = fwd.jacobian(dict(NOMINAL), names)
    assert len(calls) == 1 and np.array_equal(J1, J2) and np.array_equal(f1, f2)
    for k, n in enumerate(names):
        h = 1e-4 * NOMINAL[n]
        fd = (fwd.predict({**NOMINAL, n: NOMINAL[n] + h}) - fwd.predict({**NOMINAL, n: NOMINAL[n] - h})) / (2 * h)
        np.testing.assert_allclose(J2[:, k], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())
    _, J3 = fwd.jacobian(NOMINAL, ["E1"])               # other names: computed
    assert len(calls) == 2
    np.testing.assert_allclose(J3[:, 0], J1[:, 0], rtol=1e-9)
    fwd.jacobian({**NOMINAL, "E1": 1.01 * NOMINAL["E1"]}, names)   # other constants: computed
    assert len(calls) == 3
