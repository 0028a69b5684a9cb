"""The warm eigen-solve (engine/plate/warm.py): certified answers equal to ARPACK's, or none.

Reference: a fresh model (no previous solve, so ARPACK's shift-invert Lanczos) at the same
constants. Counts of warm solves from ``engine.plate.warm.COUNTS``.
"""
import numpy as np
import pytest

from engine.laminate import Laminate, Material, Ply
from engine.plate import PlateModel
from engine.plate import warm as W

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")
CFRP = Laminate(tuple(Ply(T300, a, 1.3333e-4) for a in [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0]))
ALU = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="alu")
NAMES6 = ("E1", "E2", "G12", "nu12", "G13", "G23")
P0 = {k: getattr(T300, k) for k in NAMES6}


def _cold(lam, length, width, mesh, n, params, material=None):
    return PlateModel.build(lam, length, width, mesh).solve(n, params=params, material=material)


def _warm_count():
    return W.COUNTS["warm"]


@pytest.fixture(scope="module")
def demo_model():
    return PlateModel.build(CFRP, 0.33, 0.33)       # the demo plate's default mesh (3,125 DOF)


def test_demo_plate_warm_equals_arpack_frequencies_and_sensitivities(demo_model):
    demo_model.solve(56, params=P0)
    p1 = {k: v * (1 + 2e-4 * (-1) ** i) for i, (k, v) in enumerate(P0.items())}
    n0 = _warm_count()
    warm = demo_model.solve(56, params=p1)
    assert _warm_count() == n0 + 1                   # the warm path answered
    cold = _cold(CFRP, 0.33, 0.33, None, 56, p1)
    np.testing.assert_allclose(warm.omega2, cold.omega2, rtol=1e-9, atol=0)
    sw = demo_model.eigen_sensitivities(warm, NAMES6)
    sc = demo_model.eigen_sensitivities(cold, NAMES6)
    # first order in the shapes' error (~1e-6, the warm path's residual floor): 5e-6 stated
    np.testing.assert_allclose(sw, sc, rtol=5e-6, atol=1e-9 * np.abs(sc).max())
    # M-orthonormal shapes
    M = demo_model.matrices(p1)[1]
    np.testing.assert_allclose(warm.shapes.T @ (M @ warm.shapes), np.eye(56), atol=1e-9)


def test_far_start_falls_back_to_arpack_bitwise(demo_model):
    demo_model.solve(20, params=P0)
    p1 = dict(P0, E2=P0["E2"] * 1.3, G12=P0["G12"] * 0.8)
    n0 = _warm_count()
    got = demo_model.solve(20, params=p1)
    assert _warm_count() == n0
    assert np.array_equal(got.omega2, _cold(CFRP, 0.33, 0.33, None, 20, p1).omega2)


def test_square_isotropic_degenerate_pairs():
    """Square isotropic plate: degenerate pairs (Leissa's (1,2)/(2,1) family). The pair's
    eigenvectors are any basis of its space: the frequencies and the pair's summed
    sensitivities (trace) must agree."""
    lam = Laminate((Ply(ALU, 0.0, 0.003),))
    m = PlateModel.build(lam, 0.3, 0.3, (10, 10))
    p0 = {"E": 70e9, "G": 70e9 / 2.66}
    m.solve(19, params=p0)     # 19: the 19th/20th are not a pair (a pair split at the top cannot certify)
    p1 = {"E": 70e9 * (1 + 1e-4), "G": p0["G"] * (1 - 1e-4)}
    n0 = _warm_count()
    warm = m.solve(19, params=p1)
    assert _warm_count() == n0 + 1
    cold = _cold(lam, 0.3, 0.3, (10, 10), 19, p1)
    f = cold.omega2
    assert np.any(np.diff(f) / f[1:] < 1e-9)         # there are degenerate pairs
    np.testing.assert_allclose(warm.omega2, f, rtol=1e-9, atol=0)
    sw, sc = m.eigen_sensitivities(warm, ["E", "G"]), m.eigen_sensitivities(cold, ["E", "G"])
    groups = np.split(np.arange(19), np.flatnonzero(np.diff(f) / f[1:] > 1e-6) + 1)
    for g in groups:
        ref = sc[g].sum(0)      # (d/dE, d/dG): to 5e-6 of the larger
        np.testing.assert_allclose(sw[g].sum(0), ref, rtol=0, atol=5e-6 * np.abs(ref).max())


def test_mode_crossing_between_solves_is_followed():
    """Square plate, E1 = E2 (1 +- 4e-4): the (m,n)/(n,m) pairs split one way, then the other:
    between the previous and the new constants the pairs' lower and upper modes swap shapes
    (MAC ~0). The warm answer (a 4e-4 step: tried and certified) equals ARPACK's."""
    mat = Material(E1=10e9, E2=10e9, nu12=0.3, G12=3.0e9, G13=3.0e9, G23=3.0e9, density=1500.0, name="o")
    lam = Laminate((Ply(mat, 0.0, 0.004),))
    m = PlateModel.build(lam, 0.3, 0.3, (10, 10))
    pa = {"E1": 10e9, "E2": 10e9 * (1 + 4e-4)}
    pb = {"E1": 10e9 * (1 + 4e-4), "E2": 10e9}
    a = m.solve(12, params=pa, material="o")
    n0 = _warm_count()
    warm = m.solve(12, params=pb, material="o")
    assert _warm_count() == n0 + 1
    M = m.matrices(pb, "o")[1]
    mac = np.abs(np.einsum("ij,ij->j", a.shapes, M @ warm.shapes))
    assert np.sum(mac < 0.1) >= 4                    # the crossing happened (pairs swapped)
    cold = _cold(lam, 0.3, 0.3, (10, 10), 12, pb, "o")
    np.testing.assert_allclose(warm.omega2, cold.omega2, rtol=1e-9, atol=0)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->j", cold.shapes, M @ warm.shapes)), 1.0, atol=1e-6)


def test_coupled_layup_all_fields_block():
    """Unsymmetric [0/90] (B != 0): the single five-field block with 6 rigid modes."""
    lam = Laminate(tuple(Ply(T300, a, 4e-4) for a in (0, 90)))
    m = PlateModel.build(lam, 0.25, 0.2, (8, 8))
    m.solve(15)
    p1 = {k: v * (1 - 1e-4) for k, v in P0.items()}
    n0 = _warm_count()
    warm = m.solve(15, params=p1)
    assert _warm_count() == n0 + 1
    np.testing.assert_allclose(warm.omega2, _cold(lam, 0.25, 0.2, (8, 8), 15, p1).omega2, rtol=1e-9, atol=0)


def test_a_missing_mode_in_the_start_is_caught():
    """A start that lacks one wanted mode (replaced by a spare) cannot certify: the Ritz
    values then skip that eigenvalue and the (n+1)-th lies above the counted bound."""
    lam = Laminate(tuple(Ply(T300, a, 1.3333e-4) for a in [0, 90, 90, 0]))
    m = PlateModel.build(lam, 0.3, 0.2, (10, 10))
    m.solve(10)
    st = m._warm["bending"]
    V = st.vectors.copy()
    V[:, 8] = V[:, -1]                    # mode 6 (3 rigid first) gone, a spare twice
    V[:, -1] = st.vectors[:, -2]
    bad = W.WarmStart(V, st.lam, st.n_want, st.lower, st.c, st.mass)
    c, inert = m.coefficients()
    blk = m._block("bending")
    mb, M = m._block_mass("bending", inert)
    sigma = -0.1 * m._omega2_scale(c, inert)
    lu = blk.factor(m._data(c, inert), mb, sigma)
    assert W.warm_eig(bad, lu, M, sigma, c, False, st.n_want) is None
    assert W.warm_eig(st, lu, M, sigma, c, False, st.n_want) is not None   # the honest start does


@pytest.mark.parametrize("coupled", [False, True])
def test_stiffening_bound_orders_every_eigenvalue(coupled):
    """Courant-Fischer premise of the counting: alpha lam_j(old) <= lam_j(new) <= beta lam_j(old)
    for every j, with (alpha, beta) from the constitutive matrices (here checked on 40 modes)."""
    lam = Laminate(tuple(Ply(T300, a, 4e-4) for a in ((0, 90) if coupled else (0, 90, 90, 0))))
    rng = np.random.default_rng(3)
    m = PlateModel.build(lam, 0.25, 0.2, (8, 8))
    for _ in range(3):
        pa = {k: v * np.exp(0.2 * rng.standard_normal()) for k, v in P0.items()}
        pb = {k: v * np.exp(0.2 * rng.standard_normal()) for k, v in P0.items()}
        try:
            ca, _ = m.coefficients(pa)
            cb, _ = m.coefficients(pb)
        except Exception:   # an inadmissible draw (Poisson bound)
            continue
        alpha, beta = W.stiffening_bounds(cb, ca, coupled)
        la = _cold(lam, 0.25, 0.2, (8, 8), 40, pa).omega2
        lb = _cold(lam, 0.25, 0.2, (8, 8), 40, pb).omega2
        assert alpha > 0
        assert np.all(lb >= alpha * la * (1 - 1e-9)) and np.all(lb <= beta * la * (1 + 1e-9))
