"""The Identification tab shows the GUM uncertainty budget (pytest-qt, offscreen).

Reference numbers from plate physics, not from the code: for a thin free isotropic
plate f_i = C_i(nu) h sqrt(E/rho) / a^2, so with nu fixed the moduli fitted to measured
frequencies scale as rho h^-2: a 1 % standard uncertainty of the thickness contributes
2 % of E and of G, a 1 % one of the density 1 % (Kirchhoff limit; h/a = 1e-3 here).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402

from labid.inputs.specimen import specimen_from_dict  # noqa: E402
from labid.workflows.identification.synthetic import synthetic_features  # noqa: E402

ART = Path(__file__).resolve().parents[3] / "artifacts"
#: a guard against a hung job, not a speed requirement: the wait ends on the job's signal
BUDGET = 900_000
E, G, H, RHO = 70e9, 26.3e9, 5e-4, 2700.0
PLATE = {"name": "Al 500x350x0.5", "plate": {"length": 0.5, "width": 0.35},
         "materials": {"Al": {"density": RHO, "E": E, "G": G}},
         "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": H},
         "uncertainty": {"thickness": 0.01 * H, "density": 0.01 * RHO, "length": 0.0, "width": 0.0}}


@pytest.fixture
def win(main_window):
    return main_window


def cells(view) -> dict[str, dict[str, str]]:
    """{source row: {constant: text}} of the budget table."""
    t = view.budget_table
    heads = [t.horizontalHeaderItem(j).text() for j in range(t.columnCount())]
    return {t.item(i, 0).text(): {heads[j]: t.item(i, j).text() for j in range(1, t.columnCount())}
            for i in range(t.rowCount())}


def gpa(text: str) -> float:
    v, unit = text.split()
    assert unit == "GPa", text
    return float(v)


def test_identify_in_the_panel_shows_the_gum_budget(win, qtbot, tmp_path):
    spec = specimen_from_dict(PLATE)
    doc = synthetic_features(spec, n_modes=6, waves=())
    doc["specimen"] = PLATE
    p = tmp_path / "features.json"
    p.write_text(json.dumps(doc))
    view = win.identification
    assert view.load_features_file(str(p))
    win.tabs.setCurrentWidget(view)
    assert view.data_choice() == "modal"
    for n, cb in view.param_checks.items():
        cb.setChecked(n in ("E", "G"))
    assert not view.budget_table.isVisible()           # nothing identified yet: no table, a note
    assert "no GUM budget" in view.budget_label.text()
    qtbot.mouseClick(view.run_btn, Qt.LeftButton)
    job = view.job
    assert job is not None
    if not job.has_ended:
        with qtbot.waitSignal(job.ended, timeout=BUDGET):
            pass
    assert view.result is not None and "uncertainty_budget" in view.result, view.result.get("uncertainty_budget_error")
    assert view.budget_table.isVisible() and view.lower_tabs.currentWidget() is view.budget_box
    c = cells(view)
    assert list(c["thickness"]) == ["E", "G"]
    # thickness 1 % -> 2 % of each modulus; density 1 % -> 1 % (the scaling law, to display rounding)
    assert gpa(c["thickness"]["E"]) == pytest.approx(0.02 * E / 1e9, abs=0.051)
    assert gpa(c["thickness"]["G"]) == pytest.approx(0.02 * G / 1e9, abs=0.0051)
    assert gpa(c["density"]["E"]) == pytest.approx(0.01 * E / 1e9, abs=0.0051)
    assert gpa(c["density"]["G"]) == pytest.approx(0.01 * G / 1e9, abs=0.0051)
    # u_c is the quadrature sum of the rows, U = 2 u_c (noise-free data: type A is tiny)
    for n in ("E", "G"):
        parts = [gpa(c[s][n]) for s in c if s not in ("combined u_c", "expanded U (k=2)")]
        uc = gpa(c["combined u_c"][n])
        assert uc == pytest.approx(sum(x * x for x in parts) ** 0.5, rel=0.05)
        assert gpa(c["expanded U (k=2)"][n]) == pytest.approx(2 * uc, rel=0.05)
        assert uc == pytest.approx(5 ** 0.5 * 0.01 * (E if n == "E" else G) / 1e9, rel=0.05)
    ART.mkdir(exist_ok=True)
    assert win.grab().save(str(ART / "identification_budget.png"))


def test_stored_result_shows_its_budget_or_says_it_has_none(win):
    """A stored result (labid identify writes uncertainty_budget into the run) is shown
    as it is; one without (an older result) says so."""
    view = win.identification
    share = 0.8
    res = {"parameters": {"E1": {"value": 136.7e9, "std": 0.1e9}, "nu12": {"value": 0.3, "std": 0.001}},
           "converged": True, "method": "levenberg-marquardt",
           "uncertainty_budget": {"coverage_factor": 2.0, "coverage": "about 95 %", "notes": ["a note"],
                                  "inputs": [{"name": "thickness", "u": 1.6e-5, "unit": "m", "source": "default"}],
                                  "constants": {
                                      "E1": {"value": 136.7e9, "u_combined": 3.0e9, "U": 6.0e9, "U_rel": 0.044,
                                             "u_type_a": 0.1e9, "u_type_b": 2.99e9,
                                             "contributions": {"type A (fit)": {"u": 0.1e9, "share": 0.001},
                                                               "thickness": {"u": 2.7e9, "share": share}}},
                                      "nu12": {"value": 0.3, "u_combined": 0.002, "U": 0.004, "U_rel": 0.013,
                                               "u_type_a": 0.001, "u_type_b": 0.0017,
                                               "contributions": {"type A (fit)": {"u": 0.001, "share": 0.25},
                                                                 "thickness": {"u": 0.0017, "share": 0.72}}}}}}
    view.show_result(res)
    c = cells(view)
    assert c["thickness (default)"] == {"E1": "2.7 GPa", "nu12": "0.0017"}
    assert c["type A (fit)"] == {"E1": "0.10 GPa", "nu12": "0.001"}
    assert c["combined u_c"] == {"E1": "3.0 GPa", "nu12": "0.002"}
    assert c["expanded U (k=2)"] == {"E1": "6.0 GPa", "nu12": "0.004"}
    t = view.budget_table
    assert t.item(1, 1).toolTip() == "80.0 % of u_c²"
    assert "a note" in view.budget_label.text()
    view.show_result({"parameters": {"E1": {"value": 136.7e9, "std": 0.1e9}}, "converged": True})
    assert not view.budget_table.isVisible() and "no GUM budget" in view.budget_label.text()
