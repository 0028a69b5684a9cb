"""bench.independent.ritz_plate (the gap bench's independent plate) against published values
(ORACLES.md), a rigid-body limit, the Ritz bound and the engine at a fine mesh."""
import tomllib
from importlib import resources

import numpy as np
import pytest
import scipy.linalg as sl

from bench.independent.ritz_plate import Ply, RitzPlate, laminate_matrices, plies_from_table
from engine.laminate import Laminate, Material
from engine.laminate import Ply as EPly
from engine.laminate import abdh
from engine.plate import Mesh, PlateModel

NAFEMS_FV12 = np.array([1.622, 2.360, 2.922, 4.190, 4.190, 7.356, 7.356, 7.668])
LEISSA_FREE_SQUARE = np.array([13.47, 19.60, 24.27, 34.80, 34.80, 61.09, 61.09, 63.69])
T300 = dict(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9)


def _cfrp_table():
    return tomllib.loads(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text())


def test_laminate_matrices_equal_the_engine_s_for_an_unsymmetric_angle_ply():
    angles, t = (0.0, 30.0, -60.0, 90.0, 17.0), 2e-4
    plies = [Ply(T300, 1560.0, a, t) for a in angles]
    mine = laminate_matrices(plies)
    mat = Material(**T300, density=1560.0, name="T300")
    ref = abdh(Laminate(tuple(EPly(mat, a, t) for a in angles)))
    for k in "ABD":
        np.testing.assert_allclose(mine[k], getattr(ref, k), rtol=1e-12, atol=1e-12 * np.abs(mine[k]).max())
    np.testing.assert_allclose(mine["H"], ref.H, rtol=1e-12)
    np.testing.assert_allclose(mine["I"], [ref.I1, ref.I2, ref.I3], rtol=1e-12, atol=1e-25)
    assert np.abs(mine["B"]).max() > 1e3          # the case really couples membrane and bending


def test_nafems_fv12_and_leissa_thin_limit():
    steel = {"E": 200e9, "nu": 0.3}
    fv = RitzPlate([Ply(steel, 8000.0, 0.0, 0.05)], 10.0, 10.0, order=8).solve(8)
    np.testing.assert_allclose(fv.frequencies_hz, NAFEMS_FV12, rtol=5e-3)
    assert np.all(fv.rigid_hz < 1e-4 * fv.frequencies_hz[0])       # six rigid-body modes at zero
    h, a, E, nu, rho = 1e-3, 1.0, 200e9, 0.3, 8000.0
    f = RitzPlate([Ply(steel, rho, 0.0, h)], a, a, order=8).solve(8).frequencies_hz
    lam = 2 * np.pi * f * a ** 2 * np.sqrt(rho * h * 12 * (1 - nu ** 2) / (E * h ** 3))
    np.testing.assert_allclose(lam, LEISSA_FREE_SQUARE, rtol=1e-3)   # Leissa's table has 4 digits


def test_frequencies_fall_with_the_order_and_converge():
    """Ritz bound: nested bases give upper bounds falling monotonically to the limit."""
    plies, L, W = plies_from_table(_cfrp_table())
    f = [RitzPlate(plies, L, W, order=o).solve(8).frequencies_hz for o in (6, 8, 10)]
    assert np.all(f[0] >= f[1] * (1 - 1e-12)) and np.all(f[1] >= f[2] * (1 - 1e-12))
    assert np.max(f[1] / f[2] - 1) < 1e-3 and np.max(f[1] / f[2] - 1) < np.max(f[0] / f[1] - 1)


def test_suspension_modes_match_the_rigid_plate_on_springs():
    """Springs lift the three out-of-plane rigid-body modes; for soft springs they are the modes
    of a rigid plate on those springs (3 x 3 problem: bounce and two rockings)."""
    steel = {"E": 200e9, "nu": 0.3}
    L, W, h, rho = 0.4, 0.3, 2e-3, 7800.0
    springs = [(0.05, 0.25, 150.0), (0.35, 0.25, 150.0), (0.2, 0.02, 300.0)]
    modes = RitzPlate([Ply(steel, rho, 0.0, h)], L, W, order=8, springs=springs).solve(4)
    m = rho * h * L * W
    M3 = np.diag([m, m * L ** 2 / 12, m * W ** 2 / 12])
    K3 = sum(k * np.outer(v, v) for x, y, k in springs for v in [np.array([1.0, x - L / 2, y - W / 2])])
    rig = np.sqrt(sl.eigh(K3, M3, eigvals_only=True)) / (2 * np.pi)
    lifted = np.sort(modes.rigid_hz)[-3:]
    np.testing.assert_allclose(lifted, rig, rtol=2e-3)
    assert np.all(np.sort(modes.rigid_hz)[:3] < 1e-3)                  # in-plane ones stay at zero
    free = RitzPlate([Ply(steel, rho, 0.0, h)], L, W, order=8).solve(4).frequencies_hz
    assert np.all(modes.frequencies_hz > free)                         # springs stiffen the elastic modes


@pytest.fixture(scope="module")
def engine_case():
    """CFRP with the top ply 6 deg off, two 5 g masses, two 400 N/m springs, a 6 % taper."""
    tab = _cfrp_table()
    L, W = 0.33, 0.33
    masses = [(0.02, 0.02, 0.005), (0.31, 0.02, 0.005)]
    springs = [(0.03, 0.33, 400.0), (0.30, 0.33, 400.0)]
    taper = lambda x, y: 1.0 + 0.06 * (2 * x / L - 1)                       # noqa: E731
    plies, _, _ = plies_from_table(tab, top_offset=6.0)
    ritz = RitzPlate(plies, L, W, order=10, masses=masses, springs=springs, thickness_field=taper)
    f_ritz = ritz.solve(10).frequencies_hz
    mat = Material(**T300, density=1560.0, name="T300")
    angles = tab["layup"]["angles_deg"]
    lam = Laminate(tuple(EPly(mat, a + (6.0 if i == len(angles) - 1 else 0.0), 1.3333e-4)
                         for i, a in enumerate(angles)))
    fe = PlateModel.build(lam, L, W, Mesh.default(L, W, lam.thickness, n=12))
    fe = fe.with_thickness_field(taper).with_point_masses(masses).with_springs(springs)
    return f_ritz, fe.solve(10).frequencies_hz


def test_agrees_with_the_engine_at_a_fine_mesh(engine_case):
    f_ritz, f_fe = engine_case
    np.testing.assert_allclose(f_ritz, f_fe, rtol=2e-4)         # measured 6e-5


def test_uniform_fields_equal_scaled_plies_and_density():
    plies, L, W = plies_from_table(_cfrp_table())
    thick = [Ply(p.constants, p.density * 0.9, p.angle_deg, p.thickness * 1.07) for p in plies]
    a = RitzPlate(plies, L, W, order=6, thickness_field=lambda x, y: 1.07 + 0 * x,
                  density_field=lambda x, y: 0.9 + 0 * x).solve(6).frequencies_hz
    b = RitzPlate(thick, L, W, order=6, layers=(0.5 / 1.07, 2.0 / 1.07)).solve(6).frequencies_hz   # same basis
    np.testing.assert_allclose(a, b, rtol=1e-10)
