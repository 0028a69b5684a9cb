"""The verdict's set-aside test (engine.identify.verdict.set_aside_test): how many listed peaks a
fit may leave without a model mode before the verdict says so first.

Found by bench/bench_plan.py (session 24, wood-like plate, case 46): a fit set aside the three
E2-informative peaks of 12, E2 +25 %, chi^2/nu 2.6 (p = 0.018), and was called "consistent"
because 3 is not more than 2 AND 25 % of 12. The peaks here come from the independent
Rayleigh-Ritz plate (bench/independent/ritz_plate.py), not from labid's plate model."""
from __future__ import annotations

import math
import tomllib
from importlib import resources

import numpy as np
import pytest

from bench.independent.ritz_plate import RitzPlate, plies_from_table
from engine.identify.verdict import SPURIOUS_RATE, set_aside_test
from labid.workflows.identification import problem_from_features, run

NOMINAL = {"E1": 136.7e9, "E2": 9.0e9, "G12": 5.0e9}


def test_the_count_and_joint_p_values_are_the_binomial_tail_and_fisher_s_combination():
    """Exact: P(K >= k) summed from the binomial terms; Fisher's chi^2 with 4 dof has the closed
    form sf(x) = exp(-x/2) (1 + x/2), i.e. p1 p2 (1 - ln(p1 p2))."""
    q = SPURIOUS_RATE
    for n, k, pc in ((12, 3, 0.0177), (40, 2, 0.5), (8, 1, 0.9), (10, 7, 0.99)):
        tail = sum(math.comb(n, j) * q ** j * (1 - q) ** (n - j) for j in range(k, n + 1))
        p_count, p_joint = set_aside_test(n, k, pc)
        assert p_count == pytest.approx(tail, rel=1e-10)
        prod = tail * pc
        assert p_joint == pytest.approx(prod * (1.0 - math.log(prod)), rel=1e-9)
    assert set_aside_test(12, 0, 1e-6) == (1.0, 1.0)      # nothing set aside: the chi^2 test alone


@pytest.fixture(scope="module")
def ritz_peaks():
    """The 9 lowest flexible modes (Hz) of the built-in CFRP plate by the Ritz plate, and 3
    frequencies that are no mode of it (the middle of the three widest gaps between them)."""
    table = tomllib.loads(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text())
    plies, L, W = plies_from_table(table)
    f = RitzPlate(plies, L, W, order=10).solve(12).frequencies_hz[:9]
    gaps = np.argsort(np.diff(f))[-3:]
    foreign = np.sqrt(f[gaps] * f[gaps + 1])
    return np.asarray(f, float), np.sort(foreign)


def _fit(freqs):
    freqs = np.sort(np.asarray(freqs, float))
    doc = {"specimen": "cfrp", "modal": {"frequencies_hz": freqs.tolist(), "sigma_hz": (1e-3 * freqs).tolist()}}
    return run(problem_from_features(doc), tuple(NOMINAL), dict(NOMINAL)).to_dict()


def test_three_of_twelve_peaks_not_the_plate_s_is_said_first_and_nothing_identified(ritz_peaks):
    """9 Ritz modes + 3 peaks that are not the plate's: the three are set aside. The old rule
    (more than 2 AND 25 % of 12) let it pass as identified; P(K >= 3 | 12, 3 %) = 0.0047, so
    the verdict calls it questionable (or inconsistent) and reports no constant identified."""
    f, foreign = ritz_peaks
    out = _fit(np.r_[f, foreign])
    aside = [r["measured_hz"] for r in out["pairing"] if r["mode_index"] is None]
    np.testing.assert_allclose(sorted(aside), foreign, rtol=1e-12)
    assert out["fit"]["set_aside_p"] < 1e-2
    assert out["fit"].get("questionable") or not out["fit"]["consistent"]
    assert not out["fit"]["identified"]
    assert not any(p["identified"] for p in out["parameters"].values())


def test_one_peak_of_ten_not_the_plate_s_is_accepted(ritz_peaks):
    """The same plate with one foreign peak: set aside, the fit consistent, not questionable,
    every constant identified and within 3 % of the Ritz plate's (its constants are nominal)."""
    f, foreign = ritz_peaks
    out = _fit(np.r_[f, foreign[:1]])
    assert sum(r["mode_index"] is None for r in out["pairing"]) == 1
    assert out["fit"]["consistent"] and "questionable" not in out["fit"]
    assert out["fit"]["identified"]
    for n, p in out["parameters"].items():
        assert abs(p["value"] / NOMINAL[n] - 1) < 0.03, (n, p["value"])
