"""engine.plate against published values (ORACLES.md), energy bounds and limits."""
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp

from engine.laminate import Laminate, Material, Ply, abdh
from engine.plate import FEError, Mesh, PlateModel, coefficients_from_abdh, natural_frequencies
from engine.plate.element import combo_scales, reference_matrices
from labid.inputs.specimen import load_specimen

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")
CFRP_ANGLES = [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0]
CFRP = Laminate(tuple(Ply(T300, a, 1.3333e-4) for a in CFRP_ANGLES))
A_CFRP = 0.33
STEEL = Material.isotropic_from(200e9, 8000.0, nu=0.3, name="steel")
ALU = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="alu")

NAFEMS_FV12 = np.array([1.622, 2.360, 2.922, 4.190, 4.190, 7.356, 7.356, 7.668])
LEISSA_FREE_SQUARE = np.array([13.47, 19.60, 24.27, 34.80, 34.80, 61.09, 61.09, 63.69])


@pytest.fixture(scope="module")
def cfrp_model():
    return PlateModel.build(CFRP, A_CFRP, A_CFRP)


@pytest.fixture(scope="module")
def cfrp_modes(cfrp_model):
    return cfrp_model.solve(10)


def test_nafems_fv12_default_mesh():
    lam = Laminate((Ply(STEEL, 0.0, 0.05),))
    modes = PlateModel.build(lam, 10.0, 10.0).solve(8)
    np.testing.assert_allclose(modes.frequencies_hz, NAFEMS_FV12, rtol=5e-3)
    # the six excluded modes are rigid: zero frequency up to round-off
    assert modes.rigid_max_omega < 1e-3 * np.sqrt(modes.omega2[0])
    assert np.all(np.diff(modes.frequencies_hz) >= 0)


def _leissa(h_over_a):
    a, nu, E, rho = 1.0, 0.3, 200e9, 8000.0
    h = h_over_a * a
    lam = Laminate((Ply(STEEL, 0.0, h),))
    D = E * h**3 / (12 * (1 - nu**2))
    om = np.sqrt(PlateModel.build(lam, a, a).solve(8).omega2)
    return om * a**2 * np.sqrt(rho * h / D)


def test_leissa_thin_plate_limit_and_thick_plate_below():
    errs = [np.max(np.abs(_leissa(r) / LEISSA_FREE_SQUARE - 1)) for r in (0.02, 0.005, 0.001)]
    assert errs[0] > errs[1] > errs[2]            # approached as h/a -> 0
    assert errs[2] < 1e-3                          # Leissa's table has 4 digits
    thick = _leissa(0.1)
    assert np.all(thick < LEISSA_FREE_SQUARE * 0.97)  # shear and rotary inertia lower them


@pytest.mark.parametrize("lam", [
    CFRP,
    Laminate((Ply(STEEL, 0.0, 0.002), Ply(ALU, 0.0, 0.004))),            # B != 0, I2 != 0
    Laminate(tuple(Ply(T300, a, 4e-4) for a in (0, 90, 30))),              # B != 0, A16 != 0
])
def test_exactly_six_zero_energy_modes(lam):
    """Full spectrum of a small mesh: the six rigid-body modes and no spurious (hourglass) one."""
    m = PlateModel.build(lam, 0.3, 0.2, (2, 3))
    K, M = m.matrices()
    K, M = K.toarray(), M.toarray()
    np.testing.assert_allclose(K, K.T, atol=1e-9 * np.abs(K).max())
    R = m.rigid_body_vectors()
    assert np.abs(K @ R).max() < 1e-8 * np.abs(K).max() * np.abs(R).max()
    w = sl.eigh(K, M, eigvals_only=True)
    assert np.sum(np.abs(w) < 1e-4 * w[6]) == 6    # rigid: round-off of ~1e-16 * w.max()
    assert w[6] > 0


def test_cfrp_default_mesh_converged(cfrp_modes):
    """Default mesh vs a much finer graded one (its convergence limit to ~1e-5)."""
    t = CFRP.thickness
    fine = Mesh.graded(A_CFRP, A_CFRP, 8, [t / 2, 2 * t, 8 * t])
    ref = PlateModel.build(CFRP, A_CFRP, A_CFRP, fine).solve(10).frequencies_hz
    np.testing.assert_allclose(cfrp_modes.frequencies_hz, ref, rtol=1e-3)
    # a uniform mesh of the same size converges only like O(h) at the free edges
    uni = PlateModel.build(CFRP, A_CFRP, A_CFRP, (8, 8)).solve(10).frequencies_hz
    assert np.max(np.abs(uni / ref - 1)) > 2 * np.max(np.abs(cfrp_modes.frequencies_hz / ref - 1))


@pytest.mark.parametrize("size", [(0.6, 0.2), (0.2, 0.45)])
def test_default_mesh_converged_on_rectangles(size):
    L, W = size
    t = CFRP.thickness
    f = PlateModel.build(CFRP, L, W).solve(10).frequencies_hz
    fine = Mesh.graded(L, W, 16, [t / 2, 2 * t, 8 * t])
    ref = PlateModel.build(CFRP, L, W, fine).solve(10).frequencies_hz
    np.testing.assert_allclose(f, ref, rtol=1e-3)


def test_coefficients_reproduce_abdh(cfrp_model):
    c, inert = cfrp_model.coefficients()
    c_ref, i_ref = coefficients_from_abdh(abdh(CFRP))
    np.testing.assert_allclose(c, c_ref, rtol=1e-12, atol=1e-12 * np.abs(c_ref).max())
    np.testing.assert_allclose(inert, i_ref, rtol=1e-12, atol=1e-16)


def test_mass_normalised_shapes_and_points(cfrp_model, cfrp_modes):
    K, M = cfrp_model.matrices()
    phi = cfrp_modes.shapes
    np.testing.assert_allclose(phi.T @ (M @ phi), np.eye(phi.shape[1]), atol=1e-8)
    np.testing.assert_allclose(np.diag(phi.T @ (K @ phi)), cfrp_modes.omega2, rtol=1e-8)
    # at nodes, shapes_at returns the w0 DOF values
    mesh = cfrp_model.mesh
    nodes = np.array([0, 7, mesh.n_nodes // 2, mesh.n_nodes - 1])
    np.testing.assert_allclose(cfrp_model.shapes_at(cfrp_modes, mesh.coords[nodes]),
                               phi[5 * nodes + 2].T, atol=1e-12)
    # partition of unity: the rigid z translation is 1 everywhere
    pts = np.random.default_rng(0).uniform(0, A_CFRP, (50, 2))
    T = cfrp_model.interpolation(pts)
    np.testing.assert_allclose(T @ cfrp_model.rigid_body_vectors()[:, 2], 1.0, rtol=1e-12)
    with pytest.raises(FEError):
        cfrp_model.shapes_at(cfrp_modes, [[0.1, 0.5]])


def test_point_mass_first_order_estimate(cfrp_model, cfrp_modes):
    """A 1 % point mass at an antinode: df/f ~ -m phi^2 / 2 (first-order perturbation),
    the estimate becoming exact as the mass goes to zero."""
    plate_mass = A_CFRP**2 * CFRP.thickness * T300.density
    g = np.linspace(0, A_CFRP, 34)
    pts = np.array([(x, y) for x in g for y in g])
    for mode in (0, 1):
        w = cfrp_model.shapes_at(cfrp_modes, pts)[mode]
        x, y = pts[np.argmax(np.abs(w))]
        phi2 = cfrp_model.shapes_at(cfrp_modes, [[x, y]])[mode, 0] ** 2
        for frac, tol in ((0.01, 0.1), (1e-4, 2e-3)):
            m = frac * plate_mass
            new = cfrp_model.with_point_masses([(x, y, m)]).solve(10)
            rel = new.frequencies_hz[mode] / cfrp_modes.frequencies_hz[mode] - 1
            est = -0.5 * m * phi2
            assert rel == pytest.approx(est, rel=tol)
        assert 0.5 * 0.01 * plate_mass * phi2 > 0.01   # an antinode: a visible shift


def test_spring_bounce_mode_and_rotary_inertia():
    """A soft spring at the centre: the z-translation becomes a bounce at sqrt(k / m_total)."""
    a, b = 0.3, 0.2
    lam = Laminate((Ply(ALU, 0.0, 0.003),))
    model = PlateModel.build(lam, a, b)
    m_total = a * b * 0.003 * ALU.density
    k = m_total * (2 * np.pi * 1.0) ** 2        # 1 Hz bounce, far below the first mode
    sprung = model.with_springs([(a / 2, b / 2, k)])
    assert sprung.solve(4).rigid_max_omega == pytest.approx(2 * np.pi, rel=1e-4)
    extra = 0.05
    loaded = sprung.with_point_masses([(a / 2, b / 2, extra)])
    assert loaded.solve(4).rigid_max_omega == pytest.approx(
        np.sqrt(k / (m_total + extra)), rel=1e-4)
    # rotary inertia: first-order shift -1/2 (Iy bx^2 + Ix by^2) of the mode turning most there
    base = model.solve(6)
    c = [[a / 2, b / 2]]
    bx = (model.interpolation(c, component=3) @ base.shapes)[0]
    by = (model.interpolation(c, component=4) @ base.shapes)[0]
    i = int(np.argmax(bx**2 + by**2))
    inertia = 2e-3 / (bx[i] ** 2 + by[i] ** 2)
    rot = model.with_point_masses([(a / 2, b / 2, 0.0, inertia, inertia)]).solve(6)
    est = -0.5 * inertia * (bx[i] ** 2 + by[i] ** 2)
    assert rot.frequencies_hz[i] / base.frequencies_hz[i] - 1 == pytest.approx(est, rel=0.05)
    with pytest.raises(FEError):
        model.with_point_masses([(0.1, 0.1)])


def test_recombined_solve_equals_rebuilt_model(cfrp_model):
    p = {"E1": 120e9, "G12": 4.2e9, "nu12": 0.27, "density": 1500.0}
    f1 = cfrp_model.solve(10, params=p).frequencies_hz
    lam = CFRP.with_params(p)
    f2 = PlateModel.build(lam, A_CFRP, A_CFRP, cfrp_model.mesh).solve(10).frequencies_hz
    np.testing.assert_allclose(f1, f2, rtol=1e-9)
    np.testing.assert_allclose(natural_frequencies(lam, A_CFRP, A_CFRP, n=10), f2, rtol=1e-9)


def _fd_check(model, base, names, n=6, material=None, rel_step=1e-5):
    modes = model.solve(n, params=base, material=material)
    sens = model.eigen_sensitivities(modes, names)
    assert sens.shape == (n, len(names))
    for j, name in enumerate(names):
        h = rel_step * base[name]
        up = model.solve(n, params={**base, name: base[name] + h}, material=material).omega2
        dn = model.solve(n, params={**base, name: base[name] - h}, material=material).omega2
        fd = (up - dn) / (2 * h)
        scale = np.abs(modes.omega2) / abs(base[name])  # d lambda/dp is O(lambda/p)
        np.testing.assert_allclose(sens[:, j], fd, rtol=0, atol=2e-5 * scale.max(),
                                   err_msg=name)


def test_sensitivities_orthotropic_vs_finite_differences():
    model = PlateModel.build(CFRP.scaled_thickness(4.0), 0.3, 0.22, (3, 3))  # thick: G13, G23 matter
    names = ["E1", "E2", "nu12", "G12", "G13", "G23", "density"]
    base = T300.params()
    _fd_check(model, base, names)
    # sensor masses and suspension springs do not depend on the constants
    loaded = model.with_point_masses([(0.02, 0.03, 0.004, 1e-7, 1e-7)]).with_springs([(0.15, 0.2, 50.0)])
    _fd_check(loaded, base, ["E1", "G12", "density"])


def test_sensitivities_isotropic_and_two_materials():
    lam = Laminate((Ply(STEEL, 0.0, 0.004), Ply(ALU, 0.0, 0.006)))
    model = PlateModel.build(lam, 0.3, 0.22, (3, 3))
    _fd_check(model, {"E": 70e9, "G": 26e9, "density": 2700.0}, ["E", "G", "density"],
              material="alu")
    _fd_check(model, {"E": 200e9, "nu": 0.3}, ["nu"], material="steel")


def test_unsymmetric_layup_energy_bounds_and_mirror():
    """B != 0: with N free the pointwise minimum of the membrane + coupling energy gives the
    reduced bending stiffness D* = D - B A^-1 B (a lower bound, up to the small in-plane
    inertia); clamping u0 = v0 = 0 gives D alone (an upper bound). Free edges leave N ~ 0,
    so the coupled frequencies sit at the D* end. Turning the plate upside down (B -> -B,
    I2 -> -I2) cannot change any frequency.
    """
    for lam in (Laminate(tuple(Ply(T300, a, 4e-4) for a in (0, 90, 0, 90))),
                Laminate((Ply(STEEL, 0.0, 0.002), Ply(ALU, 0.0, 0.004)))):
        r = abdh(lam)
        assert np.abs(r.B).max() > 1e-3 * np.abs(r.A).max() * lam.thickness
        model = PlateModel.build(lam, 0.3, 0.2)
        f = model.solve(8).frequencies_hz
        c, inert = coefficients_from_abdh(r)
        c0 = c.copy()
        c0[6:12] = 0.0
        i0 = inert.copy()
        i0[1] = 0.0
        f_upper = model.solve_coefficients(c0, i0, 8).frequencies_hz
        d_star = r.D - r.B @ np.linalg.solve(r.A, r.B)
        c_lower = coefficients_from_abdh(replace(r, B=0 * r.B, D=d_star))[0]
        f_lower = model.solve_coefficients(c_lower, i0, 8).frequencies_hz
        assert np.all(f < f_upper)
        pos = (f - f_lower) / (f_upper - f_lower)
        assert np.all(pos > -0.01) and np.all(pos < 0.1)
        flipped = Laminate(tuple(reversed(lam.plies)))
        f_flip = PlateModel.build(flipped, 0.3, 0.2).solve(8).frequencies_hz
        np.testing.assert_allclose(f_flip, f, rtol=1e-7)


def test_bad_mesh_and_inputs():
    with pytest.raises(FEError):
        PlateModel.build(CFRP, 0.3, 0.3, (0, 4))
    with pytest.raises(FEError):
        PlateModel.build(CFRP, 0.3, 0.3, (2.5, 4))
    with pytest.raises(FEError):
        PlateModel.build(CFRP, 0.3, 0.3, "8x8")
    with pytest.raises(FEError):
        Mesh.graded(0.3, 0.3, 4, [0.2])
    model = PlateModel.build(CFRP, 0.3, 0.3, (2, 2))
    with pytest.raises(FEError):
        model.solve(0)
    with pytest.raises(KeyError):
        model.solve(4, params={"E": 1e9})
    with pytest.raises(ValueError):
        model.solve(4, params={"E2": -1e9})


@pytest.mark.parametrize("lam", [
    Laminate((Ply(STEEL, 0.0, 0.09),)),                                   # symmetric: split solve
    Laminate((Ply(STEEL, 0.0, 0.03), Ply(ALU, 0.0, 0.06))),               # coupled solve
])
def test_sparse_solver_matches_dense_spectrum_with_inplane_modes(lam):
    """Thick plate (h/a = 0.3): in-plane (membrane) modes fall among the lowest ones;
    the shift-invert solve must return exactly the dense generalised spectrum."""
    model = PlateModel.build(lam, 0.3, 0.3, (3, 3))
    K, M = model.matrices()
    w = sl.eigh(K.toarray(), M.toarray(), eigvals_only=True)
    modes = model.solve(14)
    np.testing.assert_allclose(modes.omega2, w[6:20], rtol=1e-8)
    # in-plane modes are among them (u0, v0 carry most of their kinetic energy)
    uv = np.zeros(model.mesh.n_dof, bool)
    uv[0::5] = uv[1::5] = True
    share = np.einsum("ik,ij,jk->k", modes.shapes[uv], M.toarray()[np.ix_(uv, uv)], modes.shapes[uv])
    assert np.any(share > 0.9)


def test_density_scaling_through_the_mass_memo(cfrp_model, cfrp_modes):
    """f ~ 1/sqrt(rho) at fixed stiffness; alternating densities on one model
    (the mass data are memoised per density) must not reuse a stale M."""
    rho = T300.density
    f0 = cfrp_modes.frequencies_hz
    for k in (4.0, 1.0, 0.25, 4.0):
        f = cfrp_model.solve(10, params={"density": k * rho}).frequencies_hz
        np.testing.assert_allclose(f, f0 / np.sqrt(k), rtol=1e-9)
    K, M = cfrp_model.matrices({"density": 4.0 * rho})
    _, M1 = cfrp_model.matrices()
    M.data[:] = 0.0   # a returned M is the caller's own copy
    np.testing.assert_allclose(cfrp_model.matrices({"density": 4.0 * rho})[1].sum(), 4.0 * M1.sum(), rtol=1e-12)
    # total mass of the plate: translation vector r_x' M r_x
    r = cfrp_model.rigid_body_vectors()[:, 0]
    assert r @ (M1 @ r) == pytest.approx(A_CFRP**2 * CFRP.thickness * rho, rel=1e-12)


def test_membrane_solve_reuse_matches_dense_spectrum():
    """A thin plate first (membrane modes far above: later solves may reuse its
    membrane rigid modes), then constants that bring in-plane modes among the
    lowest (the eigenvalue bound must force a new membrane solve): every solve
    on the one model equals the dense generalised spectrum."""
    mat = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                   density=1560.0, name="T300")
    lam = Laminate((Ply(mat, 0.0, 0.01), Ply(mat, 90.0, 0.01), Ply(mat, 0.0, 0.01)))
    model = PlateModel.build(lam, 0.3, 0.3, (3, 3))
    seq = [{}, {"E1": 120e9}, {"E1": 130e9, "G13": 4e9}, {"E1": 4e9, "E2": 3e9, "G12": 0.05e9},
           {"E1": 150e9}, {"E1": 4e9, "E2": 3e9, "G12": 0.05e9}]
    shares = []
    for p in seq:
        K, M = model.matrices(p)
        w = sl.eigh(K.toarray(), M.toarray(), eigvals_only=True)
        modes = model.solve(8, params=p)
        np.testing.assert_allclose(modes.omega2, w[6:14], rtol=1e-8, err_msg=str(p))
        assert modes.rigid_max_omega < 1e-3 * np.sqrt(modes.omega2[0])
        uv = np.zeros(model.mesh.n_dof, bool)
        uv[0::5] = uv[1::5] = True
        shares.append(np.einsum("ik,ij,jk->k", modes.shapes[uv], M.toarray()[np.ix_(uv, uv)],
                                modes.shapes[uv]).max())
    assert shares[3] > 0.9 and shares[5] > 0.9   # in-plane modes among the lowest there
    assert max(shares[:3]) < 0.1                  # and not in the stiff cases


def test_stiffness_loss_over_the_whole_plate_scales_frequencies_by_sqrt():
    """A loss L over every element scales K by (1 - L): every frequency by sqrt(1 - L);
    a local loss lowers frequencies, never raises them (Rayleigh quotient)."""
    spec = load_specimen("cfrp")
    model = PlateModel.build(spec.laminate, spec.length, spec.width)
    f0 = model.solve(6).frequencies_hz
    whole = model.with_stiffness_loss(spec.length / 2, spec.width / 2, 2 * spec.length, 0.3)
    np.testing.assert_allclose(whole.solve(6).frequencies_hz, f0 * np.sqrt(0.7), rtol=1e-8)
    local = model.with_stiffness_loss(0.1, 0.1, 0.06, 0.5).solve(6).frequencies_hz
    assert np.all(local <= f0 * (1 + 1e-9)) and np.any(local < f0 * (1 - 1e-4))


def test_fixed_pattern_equals_scipy_coo_assembly():
    """The hand-made sparse pattern (engine.plate.sparse; kept because it builds K and M from
    new constants ~2.5x cheaper than scipy's COO assembly, bench/bench_plate_pattern.py) gives
    the matrices of the textbook assembly: every element's matrices summed by
    scipy.sparse.coo_matrix at its DOFs, on a graded mesh (several element sizes) with a
    non-symmetric layup (B != 0)."""
    lam = Laminate((Ply(T300, 0.0, 0.4e-3), Ply(T300, 30.0, 0.4e-3), Ply(ALU, 0.0, 0.8e-3)))
    model = PlateModel.build(lam, 0.3, 0.2)
    mesh = model.mesh
    params = {"E1": 120e9, "G13": 4e9, "density": 1500.0}
    K, M = model.matrices(params, material="T300")
    c, inert = model.coefficients(params, material="T300")
    Kref, Mref = reference_matrices()
    s = combo_scales(mesh.element_sizes)                                  # (ne, 6)
    Ke = s @ np.tensordot(c, Kref, axes=(0, 1)).reshape(6, -1)            # (ne, 6400)
    Me = np.outer(s[:, 0], np.tensordot(inert, Mref, 1).ravel())
    dofs = mesh.element_dofs
    rows, cols = np.repeat(dofs, 80, axis=1).ravel(), np.tile(dofs, (1, 80)).ravel()
    n = mesh.n_dof
    Kc = sp.coo_matrix((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    Mc = sp.coo_matrix((Me.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    assert len(np.unique(mesh.element_sizes, axis=0)) > 1
    assert abs(K - Kc).max() <= 1e-12 * abs(Kc).max()
    assert abs(M - Mc).max() <= 1e-12 * abs(Mc).max()
