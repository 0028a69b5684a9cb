"""labid.workflows.waveloop: how two rounds' wave curves differ (pick_changes: exact counts;
curve_changes / curves_converged: the stopping rule on numpy-made curves)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from labid.workflows.waveloop import curve_changes, curves_converged, pick_changes


def curve(f, v, s, mode="A0", direction=0.0):
    return {"mode": mode, "direction_deg": direction, "frequency_hz": f, "group_velocity_m_s": v, "sigma_m_s": s}


def test_the_same_picks_have_no_change():
    w = [curve([50e3, 80e3], [1000.0, 1200.0], [2.0, 3.0])]
    assert pick_changes(w, w) == {"added": 0, "lost": 0, "max_shift_sigma": 0.0}


def test_points_added_lost_and_moved_in_sigmas():
    """A point within 0.5 % in frequency is the same point; its change counts in the smaller
    of the two sigmas; another curve (S0) appearing adds its points."""
    old = [curve([50e3, 80e3, 120e3], [1000.0, 1200.0, 1300.0], [2.0, 3.0, 4.0])]
    new = [curve([50.1e3, 90e3, 120e3], [1004.0, 1250.0, 1301.0], [4.0, 3.0, 2.0]),
           curve([100e3], [5000.0], [10.0], mode="S0")]
    ch = pick_changes(old, new)
    assert (ch["added"], ch["lost"]) == (2, 1)             # 90 kHz and S0 added, 80 kHz lost
    assert ch["max_shift_sigma"] == pytest.approx(2.0)     # 4 m/s over min(2, 4)


# --- the curves' convergence rule (session 29): numpy-made curves, no labid model --------------

def line(f):
    """A smooth A0-like group velocity (m/s) rising to a maximum near 130 kHz, f in Hz."""
    f = np.asarray(f, float)
    return 1430.0 - 0.012 * (f / 1e3 - 130.0) ** 2


F_OLD = [60e3, 98e3, 135e3, 171e3]
F_NEW = [58e3, 94e3, 129e3, 165e3]       # the next round's band: every point on another frequency


def test_points_on_other_frequencies_of_the_same_line_are_converged():
    """Seed 0's case: no point within 0.5 % of an old one (pick_changes: all added, all lost),
    yet the same line within noise: the curve rule says converged."""
    sig = [3.0, 1.5, 2.0, 1.5]
    rng = np.random.default_rng(0)
    old = [curve(F_OLD, list(line(F_OLD) + rng.normal(0, 0.3, 4) * sig), sig)]
    new = [curve(F_NEW, list(line(F_NEW) + rng.normal(0, 0.3, 4) * sig), sig)]
    pc = pick_changes(old, new)
    assert (pc["added"], pc["lost"]) == (4, 4)
    ch = curve_changes(old, new)
    assert ch["compared"] == 6                        # 3 new points in the old span, 3 old in the new
    assert (ch["span_added"], ch["span_lost"]) == (1, 1)
    assert ch["span_change"] == pytest.approx(6e3 / 37e3)  # the high end moved 6 kHz; spacing 37 kHz
    assert ch["curve_shift_sigma"] < 1.0
    assert curves_converged(ch)


def test_a_curve_moved_by_two_sigma_is_not_converged():
    """The same frequencies' shift of 2 sigma on every point: |dv| / sqrt(2) sigma = 1.41 > 1."""
    sig = [2.0] * 4
    old = [curve(F_OLD, list(line(F_OLD)), sig)]
    new = [curve(F_NEW, list(line(F_NEW) + 4.0), sig)]
    ch = curve_changes(old, new)
    assert ch["curve_shift_sigma"] == pytest.approx(2 * 2.0 / math.hypot(2.0, 2.0), rel=1e-6)
    assert not curves_converged(ch)


def test_a_span_that_gained_a_point_or_a_curve_that_vanished_is_not_converged():
    sig = [2.0] * 4
    old = [curve(F_OLD, list(line(F_OLD)), sig)]
    wider = [curve(F_OLD + [210e3], list(line(F_OLD + [210e3])), sig + [2.0])]
    ch = curve_changes(old, wider)
    assert ch["curve_shift_sigma"] == pytest.approx(0.0, abs=1e-9)
    assert ch["span_added"] == 1 and ch["span_change"] == pytest.approx(39e3 / 37e3)
    assert not curves_converged(ch)
    gone = curve_changes(old + [curve([100e3], [5000.0], [10.0], mode="S0")], old)
    assert gone["curves_lost"] == 1 and not curves_converged(gone)
