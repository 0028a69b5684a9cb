"""`labid identify` command line (CONTRACT section 3) and the multi-start study."""
from __future__ import annotations

import json

import numpy as np
import pytest

from labid.cli.main import main
from labid.workflows.identification import multi_start, random_starts, synthetic_features

AL = {"E": 71.04e9, "G": 25.32e9}


@pytest.fixture(scope="module")
def al_features(tmp_path_factory):
    d = tmp_path_factory.mktemp("al")
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 20),))
    doc["specimen"] = "aluminium"
    p = d / "features.json"
    p.write_text(json.dumps(doc))
    return p


def _run(args, capsys):
    code = main(["identify", *map(str, args)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_identify_waves_only_json_contract(al_features, tmp_path, capsys):
    out = tmp_path / "r.json"
    code, stdout, err = _run([al_features, "--start", "E=80e9,G=30e9", "--json", out], capsys)
    assert code == 0, err
    r = json.loads(out.read_text())
    assert set(r["parameters"]) == {"E", "G"}
    for n in ("E", "G"):
        assert r["parameters"][n]["value"] == pytest.approx(AL[n], rel=1e-3)
        assert r["parameters"][n]["std"] > 0
    assert r["converged"] is True
    assert r["residual"]["modal_rms_rel"] is None
    assert r["residual"]["waves_rms_rel"] < 1e-6
    assert "E" in stdout and "GPa" in stdout


def test_identify_json_to_stdout(al_features, capsys):
    code, stdout, err = _run([al_features, "--json", "-"], capsys)
    assert code == 0, err
    r = json.loads(stdout)
    assert r["converged"] and set(r["residual"]) == {"modal_rms_rel", "waves_rms_rel"}


@pytest.mark.parametrize("args,key", [
    (["--params", "E1,G13"], "--params"),
    (["--start", "E=-5"], "--start"),
    (["--start", "E=200e9,G=25e9"], "--start"),      # nu = E/2G - 1 = 3: unphysical
    (["--start", "E"], "--start"),
    (["--start", "nu=0.3"], "--start"),             # nu is not identified here (E, G are)
])
def test_identify_user_errors_exit_2(al_features, args, key, capsys):
    code, _, err = _run([al_features, *args], capsys)
    assert code == 2
    assert key in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_identify_missing_or_bad_file_exit_2(tmp_path, capsys):
    code, _, err = _run([tmp_path / "nope.json"], capsys)
    assert code == 2 and "nope.json" in err
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"specimen": "aluminium"}))
    code, _, err = _run([bad], capsys)
    assert code == 2 and "nothing to identify" in err


def test_multi_start_study_cli_with_plot(al_features, tmp_path, capsys):
    out, png = tmp_path / "r.json", tmp_path / "ms.png"
    code, _, err = _run([al_features, "--starts", "6", "--workers", "2", "--plot", png, "--json", out], capsys)
    assert code == 0, err
    ms = json.loads(out.read_text())["multi_start"]
    assert len(ms) == 6
    # starts within +-50 % of nominal; a start may end in a local minimum on the
    # nu < 1/2 bound (G > E/3): its chi^2 per point then shows the poor fit
    good = [r for r in ms if r["converged"] and r["chi2_per_point"] < 1.0]
    assert len(good) >= 4
    for r in ms:
        at_truth = all(abs(r["values"][n] / AL[n] - 1) < 1e-3 for n in ("E", "G"))
        assert at_truth == (r in good)
    assert len({r["start"]["E"] for r in ms}) == 6
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_multi_start_table2_box_through_thread_executor():
    """Any concurrent.futures executor works (here threads): random starts in the
    paper's Table 2 box all converge to E and G within 0.1 %."""
    from concurrent.futures import ThreadPoolExecutor

    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 20),))
    doc["specimen"] = "aluminium"
    starts = random_starts(AL, ("E", "G"), 8, spread={"E": (55e9, 120e9), "G": (25e9, 55e9)}, seed=3)
    # unphysical boxes corners (G < E/3 means nu > 0.5) are skipped, as in the paper's table
    starts = [s for s in starts if s["G"] > s["E"] / 3]
    with ThreadPoolExecutor(2) as ex:
        res = multi_start(doc, starts, ("E", "G"), executor=ex)
    assert len(res) == len(starts) >= 4
    for r in res:
        assert r["converged"]
        assert np.allclose([r["values"]["E"], r["values"]["G"]], [AL["E"], AL["G"]], rtol=1e-3)


def test_identify_mcmc_posterior_in_json(al_features, tmp_path, capsys):
    """--mcmc adds the posterior (calibration of the sampler: test_identify_mcmc.py)."""
    out = tmp_path / "r.json"
    code, _, err = _run([al_features, "--mcmc", "30", "--json", out], capsys)
    assert code == 0, err
    r = json.loads(out.read_text())
    post = r["posterior"]
    assert post["names"] == ["E", "G"] and post["n_samples"] == 16 * 20
    for n in ("E", "G"):   # noise-free data: samples around the truth
        assert abs(post["mean"][n] - AL[n]) < 3 * r["parameters"][n]["std"]
    code, _, err = _run([al_features, "--mcmc", "3"], capsys)
    assert code == 2 and "--mcmc" in err


def test_one_flow_identifies_the_data_set_selected():
    from labid import services

    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 10),))
    doc["specimen"] = "aluminium"
    res = services.run_identification(services.select_data(doc, "waves"), start={"E": 80e9, "G": 30e9})
    assert res.data == ("waves",) and res.data_set == "waves" and res.specimen
    assert res.parameters["E"]["value"] == pytest.approx(AL["E"], rel=1e-3)
    assert services.Identification.from_dict(res.to_dict()) == res      # one shape, stored and read


def test_null_velocities_and_missing_sigmas(tmp_path, capsys):
    """A velocity the CWT could not measure is null (CONTRACT 2): the point is dropped;
    absent sigmas get the documented default (1 % of the value) and a note."""
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 12),))
    doc["specimen"] = "aluminium"
    w = doc["waves"][0]
    w["group_velocity_m_s"][0] = None
    del w["sigma_m_s"]
    p = tmp_path / "f.json"
    p.write_text(json.dumps(doc))
    out = tmp_path / "r.json"
    code, stdout, err = _run([p, "--start", "E=80e9,G=30e9", "--json", out], capsys)
    assert code == 0, err
    r = json.loads(out.read_text())
    assert r["parameters"]["E"]["value"] == pytest.approx(AL["E"], rel=1e-3)
    assert len(r["blocks"]["waves[0]:A0@0deg"]["observed"]) == 11
    assert any("sigma_m_s absent" in m for m in r["warnings"])
    assert any("dropped" in m for m in r["warnings"])


def test_birge_ratio_widens_understated_sigmas():
    """Noise 2.5x the stated sigmas: the chi^2 per point (~6) scales the sigmas by its
    square root and the std widens by that factor; the estimate barely moves."""
    from labid.workflows.identification import problem_from_features, run

    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 40),))
    doc["specimen"] = "aluminium"
    w = doc["waves"][0]
    rng = np.random.default_rng(4)
    cg = np.array(w["group_velocity_m_s"])
    w["group_velocity_m_s"] = (cg * (1 + 0.025 * rng.standard_normal(cg.size))).tolist()
    prob = problem_from_features(doc)
    plain = run(prob, ("E", "G"), {"E": 80e9, "G": 30e9}, scale_sigmas=False)
    chi2_n = plain.residuals["waves[0]:A0@0deg"]["chi2"] / 40
    assert 3.0 < chi2_n < 10.0
    scaled = run(prob, ("E", "G"), {"E": 80e9, "G": 30e9})
    assert scaled.sigma_scale["waves"] == pytest.approx(np.sqrt(chi2_n), rel=1e-6)
    # issue 12: the std grows as sqrt(chi^2/nu), nu = 40 points - 2 parameters
    np.testing.assert_allclose(scaled.std / plain.std, np.sqrt(chi2_n * 40 / 38), rtol=0.02)
    assert scaled.fit["std_scale"] == pytest.approx(np.sqrt(chi2_n * 40 / 38), rel=0.02)
    # the same minimum: each fit stops within 0.01 of its own std of it (engine.fit.STOP_CHI2)
    assert np.all(np.abs(scaled.values - plain.values) <= 0.01 * (plain.std + scaled.std))
    assert any("Birge" in m for m in scaled.warnings)


def test_consistency_check_flags_disagreeing_data_sets():
    """Two data sets that each see E and G; the second is biased by 5 sigma per point:
    the chi^2 test on (combined - separate minima) warns and names the parameters.
    Without the bias: no warning. Forward models linear in log p (exact)."""
    from engine.fit import DataBlock
    from labid.workflows.identification import Problem, run
    from labid.inputs.specimen import load_specimen

    spec = load_specimen("aluminium")
    lt = np.log([AL["E"], AL["G"]])
    A1 = np.array([[1.0, 0.2], [0.8, 0.5], [0.3, 1.0], [1.0, 1.0]])
    A2 = np.array([[0.5, -0.3], [1.0, -0.8], [0.2, 0.9]])

    def block(A, name, kind, bias):
        def predict(p):
            return 100.0 + A @ (np.log([p["E"], p["G"]]) - lt)
        return DataBlock(name, predict(AL) + bias, 0.001, predict, None, kind)

    for bias, expect in ((0.0, False), (0.005, True)):
        prob = Problem(spec, [block(A1, "m", "modal", 0.0), block(A2, "w", "waves", bias)], "Al")
        est = run(prob, ("E", "G"), {"E": 70e9, "G": 26e9}, scale_sigmas=False)
        flagged = [m for m in est.warnings if "data sets disagree" in m]
        assert bool(flagged) == expect, est.warnings
    assert "E (" in flagged[0] or "G (" in flagged[0]


def test_multi_start_equals_single_runs_on_combined_data():
    """A multi-start study skips the consistency check (warnings only): every
    start gives the same estimate as a plain run, and the truth."""
    from labid.workflows.identification import problem_from_features, run
    doc = synthetic_features("aluminium", n_modes=6, waves=(("A0", 0.0, 50e3, 6),))
    doc["specimen"] = "aluminium"
    starts = [{"E": 80e9, "G": 30e9}]
    res = multi_start(doc, starts, ("E", "G"), max_workers=1)
    prob = problem_from_features(doc)
    assert set(prob.kinds) == {"modal", "waves"}
    for st, r in zip(starts, res):
        est = run(prob, ("E", "G"), st)
        assert r["converged"] and est.converged
        for n in ("E", "G"):
            # 1e-9: the plate's warm eigen-solve starts from the model's last solve (agrees
            # with a cold one to 1e-10, not bit for bit; engine.plate.warm)
            assert r["values"][n] == pytest.approx(est.params[n], rel=1e-9)
            # modal data from the reference mesh (not the model's): the corrected model's
            # remaining discretisation error (~1e-6 here) moves the estimate by as much
            assert r["values"][n] == pytest.approx(AL[n], rel=1e-4)
