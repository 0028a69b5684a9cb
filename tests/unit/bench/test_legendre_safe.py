"""bench/independent/legendre_safe.py, the independent guided-wave model of the wave benches:
against the exact Rayleigh-Lamb roots (ORACLES.md) and converged in its order."""
from __future__ import annotations

import numpy as np
import pytest

from bench.independent.legendre_safe import LegendrePlate, branches, layers_of, transfer

# ORACLES.md: aluminium E = 70 GPa, nu = 0.33, rho = 2700, h = 1 mm; exact Rayleigh-Lamb c_g
E, NU, RHO, H = 70e9, 0.33, 2700.0, 1e-3
G = E / (2 * (1 + NU))
AL = dict(E1=E, E2=E, E3=E, nu12=NU, nu13=NU, nu23=NU, G12=G, G13=G, G23=G, density=RHO)
TABLE = {0.1: (1783.696, 5391.689), 0.5: (2908.787, 5335.510), 1.0: (3137.051, 5118.634)}


@pytest.fixture(scope="module")
def al_plate():
    return LegendrePlate(layers_of([(AL, 0.0, H)]), 6)


def test_the_roots_at_a_frequency_are_the_exact_rayleigh_lamb_ones(al_plate):
    """The quadratic eigenproblem's real roots give A0 and S0 group velocities within 1e-6 of
    the exact table (f h = 0.1, 0.5, 1.0 MHz mm)."""
    for fh, (a0, s0) in TABLE.items():
        cg = sorted(r[1] for r in al_plate.roots(fh * 1e6 / (H * 1e3)))
        assert min(abs(c / a0 - 1) for c in cg) < 1e-6
        assert min(abs(c / s0 - 1) for c in cg) < 1e-6


def test_the_branch_tables_give_the_same_velocities(al_plate):
    """The Hermite-inverted branches w_j(k): branch 0 is A0, branch 2 S0 (below the first
    cut-off), within 2e-5 of the table (c_g linear between the 600 wavenumbers)."""
    f = np.array([0.5e6, 1.0e6])
    br = branches(al_plate, 1.1e6)
    assert br.at(0, 2 * np.pi * f)[1] == pytest.approx([TABLE[0.5][0], TABLE[1.0][0]], rel=2e-5)
    assert br.at(2, 2 * np.pi * f)[1] == pytest.approx([TABLE[0.5][1], TABLE[1.0][1]], rel=2e-5)


def test_a_laminate_converges_in_the_element_order():
    """A 12-ply [0/+-45]2s CFRP along 30 deg: A0 and S0 c_g at 200 kHz agree between orders
    3 and 5 within 1e-6 (one hierarchical element per ply)."""
    m = dict(E1=136.7e9, E2=9e9, E3=9e9, nu12=0.3, nu13=0.3, nu23=9e9 / (2 * 3.16e9) - 1, G12=5e9, G13=5.08e9,
             G23=3.16e9, density=1560.0)
    plies = [(m, a, 1.3333e-4) for a in (0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0)]
    cg = [sorted(r[1] for r in LegendrePlate(layers_of(plies, 30.0), p).roots(200e3)) for p in (3, 5)]
    assert cg[0] == pytest.approx(cg[1], rel=1e-6)


def test_point_force_strain_decays_as_a_cylindrical_wave(al_plate):
    """Far from a point force the radial strain of each mode falls as 1/sqrt(r): |H| r^1/2 the
    same at 0.3 and 1.2 m within 1 % (the Hankel kernels' far field)."""
    f = np.array([300e3])
    h1, h2 = (transfer(al_plate, r, f) for r in (0.3, 1.2))
    for key in h1:
        if abs(h1[key][0]) > 0:
            assert abs(h1[key][0]) * np.sqrt(0.3) == pytest.approx(abs(h2[key][0]) * np.sqrt(1.2), rel=1e-2)
