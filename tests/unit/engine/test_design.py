"""engine.design against outside facts: the half-sine spectrum, the elastic scaling law of
the sensitivities, the nodal lines of a free rectangular plate, the first-order effect of a point
mass, and the reflection-free window of an exact geometry."""
from __future__ import annotations

import math

import numpy as np
import pytest

from engine.design import (DesignProblem, Measurement, candidate_grid, criterion, evaluate, half_sine_spectrum,
                           modal_set, optimise, prior_draws)
from engine.design.waves import Leg, Velocities, clearance, leg_points, leg_weights, wave_jacobian
from engine.laminate import Laminate, Material, Ply
from engine.plate import PlateModel
from engine.waves import Wavelet

AL = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="Al")
L, W = 0.30, 0.24      # not square: no degenerate mode pairs


@pytest.fixture(scope="module")
def plate():
    """A 300 x 240 mm, 2 mm aluminium plate (a coarse uniform mesh: cheap) and its modes at
    the nominal and two prior draws, sampled on a 9 x 9 grid plus three centre-line points."""
    lam = Laminate((Ply(AL, 0.0, 0.002),))
    model = PlateModel.build(lam, L, W, (6, 5))
    pts = candidate_grid(L, W, 9, 0.02)
    extra = np.array([[L / 2, 0.07], [0.07, W / 2], [L / 2, W / 2]])
    draws = prior_draws(AL, ("E", "G"), {"E": 0.1, "G": 0.1}, 3, seed=1)
    ms = modal_set(model, draws, ("E", "G"), np.vstack([pts, extra]), 12)
    return model, lam, ms, len(pts)


def test_half_sine_spectrum_is_the_fourier_transform_of_the_pulse():
    T = 2e-4
    assert half_sine_spectrum(0.0, T) == pytest.approx(1.0)
    assert half_sine_spectrum(0.5 / T, T) == pytest.approx(math.pi / 4)      # removable singularity
    assert half_sine_spectrum(1.0 / T, T) == pytest.approx(1.0 / 3.0)
    assert half_sine_spectrum(1.5 / T, T) == pytest.approx(0.0, abs=1e-12)   # first zero
    # numerical Fourier transform of sin(pi t / T) on [0, T]
    t = np.linspace(0, T, 20001)
    for f in (1234.0, 3000.0, 6000.0):
        F = np.trapezoid(np.sin(np.pi * t / T) * np.exp(-2j * np.pi * f * t), t)
        F0 = np.trapezoid(np.sin(np.pi * t / T), t)
        assert half_sine_spectrum(f, T) == pytest.approx(abs(F) / F0, rel=1e-6)
    m = Measurement(contact_s=T, f_max_hz=1e9)
    assert 1.0 / T < m.band_hz() < 1.5 / T                                    # -20 dB before the zero


def test_sensitivities_obey_the_elastic_scaling_law(plate):
    """Scaling every modulus by k scales every frequency by sqrt(k): sum_j dlnf/dlnp_j = 1/2."""
    _, _, ms, _ = plate
    s = ms.jac.sum(axis=2)
    assert np.allclose(s, 0.5, atol=2e-6)


def test_amplitude_vanishes_on_the_nodal_lines_of_the_torsion_mode(plate):
    """The (1,1) twisting mode of a free rectangular plate has its nodal lines on the centre
    lines (Leissa, NASA SP-160, ch. 4): a sensor there does not see it."""
    from engine.plate import mode_families
    model, _, ms, n = plate
    i = mode_families(model, ms.first_modes, L, W).index("(1,1) torsion")
    centre_x, centre_y = n, n + 1
    assert ms.amp[0, i, centre_x] < 1e-6 and ms.amp[0, i, centre_y] < 1e-6
    assert ms.amp[0, i, :n].max() > 0.5


def test_point_mass_column_matches_a_solve_with_the_mass(plate):
    """d ln f = -m phi^2 / 2 to first order: a 1 g mass at a grid point, solved."""
    model, _, ms, _ = plate
    k = 10
    m = 1e-3
    with_mass = model.with_point_masses([(*ms.points[k], m)]).solve(12)
    got = np.log(with_mass.frequencies_hz / ms.freqs[0])
    pred = -0.5 * m * ms.phi2[0, :, k]
    big = np.abs(pred) > 1e-4
    assert big.sum() >= 6
    assert np.allclose(got[big], pred[big], rtol=0.05)


def test_a_tap_on_the_centre_lines_loses_modes_and_information(plate):
    _, _, ms, n = plate
    prob = DesignProblem(ms, Measurement(mass_kg=0.002, contact_s=None), fit=(0, 1))
    sensors = [[0, 8, 72]] * 2
    ev = evaluate(prob, sensors, [n + 2, 30])      # the plate's centre, then an off-axis grid point
    seen = ev.seen.sum(axis=1)                     # (draws, layouts)
    assert np.all(seen[:, 0] < seen[:, 1])
    crit = criterion(ev, "D")
    assert crit[0] > crit[1]
    assert np.all(ev.std[:, 0] > ev.std[:, 1])


def test_a_uniform_model_error_biases_every_modulus_by_twice_it(plate):
    """A model error of the same relative size c on every mode is what scaling both moduli by
    (1 + c)^2 does (f ~ sqrt(modulus)): the systematic part the plan adds (the fit's bias
    F^-1 J^T W e) is 2c on E and on G, whatever the layout; the data's part is unchanged."""
    _, _, ms, n = plate
    c = 1e-3
    base = DesignProblem(ms, Measurement(contact_s=None), fit=(0, 1))
    prob = DesignProblem(ms, Measurement(contact_s=None), fit=(0, 1), model_error=np.full(ms.freqs.shape[1], c))
    ev = evaluate(prob, [[0, 8, 72], [3, 40, 77]], [30, 50])
    np.testing.assert_allclose(ev.parts["discretisation (systematic)"], (2 * c) ** 2, rtol=1e-6)
    ev0 = evaluate(DesignProblem(ms, Measurement(contact_s=None), fit=(0, 1),
                                 model_error=np.zeros(ms.freqs.shape[1])), [[0, 8, 72]], [30])
    assert "discretisation (systematic)" not in ev0.parts
    assert np.all(evaluate(base, [[0, 8, 72]], [30]).std <= ev.std[:, :1] + 1e-15)


def test_search_never_ends_worse_than_its_start_and_keeps_its_gaps(plate):
    _, _, ms, n = plate
    prob = DesignProblem(ms, Measurement(mass_kg=0.002, contact_s=None), fit=(0, 1))
    allowed = np.zeros(len(ms.points), bool)
    allowed[:n] = True
    best, ends = optimise(prob, 2, allowed, min_gap=0.05, kind="A", n_random=1)
    assert best.value == min(e.value for e in ends)
    pts = ms.points[best.elements()]
    d = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    assert d[np.triu_indices(3, 1)].min() >= 0.05 - 1e-12
    centre = criterion(evaluate(prob, [list(best.sensors)], [n + 2]), "A")[0]
    assert best.value < centre


def test_clearance_is_the_first_edge_echo_of_an_exact_geometry():
    """Source at the centre of a square plate, sensor d along x: the nearest echo is the
    x = L edge's, path L - d, so the window is (L - 2 d) / c for a direction-free c."""
    f = np.geomspace(1e4, 1e5, 7)
    vel = Velocities(f, np.array([0.0, 90.0]), {"A0": np.full((2, f.size), 1500.0)})
    S, d = 0.4, 0.1
    gap = clearance(vel, (S / 2, S / 2), (S / 2 + d, S / 2), S, S)
    assert np.allclose(gap, (S - 2 * d) / 1500.0)


def test_leg_points_are_a_wavelet_resolution_apart():
    f = np.geomspace(2e4, 2e5, 400)
    vel = Velocities(f, np.array([0.0, 90.0]), {"A0": np.full((2, f.size), 1500.0)})
    wl = Wavelet(2.0, 5.0)
    leg = leg_points(vel, (1.0, 1.0), 0.0, 0.05, 0.25, 2.0, 2.0, wl)   # large plate: echoes far
    r = np.diff(np.log(leg.freqs))
    step = 2 * math.sqrt(2) / (2 * math.pi * 5 * math.sqrt(2))              # spacing / f of cmor2-5
    assert r.min() >= math.log1p(step) - 1e-9
    assert len(leg.freqs) >= 0.8 * math.log(10) / math.log1p(step)
    w = leg_weights(Leg(0.0, 0.05, 0.25, (1e5,), (1500.0,)), 1e-7, 0.0)
    assert w[0] == pytest.approx(1.0 / (2 * (1e-7 * 1500.0 / 0.2) ** 2))


def test_wave_sensitivities_obey_the_scaling_laws():
    """Guided waves of an isotropic plate depend on f h / c only: with every modulus scaled by
    k, cg(f) = sqrt(k) cg0(f / sqrt(k)), so sum_j d ln cg / d ln p_j = (1 - d ln cg / d ln f) / 2,
    and d ln cg / d ln h = d ln cg / d ln f (both 1/4 and 1/2 in the thin-plate flexural limit)."""
    from engine.safe import group_velocity
    lam = Laminate((Ply(AL, 0.0, 0.002),))
    leg = Leg(0.0, 0.05, 0.2, (2e4, 6e4), (0.0, 0.0))
    J, Jh = wave_jacobian(lam, ("E", "G"), {"E": 70e9, "G": AL.G12}, [leg], thickness=True)
    f = np.array(leg.freqs)
    dlnf = (np.log(group_velocity(lam, f * 1.001, "A0")) - np.log(group_velocity(lam, f / 1.001, "A0"))) \
        / (2 * math.log(1.001))
    assert np.all((dlnf > 0.3) & (dlnf < 0.5))
    assert np.allclose(J.sum(axis=1), 0.5 * (1 - dlnf), atol=3e-3)
    assert np.allclose(Jh[:, 0], dlnf, atol=3e-3)
