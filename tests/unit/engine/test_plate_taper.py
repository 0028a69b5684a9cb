"""engine.plate thickness field (PlateModel.with_thickness_field) and the thickness_taper effect.

Numbers from outside the code: the uniform field against the scaled laminate
(Laminate.scaled_thickness, an independent path through the ply interfaces);
the symmetry and order of the taper's shift; mesh convergence; an independent
Euler-Bernoulli beam of the same taper; finite differences of the solver.
"""
import numpy as np
import pytest
import scipy.linalg as sl

from engine.laminate import Laminate, Material, Ply
from engine.plate import FEError, Mesh, PlateModel

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")
CFRP = Laminate(tuple(Ply(T300, a, 1.3333e-4) for a in [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0]))
A = 0.33
ALU = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="alu")


def taper(t, length=A):
    return lambda x, y: 1.0 + t * (2.0 * x / length - 1.0)


@pytest.fixture(scope="module")
def base():
    return PlateModel.build(CFRP, A, A)


@pytest.fixture(scope="module")
def f_flat(base):
    return base.solve(10).frequencies_hz


def test_uniform_field_equals_scaled_laminate(base):
    s = 1.03
    ref = base.with_laminate(CFRP.scaled_thickness(s))
    names = ["E1", "E2", "G12", "G13", "density"]
    for fld in (base.with_thickness_field(np.full(base.mesh.n_elements, s)),
                base.with_thickness_field(lambda x, y: s + 0.0 * x)):
        Kr, Mr = ref.matrices()
        Kf, Mf = fld.matrices()
        assert abs(Kr - Kf).max() <= 1e-12 * abs(Kr).max()
        assert abs(Mr - Mf).max() <= 1e-12 * abs(Mr).max()
        m_ref, m_fld = ref.solve(10), fld.solve(10)
        # equal matrices: the frequencies agree to the eigen solver's tolerance
        np.testing.assert_allclose(m_fld.frequencies_hz, m_ref.frequencies_hz, rtol=1e-8)
        # the analytic sensitivities on the same mode shapes agree to round-off
        np.testing.assert_allclose(fld.eigen_sensitivities(m_ref, names),
                                   ref.eigen_sensitivities(m_ref, names), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(fld.thickness_scale, s, rtol=1e-14)


def test_field_sensitivities_match_finite_differences(base):
    model = base.with_thickness_field(taper(0.1))
    p0 = T300.params()
    modes = model.solve(6, params=p0)
    names = ["E1", "G12", "density"]
    S = model.eigen_sensitivities(modes, names)
    for j, n in enumerate(names):
        h = 1e-3 * p0[n]
        up = model.solve(6, params={**p0, n: p0[n] + h}).omega2
        dn = model.solve(6, params={**p0, n: p0[n] - h}).omega2
        fd = (up - dn) / (2 * h)
        np.testing.assert_allclose(S[:, j], fd, rtol=2e-4, atol=1e-6 * np.abs(fd).max())


def test_taper_shift_even_and_second_order(base, f_flat):
    def shift(t):
        return base.with_thickness_field(taper(t)).solve(10).frequencies_hz / f_flat - 1.0

    s1, s2, sm = shift(0.025), shift(0.05), shift(-0.025)
    # the plate and the mesh are symmetric about x = L/2: the sign of the taper is not observable
    np.testing.assert_allclose(sm, s1, rtol=1e-4, atol=1e-8)
    # even in t: no first-order term, so doubling the taper quadruples the shift (+ O(t^2);
    # close mode pairs couple strongest: modes 9-10 are off by 5 % at t = 0.05 -> 0.10)
    np.testing.assert_allclose(s2 / s1, 4.0, rtol=0.02)
    assert np.abs(s2).max() > 1e-3          # and it is not nothing: ~0.25 % at 5 % per end


def test_taper_mesh_convergence():
    t = 0.1
    shifts = []
    for n in (4, 6, 8, 11):
        m = PlateModel.build(CFRP, A, A, Mesh.default(A, A, CFRP.thickness, n=n))
        f0 = m.solve(8).frequencies_hz
        shifts.append(m.with_thickness_field(taper(t)).solve(8).frequencies_hz / f0 - 1.0)
    d = [np.abs(b - a).max() for a, b in zip(shifts, shifts[1:])]
    assert d[0] > d[1] > d[2]                # the shift converges with refinement
    assert d[1] < 0.2 * np.abs(shifts[-1]).max()


def _beam_shift(t, L, EI, rhoA, n_el=120, n_modes=3):
    """Free-free Euler-Bernoulli beam, EI s^3 and rho A s, s = 1 + t xi: relative shift of the
    lowest bending frequencies and the untapered ones (Hz) (Hermite cubic elements, Gauss-exact integration)."""
    def solve(tt):
        n = 2 * (n_el + 1)
        K, M = np.zeros((n, n)), np.zeros((n, n))
        h = L / n_el
        g, w = np.polynomial.legendre.leggauss(5)
        for e in range(n_el):
            Ke, Me = np.zeros((4, 4)), np.zeros((4, 4))
            for gi, wi in zip(g, w):
                r = (gi + 1) / 2
                x = (e + r) * h
                s = 1.0 + tt * (2 * x / L - 1)
                N = np.array([1 - 3 * r**2 + 2 * r**3, h * (r - 2 * r**2 + r**3), 3 * r**2 - 2 * r**3,
                              h * (-r**2 + r**3)])
                B = np.array([-6 + 12 * r, h * (-4 + 6 * r), 6 - 12 * r, h * (-2 + 6 * r)]) / h**2
                Ke += wi * h / 2 * EI * s**3 * np.outer(B, B)
                Me += wi * h / 2 * rhoA * s * np.outer(N, N)
            i = slice(2 * e, 2 * e + 4)
            K[i, i] += Ke
            M[i, i] += Me
        lam = sl.eigh(K, M, eigvals_only=True)
        return np.sqrt(np.abs(lam[2:2 + n_modes]))
    f0 = solve(0.0)
    return solve(t) / f0 - 1.0, f0 / (2 * np.pi)


def test_tapered_strip_matches_euler_bernoulli_beam():
    # a long narrow isotropic strip bends like a beam; the taper's relative shift of its
    # bending modes is that of the tapered beam (Poisson and shear terms cancel in the ratio)
    L, W, h, t = 0.4, 0.02, 0.002, 0.15
    lam = Laminate((Ply(ALU, 0.0, h),))
    m = PlateModel.build(lam, L, W, (40, 1))
    f0 = m.solve(8)
    f1 = m.with_thickness_field(taper(t, L)).solve(8)
    beam, f_beam = _beam_shift(t, L, ALU.E1 * W * h**3 / 12, ALU.density * W * h)
    # the three lowest plate modes are the beam's bending modes (torsion and in-plane
    # bending lie above for W << L): same frequencies within the Poisson effect
    np.testing.assert_allclose(f0.frequencies_hz[:3], f_beam, rtol=0.06)
    plate = f1.frequencies_hz[:3] / f0.frequencies_hz[:3] - 1.0
    assert np.all(np.abs(beam) > 5e-4)
    np.testing.assert_allclose(plate, beam, rtol=0.03)


def test_field_survives_derived_models_and_is_checked(base):
    s = np.full(base.mesh.n_elements, 1.05)
    fld = base.with_thickness_field(s)
    assert fld.with_point_masses([(0.1, 0.1, 0.0)]).thickness_scale is not None
    assert fld.with_laminate(CFRP).thickness_scale is not None
    assert fld.with_thickness_field(None).thickness_scale is None
    with pytest.raises(FEError, match="one factor per element"):
        base.with_thickness_field(np.ones(3))
    with pytest.raises(FEError, match="> 0"):
        base.with_thickness_field(taper(1.5))


# -- the thickness_taper effect through the diagnosis' forward model -----------------------
def test_gap_forward_taper_is_the_plate_field_and_modal_only():
    from bench.blind import draw_case
    from engine.forward.effects import EFFECTS, PLATE_EFFECTS
    from engine.gap import GapForward
    from labid.workflows.diagnosis import gap_features

    assert "thickness_taper" in PLATE_EFFECTS and EFFECTS["thickness_taper"].modalities == ("modal",)
    case = draw_case(3, "clean", wave_sets=(("A0", 0.0, 3),), mesh=(4, 4))
    pr = gap_features(case.features)
    fw = GapForward(pr, mesh=(4, 4), pairing="order")
    p, t = case.truth_constants, 0.08
    y0, y1 = fw.predict(p, {}), fw.predict(p, {"thickness_taper": t})
    n = fw.n_modal
    # built independently: the nominal plate, the taper field, the declared accelerometer masses
    model = PlateModel.build(pr.laminate, pr.length, pr.width, (4, 4))
    model = model.with_thickness_field(taper(t, pr.length)).with_point_masses(pr.rig.masses())
    np.testing.assert_allclose(y1[:n], model.solve(n, params=p).frequencies_hz, rtol=1e-8)
    assert np.abs(y1[:n] / y0[:n] - 1).max() > 1e-3
    np.testing.assert_array_equal(y1[n:], y0[n:])        # waves see the mean thickness
    # the bare plate is symmetric about x = L/2 (the rig is not): the sign of the taper is not seen
    bare = PlateModel.build(pr.laminate, pr.length, pr.width, (4, 4))
    fp = bare.with_thickness_field(taper(t, pr.length)).solve(n, params=p).frequencies_hz
    fm = bare.with_thickness_field(taper(-t, pr.length)).solve(n, params=p).frequencies_hz
    np.testing.assert_allclose(fp, fm, rtol=1e-7)


def test_stiffness_loss_on_a_field_is_that_of_the_local_laminate(base):
    # the loss removes a fraction of the local (field-scaled) stiffness: with a uniform field
    # it equals the loss on the scaled laminate
    s, p = 1.04, T300.params()
    ref = base.with_laminate(CFRP.scaled_thickness(s)).with_stiffness_loss(0.1, 0.2, 0.06, 0.4, p)
    fld = base.with_thickness_field(np.full(base.mesh.n_elements, s)).with_stiffness_loss(0.1, 0.2, 0.06, 0.4, p)
    assert abs(ref.k_add - fld.k_add).max() <= 1e-12 * abs(ref.k_add).max()
    assert abs(ref.k_add).max() > 0
