"""The branch series' roots, all branches of a class at once (issue 29, session 26).

``roots_from_series`` evaluates every branch's series in one ``chebval`` per step; the
roots must be bit for bit those of one call per branch, and the group velocities the exact
Rayleigh-Lamb ones (1 mm aluminium, E = 70 GPa, nu = 0.33, 2700 kg/m^3; the values of
engine.safe's docstring, f h = 0.1 / 0.5 MHz mm: A0 1783.696 / 2908.787 m/s, S0 5391.689 /
5335.510 m/s)."""
import numpy as np
import pytest

from engine.laminate import Laminate, Material, Ply
from engine.safe import safe_model
from engine.safe.branches import cheb_branches, reduce_class
from engine.safe.roots import roots_from_series

EXACT = {"A0": (1783.696, 2908.787), "S0": (5391.689, 5335.510)}


@pytest.fixture(scope="module")
def classes():
    al = Laminate([Ply(Material.isotropic_from(70e9, 2700.0, nu=0.33), 0.0, 1e-3)])
    model = safe_model(al, 0.0, fmax_hz=1.2e6)
    w = 2 * np.pi * np.r_[np.linspace(2e4, 1.2e6, 40), 1e5, 5e5]
    out = []
    for cls in model.classes:
        red = reduce_class(cls, float(w.max()))
        if red is not None:
            out.append((cheb_branches(red, red.n_branches), w))
    return out


def test_all_branches_at_once_equal_one_call_per_branch(classes):
    n_checked = 0
    for br, w in classes:
        js = [j for j in range(br.lam.shape[1]) if br.converged[j]]
        k_all, dl_all = roots_from_series(br, w, js)
        assert k_all.shape == (len(js), len(w))
        for i, j in enumerate(js):
            k1, dl1 = roots_from_series(br, w, j)
            assert np.array_equal(k1, k_all[i], equal_nan=True)
            assert np.array_equal(dl1, dl_all[i], equal_nan=True)
            n_checked += int(np.isfinite(k1).sum())
    assert n_checked > 100                      # several branches, most frequencies have a root


def test_fundamental_group_velocities_are_rayleigh_lamb(classes):
    found = {}
    for br, w in classes:
        js = [j for j in range(br.lam.shape[1]) if br.converged[j]]
        _, dl = roots_from_series(br, w, js)
        cg = dl[:, -2:] / (2 * w[-2:])          # at 100 kHz and 500 kHz
        for row in cg:
            for name, ref in EXACT.items():
                if np.allclose(row, ref, rtol=1e-6):
                    found[name] = row
    assert set(found) == set(EXACT)
