"""The gap diagnosis on data its own models did not make (issue 28): the independent
generator (bench/blind_independent.py: Rayleigh-Ritz plate; group velocities from the
independent Legendre SAFE, bench/independent/legendre_safe.py)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.blind_independent import SPECIMENS, draw, legendre_group_velocity, legendre_plies
from bench.gap_effect_models import shifts
from labid.base import progress
from labid.workflows.diagnosis import run_diagnosis


@pytest.fixture(autouse=True)
def _quiet():
    progress.set_quiet(True)
    yield
    progress.set_quiet(False)


def test_one_wave_point_with_four_constants_is_insufficient_data_not_none():
    case = draw(11, "clean", specimen="cfrp", data="waves", noise=0.002, wave_sets=(("A0", 0.0, 1),))
    res = run_diagnosis(case.features, names=("E1", "nu12", "G13", "G23"), prior=0.3)
    assert res["verdict"] == "insufficient_data"
    assert res["gap"]["n"] == 1 and not any(e["refitted"] for e in res["effects"])
    assert "1 independent feature(s) for 4 fitted constant(s)" in res["advice"][0]
    assert any("S0" in a for a in res["advice"]) and any("a modal test" in a for a in res["advice"])


@pytest.mark.slow
def test_clean_39_mode_wood_plate_is_no_false_alarm_once_corrections_pair_by_frequency():
    """Ritz data, 39 modes, 0.13 % noise: identify's nominal discretisation corrections applied
    by mode order pair two close pairs crosswise (chi^2 152 for 36 dof before); solved at the
    estimate (by identify itself since issue 24's re-correction, else by the diagnosis, which
    then pairs the peaks by the corrected frequencies) the gap test is passed."""
    case = draw(6, "clean")
    assert (case.specimen, case.n_modes) == ("wood", 39)
    res = run_diagnosis(case.features, names=case.params, prior=case.prior)
    assert res["verdict"] == "none", res["gap"]
    notes = list(res["diagnosis_notes"]) + list(res.get("notes") or [])
    assert any("corrected (again, at the estimate)" in n or "paired by the corrected frequencies" in n
               for n in notes), notes


@pytest.mark.slow
def test_hidden_accelerometer_mass_is_found_from_ritz_frequencies():
    case = dataclasses.replace(draw(7, "sensor_mass", specimen="aluminium", n_modes=10, noise=0.002,
                                    magnitude=0.004))
    res = run_diagnosis(case.features, names=case.params, prior=case.prior)
    assert res["verdict"] == "sensor_mass"
    e = res["effects"][0]
    assert e["magnitude"] == pytest.approx(0.004, rel=0.3) and e["constants_std"]["E"] > 0


def test_density_gradient_model_shifts_the_modes_as_the_independent_density_field():
    """The diagnoser's gradient (point masses with rotary inertia at Gauss points) against the
    Ritz plate's density field by quadrature: the former 24 x 12 lumps were 0.4-1 per mille
    off, more than the shift itself on some modes."""
    ritz, engine = shifts("aluminium", "density_gradient", 0.10, n=8, order=8, elements=8)
    assert np.abs(ritz).max() > 2e-3                      # the effect is there
    assert np.abs(engine - ritz).max() < 5e-5


def test_generator_wave_velocities_are_the_exact_rayleigh_lamb_ones():
    """The generator's A0/S0 (labels by root order, isotropic E, G table read as the bench reads
    it) against the exact Rayleigh-Lamb group velocities of ORACLES.md (aluminium E = 70 GPa,
    nu = 0.33, 2700 kg/m^3, h = 1 mm; f h = 0.1, 0.5, 1.0 MHz mm): within 1e-6."""
    E, nu = 70e9, 0.33
    table = {"plate": {"length": 0.3, "width": 0.2},
             "materials": {"Al": {"density": 2700.0, "E": E, "G": E / (2 * (1 + nu))}},
             "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": 1e-3}}
    plies = legendre_plies(table, {})
    f = np.array([0.1e6, 0.5e6, 1.0e6])
    assert legendre_group_velocity(plies, "A0", 0.0, f, 8) == pytest.approx([1783.696, 2908.787, 3137.051], rel=1e-6)
    assert legendre_group_velocity(plies, "S0", 30.0, f, 8) == pytest.approx([5391.689, 5335.510, 5118.634], rel=1e-6)


def test_generator_labels_the_cfrp_laminate_modes_by_their_thin_plate_limits():
    """The 12-ply CFRP of the bench at 500 Hz: S0 tends to the classical-lamination plate
    velocity sqrt(A_ii / rho h) (within 1e-5 along 0 and 90 deg), A0 to the Kirchhoff flexural
    group velocity 2 (D_ii / rho h)^(1/4) sqrt(w) (within 1 %: the 3D shear and rotary inertia
    corrections, which grow with f). A, D from the plane-stress ply stiffness, computed here."""
    table = SPECIMENS["cfrp"][0]()
    plies = legendre_plies(table, {})
    A, D, rho_h, z = np.zeros((3, 3)), np.zeros((3, 3)), 0.0, -sum(t for _, _, t in plies) / 2
    for c, ang, t in plies:
        n21 = c["nu12"] * c["E2"] / c["E1"]
        d = 1 - c["nu12"] * n21
        Q = np.array([[c["E1"] / d, c["nu12"] * c["E2"] / d, 0], [c["nu12"] * c["E2"] / d, c["E2"] / d, 0],
                      [0, 0, c["G12"]]])
        m, n = np.cos(np.radians(ang)), np.sin(np.radians(ang))
        T = np.array([[m * m, n * n, 2 * m * n], [n * n, m * m, -2 * m * n], [-m * n, m * n, m * m - n * n]])
        R = np.diag([1.0, 1.0, 2.0])
        Qb = np.linalg.inv(T) @ Q @ R @ T @ np.linalg.inv(R)
        A += Qb * t
        D += Qb * ((z + t) ** 3 - z ** 3) / 3
        rho_h += c["density"] * t
        z += t
    f, w = 500.0, 2 * np.pi * 500.0
    for i, direction in ((0, 0.0), (1, 90.0)):
        s0 = legendre_group_velocity(plies, "S0", direction, [f], 3)[0]
        a0 = legendre_group_velocity(plies, "A0", direction, [f], 3)[0]
        assert s0 == pytest.approx(np.sqrt(A[i, i] / rho_h), rel=1e-5)
        assert a0 == pytest.approx(2 * (D[i, i] / rho_h) ** 0.25 * np.sqrt(w), rel=1e-2)
        assert a0 < 0.1 * s0


def test_generator_records_which_wave_model_made_a_case():
    case = draw(11, "clean", specimen="aluminium", data="waves", noise=0.002, wave_sets=(("S0", 0.0, 2),))
    assert case.detail["wave_generator"] == "legendre"
    assert draw(11, "clean", specimen="aluminium", data="modal", n_modes=10).detail["wave_generator"] is None


@pytest.mark.slow
def test_one_ply_plate_turned_is_named_misalignment_not_a_top_ply_error():
    """Wood-like one-ply Ritz plate, material axes turned 3.44 deg, 20 modes at 0.2 %: with one
    ply the top ply turned is the whole layup turned; the diagnosis named it ply_angle_error and
    screened the misalignment out (session 24 bench, seed 9). Now: misalignment, within 30 %."""
    case = draw(9, "misalignment")
    assert (case.specimen, case.n_modes) == ("wood", 20)
    res = run_diagnosis(case.features, names=case.params, prior=case.prior)
    assert res["verdict"] == "misalignment", [(e["name"], e["delta_chi2"]) for e in res["effects"][:3]]
    assert "ply_angle_error" not in [e["name"] for e in res["effects"]]
    assert res["effects"][0]["magnitude"] == pytest.approx(case.magnitude, rel=0.3)


def _refitted(name: str, chi2: float):
    from engine.gap.candidates import Candidate
    from engine.gap.refit import Refit
    return Candidate(name, refit=Refit(iterations=3, converged=True, magnitude=1.0, std=0.1, chi2=chi2,
                                       residual=np.zeros(30), constants={}, held_out_after=1.0))


def test_an_effect_that_closes_less_than_its_own_1_percent_test_is_not_named():
    """Session 24 bench, thickness bump seed 8 (CFRP, 30 modes, out of the library, oracle
    chi^2 16.8): chi^2 47.35 over the 1 % threshold 46.96 (27 dof); a uniform thickness error
    closed 5.13 of it and was named (with four others within 4). A drop below chi^2_1's 1 %
    quantile 6.63 is not evidence for the effect: `unattributed`. A drop of 10 still names it."""
    from scipy import stats

    from engine.gap.verdict import decide
    test = {"chi2": 47.35, "dof": 27.0, "threshold": float(stats.chi2.isf(0.01, 27.0)), "alpha": 0.01,
            "significant": True}
    assert decide([_refitted("thickness", 47.35 - 5.13)], test, 30, 0.001)[0] == "unattributed"
    assert decide([_refitted("thickness", 47.35 - 10.0)], test, 30, 0.001)[0] == "thickness"
    loose = dict(test, threshold=float(stats.chi2.isf(0.05, 27.0)), alpha=0.05)  # at 5 %: chi^2_1 quantile 3.84
    assert decide([_refitted("thickness", 47.35 - 5.13)], loose, 30, 0.001)[0] == "thickness"


@pytest.mark.slow
def test_a_thickness_bump_just_over_the_threshold_is_not_named_a_library_effect():
    """The bench case itself (Ritz plate with a 14.6 % local thickness bump, out of the library)."""
    case = draw(8, "thickness_bump")
    assert (case.specimen, case.n_modes) == ("cfrp", 30)
    res = run_diagnosis(case.features, names=case.params, prior=case.prior)
    assert res["verdict"] in ("none", "unattributed"), (res["verdict"], res["gap"])
