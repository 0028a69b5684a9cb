"""`labid demo`: the whole job on the simulated rig, checked against the specimen's truth
(one demo run per test session: the ``demo_output`` fixture of tests/conftest.py)."""
import pytest

from labid.inputs.specimen import load_specimen


@pytest.mark.slow
def test_demo_end_to_end(demo_output):
    out, res = demo_output
    truth = load_specimen("cfrp").laminate.plies[0].material.params()
    assert set(res["identified"]) == {"modal", "waves", "combined"}
    assert all(res["converged"].values())
    modal, comb = res["identified"]["modal"], res["identified"]["combined"]
    # issue 12: the fit starts from datasheet values (17-22 % below the truth), on peaks
    # from the rig's reference mesh: the stiff constants from modal data alone within
    # 2 std (their std includes nu12 and G23, held under a weak prior when modal data
    # cannot constrain them), E1 within 1 %
    assert res["start"]["E1"] == 110e9
    assert modal["E1"]["value"] == pytest.approx(truth["E1"], rel=0.01)
    for n in ("E1", "E2", "G12"):
        assert abs(modal[n]["value"] - truth[n]) <= 2 * modal[n]["std"], (n, modal[n], truth[n])
    # combined: every constant within 2 std of the truth (the uncertainty means something)
    for n in ("E1", "E2", "nu12", "G12", "G13", "G23"):
        p = comb[n]
        assert abs(p["value"] - truth[n]) <= 2 * p["std"], (n, p, truth[n])
    # waves only carry the out-of-plane shear moduli (paper Table 3 parameters)
    assert {"E1", "G13", "G23"} <= set(res["identified"]["waves"])
    # no effect was injected: the diagnosis must not invent one
    assert res["gap"]["verdict"] == "none"
    for key in ("run", "features", "gap_figure", "report"):
        assert (out / res["files"][key].split("/")[-1]).stat().st_size > 0
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html
    assert "Uncertainty budget" in html and "expanded U (k = 2)" in html     # the certificate's GUM budget
    # section 6: waves only, a tone-burst pitch-catch run on the aluminium plate (edge
    # reflections, crosstalk, sensor response): E and G within 1 % of the truth
    al = res["waves_only_aluminium"]
    truth_al = load_specimen("aluminium").laminate.plies[0].material.params()
    assert al["converged"] and set(al["identified"]) == {"E", "G"}
    for n in ("E", "G"):
        assert al["identified"][n]["value"] == pytest.approx(truth_al[n], rel=0.01), n
    assert al["points"]["A0"] >= 2 and al["points"]["S0"] >= 2
