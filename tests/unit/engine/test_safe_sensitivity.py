"""The analytic group-velocity Jacobian (engine.safe.group_velocity_jacobian, the wave blocks'
Jacobian) against central differences of the UNREDUCED SAFE model (Newton on the full class
model, ``solve_full``: no Ritz basis, no branch series) and against an exact scaling law."""
from __future__ import annotations

import numpy as np
import pytest

from engine.forward import wave_block
from engine.laminate import Laminate, Material, Ply
from engine.safe import dispersion, group_velocity, safe_model
from engine.safe.branches import solve_full
from engine.safe.labels import fundamental_rows

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")
LAM = Laminate(tuple(Ply(T300, float(a), 0.25e-3) for a in (0, 45, -45, 90, 90, -45, 45, 0)))
NAMES = ["E1", "E2", "nu12", "G12", "G13", "G23"]
P0 = {n: float(getattr(T300, n)) for n in NAMES}
F = np.array([15e3, 60e3, 150e3])


def _full_cg(params, mode, direction, order, epp, k_start):
    """c_g of ``mode`` by Newton on the full (unreduced) class model at each frequency."""
    m = safe_model(LAM.with_params(params), direction, order=order, elements_per_ply=epp)
    row = next(r for r in fundamental_rows(m) if r["label"] == mode)
    return np.array([solve_full(m.classes[row["ci"]], 2 * np.pi * f, row["j"], k, tol=1e-15)[1]
                     for f, k in zip(F, k_start)])


@pytest.mark.parametrize("mode,direction", [("A0", 0.0), ("S0", 30.0)])
def test_jacobian_matches_central_differences_of_the_full_model(mode, direction):
    blk = wave_block(LAM, F, np.ones(3), np.ones(3), mode=mode, direction_deg=direction)
    cg, J = blk.jacobian(P0, NAMES)
    assert np.array_equal(cg, group_velocity(LAM, F, mode, direction))     # the prediction itself
    m0 = safe_model(LAM, direction, fmax_hz=F.max())
    k0 = dispersion(LAM, F, direction).mode(mode).wavenumber_rad_m
    Jf = np.empty_like(J)
    for i, n in enumerate(NAMES):
        h = 1e-4 * P0[n]
        Jf[:, i] = (_full_cg({**P0, n: P0[n] + h}, mode, direction, m0.order, m0.elements_per_ply, k0)
                    - _full_cg({**P0, n: P0[n] - h}, mode, direction, m0.order, m0.elements_per_ply, k0)) / (2 * h)
    L = np.array([P0[n] for n in NAMES])                   # d c_g / d log p, m/s
    scale = np.abs(Jf * L).max()
    # measured: <= 6e-6 of the largest entry (the Ritz basis' and the differences' own errors);
    # a wrong term (lambda_kk, lambda_kp, the mass term) is off by > 1e-2
    np.testing.assert_allclose(J * L, Jf * L, rtol=0, atol=5e-5 * scale)
    assert np.all(np.abs(Jf * L).max(axis=0) > 1e-3 * scale) or mode == "S0"


def test_stiffness_and_density_scaling_law():
    """Scaling every modulus and the density by s leaves every wave speed unchanged, so
    sum over the moduli of p dc_g/dp = -rho dc_g/drho exactly (the Poisson ratios do not scale)."""
    names = NAMES + ["density"]
    p = {**P0, "density": T300.density}
    blk = wave_block(LAM, F, np.ones(3), np.ones(3), mode="A0", direction_deg=20.0)
    _, J = blk.jacobian(p, names)
    moduli = sum(p[n] * J[:, i] for i, n in enumerate(names) if n[0] in "EG")
    rho = p["density"] * J[:, names.index("density")]
    assert np.all(np.abs(rho) > 100.0)                       # m/s per unit log rho: not a zero test
    np.testing.assert_allclose(moduli, -rho, rtol=1e-6)


def test_custom_group_velocity_keeps_differences():
    blk = wave_block(LAM, F, np.ones(3), np.ones(3), group_velocity=lambda lam, f, **kw: np.ones(len(f)))
    assert blk.jacobian is None


def test_jacobian_without_a_root_is_unphysical(monkeypatch):
    """Where the mode has no root the block says ValueError (the estimators shorten the step),
    as the estimator's own check of predictions does: no NaN reaches the fit."""
    import engine.forward.waves as fw
    real = fw.group_velocity_jacobian

    def no_root_at_the_second(*a, **k):
        cg, jac = real(*a, **k)
        jac[1] = np.nan
        return cg, jac
    monkeypatch.setattr(fw, "group_velocity_jacobian", no_root_at_the_second)
    blk = wave_block(LAM, F, np.ones(3), np.ones(3))
    with pytest.raises(ValueError, match="no root"):
        blk.jacobian(P0, NAMES)
