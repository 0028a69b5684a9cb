"""GUM uncertainty budget (issue 16): sensitivities against exact scaling laws of plate physics.

Exact references (not from the code):
* free isotropic plate, thin (Kirchhoff limit): f_i = C_i(nu) h sqrt(E/rho) / a^2, so with
  nu held, E and G scale as rho h^-2 a^4: dE/dh = -2 E/h, dE/drho = E/rho, and stretching
  the plate (L dE/dL + W dE/dW) = 4 E. With the plate weighed (rho = m / (L W h)):
  dE/dh = -3 E/h, L dE/dL + W dE/dW = 2 E, dE/dm = E/m. The density scaling is exact in
  Mindlin theory too; the h and a laws hold to O((h/a)^2), here < 1e-4.
* guided waves: the dispersion relation depends on f h / c only, so
  c(f; s^2 E, s^2 G, s h) = s c(f; E, G, h): scaling every measured velocity (the path
  length d) and the thickness together scales the moduli by s^2:
  d dE/dd + h dE/dh = 2 E.
"""
from __future__ import annotations

import numpy as np
import pytest

from engine.fit import DataBlock, estimate
from engine.fit.budget import BudgetInput, gum_budget, sensitivity_coefficients
from labid.base.summary import budget_text
from labid.workflows.budget import budget_of_problem, uncertainty_table
from labid.base.errors import UserError
from labid.workflows.identification.estimation import problem_from_features, run
from labid.inputs.specimen import specimen_from_dict
from labid.workflows.identification.synthetic import synthetic_features

PLATE = {"name": "Al 500x350x0.5", "plate": {"length": 0.5, "width": 0.35},
         "materials": {"Al": {"density": 2700.0, "E": 70e9, "G": 26.3e9}},
         "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": 5e-4}}


def _modal_case(unc: dict | None):
    sdoc = dict(PLATE, **({"uncertainty": unc} if unc is not None else {}))
    spec = specimen_from_dict(sdoc)
    doc = synthetic_features(spec, n_modes=8, waves=())
    doc["specimen"] = sdoc
    prob = problem_from_features(doc)
    est = run(prob, ("E", "G"))
    return prob, est, doc


def _table(b):
    return {n: {k: v["sensitivity"] for k, v in c["contributions"].items()} for n, c in b["constants"].items()}


def test_thin_plate_density_held_exact_scaling():
    prob, est, doc = _modal_case({"thickness": 5e-6, "density": 27.0})
    b = budget_of_problem(prob, est, doc)
    S = _table(b)
    h, L, W, rho = 5e-4, 0.5, 0.35, 2700.0
    for n, v in (("E", 70e9), ("G", 26.3e9)):
        assert S[n]["thickness"] * h / v == pytest.approx(-2.0, rel=1e-3)
        assert S[n]["density"] * rho / v == pytest.approx(1.0, rel=1e-3)
        assert (S[n]["length"] * L + S[n]["width"] * W) / v == pytest.approx(4.0, rel=1e-3)
    # u_c is the quadrature sum; U = 2 u_c; the 1 % thickness input gives 2 % on E
    cE = b["constants"]["E"]
    assert cE["contributions"]["thickness"]["u"] / 70e9 == pytest.approx(0.02, rel=1e-3)
    parts = [v["u"] for v in cE["contributions"].values()]
    assert cE["u_combined"] == pytest.approx(np.sqrt(np.sum(np.square(parts))), rel=1e-12)
    assert cE["U"] == pytest.approx(2.0 * cE["u_combined"])
    assert b["coverage_factor"] == 2.0 and "95 %" in b["coverage"]
    assert "thickness" in budget_text(b)


def test_thin_plate_weighed_exact_scaling():
    prob, est, doc = _modal_case({"mass": 0.01})
    b = budget_of_problem(prob, est, doc)
    S = _table(b)
    h, L, W = 5e-4, 0.5, 0.35
    m = L * W * h * 2700.0
    for n, v in (("E", 70e9), ("G", 26.3e9)):
        assert S[n]["thickness"] * h / v == pytest.approx(-3.0, rel=1e-3)
        assert S[n]["mass"] * m / v == pytest.approx(1.0, rel=1e-3)
        assert (S[n]["length"] * L + S[n]["width"] * W) / v == pytest.approx(2.0, rel=1e-3)
    assert "density" not in S["E"]


def test_defaults_are_stated_values():
    spec = specimen_from_dict(PLATE)
    t = uncertainty_table(spec)
    assert t["thickness"] == (pytest.approx(0.01 * 5e-4), "default")
    assert t["density"] == (pytest.approx(27.0), "default")
    assert t["length"] == (5e-4, "default")


@pytest.mark.parametrize("tab", [{"thickness": -1.0}, {"thick": 1e-5}, {"mass": 0.1, "density": 3.0},
                                 {"length": "1 mm"}])
def test_bad_uncertainty_table_is_a_user_error(tab):
    # caught where the specimen is read, before any fit
    with pytest.raises(UserError, match="uncertainty"):
        uncertainty_table(specimen_from_dict(dict(PLATE, uncertainty=tab)))


def test_waves_path_and_thickness_exact_scaling():
    sdoc = dict(PLATE, uncertainty={"path_length": 1e-3, "sensor_position": 0.0, "source_position": 0.0})
    spec = specimen_from_dict(sdoc)
    doc = synthetic_features(spec, n_modes=0, waves=(("A0", 0.0, 150e3, 8), ("S0", 0.0, 150e3, 8)))
    doc["specimen"] = sdoc
    doc["rig"] = {"wave_path_m": 0.2}
    prob = problem_from_features(doc)
    est = run(prob, ("E", "G"))
    b = budget_of_problem(prob, est, doc)
    S = _table(b)
    for n, v in (("E", 70e9), ("G", 26.3e9)):
        assert (S[n]["path_length"] * 0.2 + S[n]["thickness"] * 5e-4) / v == pytest.approx(2.0, rel=1e-3)
    assert "sensor_position" not in S["E"]      # zero uncertainty: left out


def test_linear_model_sensitivity_is_minus_pseudo_inverse():
    """y = a + b t fitted by least squares; an input shifting the observations by x t^2
    moves (a, b) by -J^+ t^2 x, J = [1, t]: compared with numpy's polyfit of the shifted data."""
    t = np.linspace(0.0, 1.0, 7)
    J = np.column_stack([np.ones_like(t), t])
    S = sensitivity_coefficients(J, (-(t ** 2))[:, None])     # model - observed changes by -t^2
    b_fit, a_fit = np.polyfit(t, t ** 2, 1)
    assert S[:, 0] == pytest.approx([a_fit, b_fit], rel=1e-12)

    blk = DataBlock("line", 1.0 + 2.0 * t, 0.1, lambda p: p["a"] + p["b"] * t, kind="data")
    est = estimate([blk], ("a", "b"), {"a": 0.5, "b": 1.0})
    bud = gum_budget([blk], est, [BudgetInput("bow", 0.0, 0.3, "1", -(t ** 2))])
    assert bud.sensitivity[:, 0] == pytest.approx([a_fit, b_fit], rel=1e-6)
    assert bud.u_combined == pytest.approx(np.sqrt(est.std ** 2 + (0.3 * np.abs(bud.sensitivity[:, 0])) ** 2))


def _toml(unc: str) -> str:
    return ('name = "Al plate"\n[plate]\nlength = 0.5\nwidth = 0.35\n[materials.Al]\ndensity = 2700.0\n'
            'E = 70e9\nG = 26.3e9\n[layup]\nmaterial = "Al"\nangles_deg = [0]\nply_thickness = 5e-4\n' + unc)


def test_identify_cli_writes_and_prints_the_budget(tmp_path, capsys):
    import json

    from labid.cli.main import main
    (tmp_path / "plate.toml").write_text(_toml("[uncertainty]\nthickness = 5e-6\npath_length = 2e-3\n"))
    spec = specimen_from_dict(PLATE)
    doc = synthetic_features(spec, n_modes=0, waves=(("A0", 0.0, 100e3, 10),))
    doc["specimen"] = "plate.toml"
    doc["rig"] = {"wave_path_m": 0.2}
    (tmp_path / "f.json").write_text(json.dumps(doc))
    code = main(["identify", str(tmp_path / "f.json"), "--params", "E", "--json", str(tmp_path / "r.json")])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    b = json.loads((tmp_path / "r.json").read_text())["uncertainty_budget"]
    src = {x["name"]: x["source"] for x in b["inputs"]}
    assert src["thickness"] == "specimen" and src["sensor_position"] == "default"
    cE = b["constants"]["E"]
    assert cE["contributions"]["path_length"]["u"] == pytest.approx(
        abs(cE["contributions"]["path_length"]["sensitivity"]) * 2e-3)
    assert cE["U"] == pytest.approx(2 * cE["u_combined"])
    assert "uncertainty budget" in cap.out and "path_length" in cap.out

    (tmp_path / "plate.toml").write_text(_toml("[uncertainty]\nthickness = -1.0\n"))
    code = main(["identify", str(tmp_path / "f.json"), "--params", "E"])
    err = capsys.readouterr().err
    assert code == 2 and "uncertainty.thickness" in err and "Traceback" not in err
