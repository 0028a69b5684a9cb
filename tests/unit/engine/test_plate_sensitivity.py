"""engine.plate.geometry_sensitivities: d lambda from one solve against exact laws and re-solves.

Exact references (not from the code):
* lambda is proportional to 1/rho for a plate without added masses (K does not depend on rho,
  M is linear in it): d lambda / d(density scale) = -lambda;
* thin isotropic plate (Kirchhoff limit): f ~ h / a^2 sqrt(E / rho), so lambda ~ s^2 under a
  thickness scale s and ~ alpha^-4 under a uniform stretch alpha of the plate in x and y:
  d lambda/ds = 2 lambda, d lambda/d alpha_x + d lambda/d alpha_y = -4 lambda, to O((h/a)^2);
* every other input against central differences of re-solved, rebuilt models (mesh stretched,
  masses moved), the independent way of getting the same numbers.
"""
from __future__ import annotations

import numpy as np
import pytest

from engine.forward import pair_by_mac
from engine.laminate import Laminate, Material, Ply
from engine.plate import Mesh, PlateModel, geometry_sensitivities

L0, W0 = 0.30, 0.20
MASSES = [(0.07, 0.06, 0.01), (0.22, 0.13, 0.006)]   # inside elements (the FE slope jumps at edges)
N = 8


def _laminate(h: float) -> Laminate:
    mat = Material.isotropic_from(70e9, 2700.0, G=26.3e9, name="Al")
    return Laminate((Ply(mat, 0.0, h),))


def _mesh(L=L0, W=W0) -> Mesh:
    return Mesh(5, 4, L, W)


@pytest.fixture(scope="module")
def thin():
    model = PlateModel.build(_laminate(3e-4), L0, W0, mesh=_mesh())
    modes = model.solve(N)
    return modes, geometry_sensitivities(model, modes)


def test_density_is_exactly_inverse_without_masses(thin):
    modes, g = thin
    np.testing.assert_allclose(g["density"], -modes.omega2, rtol=1e-10)


def test_thin_plate_thickness_and_stretch_scaling(thin):
    modes, g = thin
    np.testing.assert_allclose(g["thickness"], 2.0 * modes.omega2, rtol=1e-4)
    np.testing.assert_allclose(g["length"] + g["width"], -4.0 * modes.omega2, rtol=1e-4)
    assert not np.any(g["masses_x"]) and not np.any(g["masses_y"])


def test_every_input_against_central_differences_of_re_solved_models():
    h = 2e-3                           # Mindlin plate, where the thin-plate laws do not hold
    lam = _laminate(h)
    base = PlateModel.build(lam, L0, W0, mesh=_mesh()).with_point_masses(MASSES)
    m0 = base.solve(N + 3)
    g = geometry_sensitivities(base, m0, MASSES)

    def omega2(model, params=None):
        mo = model.solve(N + 3, params=params)
        j, _ = pair_by_mac(m0.shapes[:, :N].T, mo.shapes.T)   # follow the modes, not the order
        return mo.omega2[j]

    def stretched(sx, sy, dx=0.0, dy=0.0):
        return PlateModel.build(lam, L0 * sx, W0 * sy, mesh=_mesh(L0 * sx, W0 * sy)).with_point_masses(
            [(x + dx, y + dy, m) for x, y, m in MASSES])

    cases = {
        "thickness": lambda s: omega2(base.with_laminate(lam.scaled_thickness(1 + s))),
        "density": lambda s: omega2(base, {"density": 2700.0 * (1 + s)}),
        "length": lambda s: omega2(stretched(1 + s, 1.0)),
        "width": lambda s: omega2(stretched(1.0, 1 + s)),
        "masses_x": lambda s: omega2(stretched(1.0, 1.0, dx=s)),
        "masses_y": lambda s: omega2(stretched(1.0, 1.0, dy=s)),
    }
    for name, f in cases.items():
        # steps where the truncation error (~step^2: 4e-4 of the scale at a 3e-3 stretch) and
        # the eigen-solver's noise (~1e-9 lambda / step) are both ~1e-6 of the scale
        step = 1e-4 if name.startswith("masses") else 3e-4
        fd = (f(step) - f(-step)) / (2 * step)
        scale = np.abs(fd).max()
        assert scale > 0
        np.testing.assert_allclose(g[name][:N], fd, atol=2e-5 * scale, err_msg=name)
