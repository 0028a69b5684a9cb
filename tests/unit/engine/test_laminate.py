"""engine.laminate against closed-form values (paper Eqs. 4, 6, 9, 12)."""
import numpy as np
import pytest

from engine.laminate import (Laminate, Material, PhysicsError, Ply, abdh, reduced_stiffness, rotate_z,
                             stiffness_3d, transform_inplane, transform_shear)

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")


def test_isotropic_stiffness_is_lame():
    E, nu = 70e9, 0.33
    m = Material.isotropic_from(E, 2700.0, nu=nu)
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    C = stiffness_3d(m)
    assert C[0, 0] == pytest.approx(lam + 2 * mu, rel=1e-12)
    assert C[0, 1] == pytest.approx(lam, rel=1e-12)
    assert C[3, 3] == pytest.approx(mu, rel=1e-12)
    # an isotropic material is invariant under any rotation about z
    np.testing.assert_allclose(rotate_z(C, 37.0), C, atol=1e-6 * C[0, 0])


def test_transverse_isotropy_defaults():
    C = stiffness_3d(T300)
    assert C[1, 1] == pytest.approx(C[2, 2], rel=1e-12)        # E3 = E2
    assert C[0, 1] == pytest.approx(C[0, 2], rel=1e-12)        # nu13 = nu12
    # in the 2-3 plane of isotropy: C44 = (C22 - C23)/2 = G23
    assert (C[1, 1] - C[1, 2]) / 2 == pytest.approx(T300.G23, rel=1e-12)
    # compliance gives back the engineering constants
    S = np.linalg.inv(C)
    assert S[0, 0] == pytest.approx(1 / T300.E1, rel=1e-12)
    assert -S[0, 1] / S[0, 0] == pytest.approx(T300.nu12, rel=1e-12)
    assert S[5, 5] == pytest.approx(1 / T300.G12, rel=1e-12)


def test_reduced_stiffness_eq4():
    Q, Qs = reduced_stiffness(T300)
    nu21 = T300.nu12 * T300.E2 / T300.E1
    d = 1 - T300.nu12 * nu21
    assert Q[0, 0] == pytest.approx(T300.E1 / d)
    assert Q[1, 1] == pytest.approx(T300.E2 / d)
    assert Q[0, 1] == pytest.approx(nu21 * T300.E1 / d)       # both forms of Eq. 4
    assert Q[2, 2] == T300.G12
    np.testing.assert_array_equal(Qs, np.diag([T300.G13, T300.G23]))


@pytest.mark.parametrize("angle", [0.0, 15.0, 45.0, -45.0, 90.0, 120.0])
def test_transformed_stiffness_matches_3d_rotation(angle):
    """Eq. 6 formulas equal the plane-stress reduction of the rotated 3D tensor."""
    Q, Qs = reduced_stiffness(T300)
    S = np.linalg.inv(rotate_z(stiffness_3d(T300), angle))
    Qb_3d = np.linalg.inv(S[np.ix_([0, 1, 5], [0, 1, 5])])
    Qs_3d = np.linalg.inv(S[np.ix_([4, 3], [4, 3])])       # (xz, yz)
    np.testing.assert_allclose(transform_inplane(Q, angle), Qb_3d, atol=1e-9 * Q[0, 0])
    np.testing.assert_allclose(transform_shear(Qs, angle), Qs_3d, atol=1e-9 * Qs[0, 0])


def test_rotation_90_swaps_axes():
    Q, Qs = reduced_stiffness(T300)
    Qb = transform_inplane(Q, 90.0)
    assert Qb[0, 0] == pytest.approx(Q[1, 1]) and Qb[1, 1] == pytest.approx(Q[0, 0])
    Qsb = transform_shear(Qs, 90.0)
    assert Qsb[0, 0] == pytest.approx(T300.G23) and Qsb[1, 1] == pytest.approx(T300.G13)


def test_quasi_isotropic_A_is_isotropic():
    """[0/45/-45/90]s: A11 = A22, A16 = A26 = 0, A66 = (A11 - A12)/2 (classical result)."""
    lam = Laminate(tuple(Ply(T300, a, 1.25e-4) for a in (0, 45, -45, 90, 90, -45, 45, 0)))
    r = abdh(lam)
    A = r.A
    assert A[0, 0] == pytest.approx(A[1, 1], rel=1e-12)
    assert abs(A[0, 2]) < 1e-12 * A[0, 0] and abs(A[1, 2]) < 1e-12 * A[0, 0]
    assert A[2, 2] == pytest.approx((A[0, 0] - A[0, 1]) / 2, rel=1e-12)
    np.testing.assert_allclose(r.B, 0.0, atol=1e-12 * A[0, 0] * lam.thickness)


def test_single_ply_abdh_closed_form():
    h = 2e-3
    m = Material.isotropic_from(70e9, 2700.0, nu=0.3)
    r = abdh(Laminate((Ply(m, 0.0, h),)))
    Q, _ = reduced_stiffness(m)
    np.testing.assert_allclose(r.A, Q * h, rtol=1e-12)
    np.testing.assert_allclose(r.D, Q * h**3 / 12, rtol=1e-12)
    assert r.D[0, 0] == pytest.approx(70e9 * h**3 / (12 * (1 - 0.3**2)), rel=1e-12)
    np.testing.assert_allclose(r.H, 5 / 6 * m.G12 * h * np.eye(2), rtol=1e-12)
    assert (r.I1, r.I3) == (pytest.approx(2700 * h), pytest.approx(2700 * h**3 / 12))
    assert abs(r.I2) < 1e-15


def test_unsymmetric_coupling_B():
    """[0/90] cross-ply: B11 = -B22 = (Q11 - Q22) h^2/8 for two plies of h/2."""
    h = 1e-3
    lam = Laminate((Ply(T300, 0.0, h / 2), Ply(T300, 90.0, h / 2)))
    Q, _ = reduced_stiffness(T300)
    B = abdh(lam).B
    assert B[0, 0] == pytest.approx(-(Q[0, 0] - Q[1, 1]) * h**2 / 8, rel=1e-12)
    assert B[1, 1] == pytest.approx(-B[0, 0], rel=1e-12)


def test_unphysical_constants_rejected():
    with pytest.raises(PhysicsError, match="positive definite"):
        Material(E1=10e9, E2=10e9, nu12=0.9, G12=3e9, G13=3e9, G23=3e9, density=1500).check()
    with pytest.raises(PhysicsError, match="G12"):
        Material(E1=10e9, E2=10e9, nu12=0.3, G12=-3e9, G13=3e9, G23=3e9, density=1500).check()
    with pytest.raises(PhysicsError, match="thickness"):
        Laminate((Ply(T300, 0.0, -1e-3),))


def test_with_params_tracks_transverse_defaults():
    m2 = T300.with_params(E2=10e9, G23=4e9)
    assert m2.e3 == 10e9 and m2.v23 == pytest.approx(10e9 / 8e9 - 1)
    iso = Material.isotropic_from(71.04e9, 2700.0, G=25.32e9)
    assert iso.params()["nu"] == pytest.approx(71.04 / (2 * 25.32) - 1)
    assert iso.with_params(G=26e9).nu12 == pytest.approx(71.04 / 52 - 1)
    with pytest.raises(KeyError):
        T300.with_params(E=1.0)
