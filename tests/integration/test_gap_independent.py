"""The gap diagnosis on data its own models did not make (issue 28): the independent
generator (bench/blind_independent.py: Rayleigh-Ritz plate, SAFE at a higher order)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.blind_independent import draw
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
