"""Gap diagnosis: chi^2 calibration, one case per verdict type, the command line.

Fast cases use a coarse plate mesh (4 x 4 elements) for both the blind
generator and the diagnoser, and modal data (plus one small wave set where a
wave effect is tested); the truths come from the generator's seed.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from engine.gap import GapFit, GapForward, GapOptions, diagnose, gap_test, own_estimate
from engine.gap.start import identify_pairing
from engine.forward import ALPHA_FIBRE, ALPHA_MATRIX, EFFECTS
from labid.cli.main import main
from labid.workflows.diagnosis import gap_features
from bench.blind import draw_case

MESH = (4, 4)


def _diagnose(case, **opts):
    """Diagnosis on the coarse mesh from identify's estimator with a 30 % prior
    (as ``labid identify --prior 0.3``: six constants from ten modes need it)."""
    problem = gap_features(case.features)
    fw = GapForward(problem, mesh=MESH, pairing=identify_pairing(problem.modal))
    options = GapOptions(**opts)
    start = own_estimate(GapFit(problem, fw, options.model_rel_sigma), prior_rel_std=0.3)
    return diagnose(problem, options, forward=fw, start=start).to_dict()


# -- chi^2 test calibration (linear Gaussian model, exact law) ------------------
@pytest.mark.parametrize("prior", [0.0, 0.5])
def test_chi2_false_alarm_rate_matches_alpha_on_clean_noise(prior):
    """Residuals of a least-squares fit to pure noise: the rate of declared gaps is alpha."""
    rng = np.random.default_rng(7)
    n, k, alpha, trials = 40, 6, 0.05, 4000
    J = rng.standard_normal((n, k)) * np.array([30.0, 10.0, 3.0, 1.0, 0.3, 0.1])
    w = np.full(k, prior)
    A = J.T @ J + np.diag(w ** 2)
    hits = 0
    for _ in range(trials):
        e = rng.standard_normal(n)             # clean data: noise only, true params = prior mean
        d = np.linalg.solve(A, J.T @ e)        # fitted parameter offset
        r = J @ d - e                          # whitened residual model - data
        hits += gap_test(r, J, w, alpha)["significant"]
    sd = np.sqrt(alpha * (1 - alpha) / trials)
    assert abs(hits / trials - alpha) < 4 * sd + (0.01 if prior else 0.0)


def test_chi2_test_dof_is_n_minus_k_without_prior():
    J = np.random.default_rng(1).standard_normal((25, 4))
    t = gap_test(np.ones(25), J, np.zeros(4), 0.01)
    assert t["dof"] == pytest.approx(21.0)
    assert t["threshold"] == pytest.approx(stats.chi2.isf(0.01, 21))


# -- verdicts -------------------------------------------------------------------
def test_clean_features_give_none():
    res = _diagnose(draw_case(11, "clean", wave_sets=(), mesh=MESH))
    assert res["verdict"] == "none"
    assert not res["gap"]["significant"]
    assert res["where"] == []


def test_accelerometer_mass_is_found_with_its_magnitude():
    case = draw_case(12, "sensor_mass", wave_sets=(), mesh=MESH)
    res = _diagnose(case)
    assert res["verdict"] == "sensor_mass"
    top = res["effects"][0]
    assert top["name"] == "sensor_mass" and top["unit"] == "kg"
    assert top["magnitude"] == pytest.approx(case.magnitude, rel=0.1)
    assert abs(top["magnitude"] - case.magnitude) < 4 * top["std"]
    g = res["gap"]
    assert g["before"] > 3.0 and g["after"] < 1.5 and g["held_out_after"] < g["held_out_before"]
    assert "modal" in res["where"]


def test_temperature_is_absorbed_with_the_bias_of_the_thermal_coefficients():
    """A uniform temperature change only rescales the moduli: the constants absorb it
    (verdict none), and the reported bias per kelvin is the physical coefficient."""
    res = _diagnose(draw_case(13, "temperature", wave_sets=(), mesh=MESH))
    assert res["verdict"] == "none"
    und = {u["name"]: u for u in res["undetectable"]}
    assert "temperature" in und
    bias = und["temperature"]["bias_in_constants_per_unit"]
    assert bias["E2"] == pytest.approx(ALPHA_MATRIX, rel=0.05)
    assert bias["G12"] == pytest.approx(ALPHA_MATRIX, rel=0.05)
    assert bias["E1"] == pytest.approx(ALPHA_FIBRE, rel=0.2)


def test_local_stiffness_loss_is_unattributed():
    case = draw_case(14, "soft_patch", wave_sets=(), mesh=MESH)
    assert case.magnitude >= 0.3
    res = _diagnose(case)
    assert res["gap"]["significant"]
    assert res["verdict"] == "unattributed"


@pytest.mark.slow
def test_timing_offset_is_found_from_group_velocities():
    case = draw_case(15, "timing_offset", wave_sets=(("A0", 0.0, 6), ("S0", 0.0, 5)), mesh=MESH)
    res = _diagnose(case, max_refits=2)
    assert res["verdict"] == "timing_offset"
    e = res["effects"][0]
    assert e["unit"] == "s" and e["magnitude"] == pytest.approx(case.magnitude, rel=0.15)


def test_the_simulated_rig_injects_the_effects_the_diagnoser_knows():
    """One effect registry (engine.forward.effects): the rig's effects are its names, except
    the real-plate effects (PLATE_EFFECTS), which the blind bench injects through
    engine.gap.GapForward (the rig does not yet)."""
    from mock_hw.rig import Effects
    from engine.forward.effects import PLATE_EFFECTS
    assert Effects.names() == tuple(k for k in EFFECTS if k not in PLATE_EFFECTS)
    assert Effects.parse("sensor_mass=0.003").active() == {"sensor_mass": 0.003}


# -- command line ------------------------------------------------------------------
@pytest.mark.slow
def test_cli_writes_contract_keys_and_plot(tmp_path):
    case = draw_case(16, "support_stiffness", wave_sets=())
    f = tmp_path / "features.json"
    f.write_text(json.dumps(case.features))
    out, png = tmp_path / "diag.json", tmp_path / "gap.png"
    # six constants from ten modes: identify needs a prior (labid identify --prior 0.3)
    assert main(["diagnose", str(f), "--json", str(out), "--plot", str(png), "--prior", "0.3"]) == 0
    res = json.loads(out.read_text())
    assert set(res) >= {"gap", "where", "effects", "verdict"}
    assert set(res["gap"]) >= {"before", "after"}
    assert set(res["effects"][0]) >= {"name", "magnitude", "unit", "gap_after", "score"}
    assert res["verdict"] == "support_stiffness"
    assert png.stat().st_size > 10_000


def test_cli_bad_features_exit_2_with_one_line(tmp_path, capsys):
    f = tmp_path / "bad.json"
    f.write_text(json.dumps({"specimen": "cfrp", "modal": {"frequencies_hz": [50.0, 60.0],
                                                          "sigma_hz": [0.1]}}))
    assert main(["diagnose", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "modal.sigma_hz" in err[0]
    assert main(["diagnose", str(tmp_path / "missing.json")]) == 2


# -- the aperture (spectral-centroid) model against CWT picks ---------------------
def test_aperture_delay_model_matches_morlet_ridge_of_a_dispersive_packet():
    """A strain sensor of length L filters by sinc(kL/2) (zero phase): the Morlet
    (B=2, C=5) ridge picked by engine.waves moves by tau_g' sigma_f^2 d ln|H|/df,
    the model of engine.forward.model. Packet: exact thin-plate flexural dispersion."""
    from engine import waves
    from engine.forward import log_sinc_slope
    fs, n, d = 5e6, 2 ** 15, 0.25
    f = np.fft.rfftfreq(n, 1 / fs)
    beta = 1000.0 ** 2 / (2 * np.pi * 1e5)        # c_p = sqrt(beta w): 1000 m/s at 100 kHz
    w = 2 * np.pi * f
    k = np.sqrt(w / beta)
    amp = np.exp(-((f - 100e3) / 90e3) ** 2)
    wl = waves.Wavelet(2.0, 5.0)
    f0 = np.array([50e3, 70e3, 90e3, 110e3])

    def picks(L):
        x = np.fft.irfft(amp * np.sinc(k * L / 2 / np.pi) * np.exp(-1j * (k * d + w * 2e-4)), n)
        W = waves.cwt(x, fs, f0, wl, precision="double")
        return waves.arrival_times(W, fs, f0, wl).times_s

    base = picks(0.0)
    cg = 2 * np.sqrt(beta * 2 * np.pi * f0)
    dtau_df = d / (4 * np.sqrt(beta * 2 * np.pi) * f0 ** 1.5) * -1.0   # d(d/cg)/df
    sig_f = f0 / (np.pi * wl.center * np.sqrt(2 * wl.bandwidth))
    for L in (0.004, 0.008):
        kk = np.sqrt(2 * np.pi * f0 / beta)
        slope = log_sinc_slope(kk * L / 2) * (L / 2) * (2 * np.pi / cg)
        model = dtau_df * sig_f ** 2 * slope
        assert np.all(model > 0)
        np.testing.assert_allclose(picks(L) - base, model, rtol=0.03)
