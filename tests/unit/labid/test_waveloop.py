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


# --- iterate_store's stopping on the constants, and the carried constants (fakes, no model) -------

class _Store:
    path = "fake.h5"

    def specimen_toml(self):
        from labid.inputs.specimen import load_specimen, specimen_text
        return specimen_text(load_specimen("cfrp"))

    def rig_toml(self):
        return ""

    def shots(self, kind):
        return []


def _loop(monkeypatch, estimates):
    """iterate_store with identify returning ``estimates`` in turn ({name: (value, std)}) and a
    re-pick that puts 4 points of ``line`` on a grid that follows the nominal E1; returns the
    analysis and the nominal constants each re-pick was given."""
    from types import SimpleNamespace

    from labid.workflows import waveloop
    from labid.workflows.analysis import Analysis
    given, it = [], iter(estimates)

    def identify(problem, names):
        e = next(it)
        return SimpleNamespace(params={n: v for n, (v, _) in e.items()}, names=list(e),
                               std=[s for _, s in e.values()], rel_std={n: s / v for n, (v, s) in e.items()},
                               fit={"identified": True})

    def wave_features(records, rig, spec, settings, notes):
        m = spec.laminate.plies[0].material
        given.append(m.params())
        f = np.array(F_OLD) * (m.E1 / 136.7e9) ** 0.25
        v = line(f) + 3.0 * len(given)               # each re-pick: the curve 3 m/s higher (1.5 sigma)
        return [curve(list(f), list(v), [1.4] * 4)], {}, {}, {}, {}

    monkeypatch.setattr(waveloop, "identify", identify)
    monkeypatch.setattr(waveloop, "problem_from_features", lambda feats, src: SimpleNamespace(material=None))
    monkeypatch.setattr(waveloop, "rig_from_text", lambda text, src: None)
    monkeypatch.setattr(waveloop, "wave_features", wave_features)
    an = Analysis({"waves": [curve(F_OLD, list(line(F_OLD)), [1.4] * 4)]})
    return waveloop.iterate_store(_Store(), an, max_iter=4), given


def test_the_loop_stops_when_the_constants_stay_within_their_std(monkeypatch):
    """Round 1 moves E1 from the file's 136.7 GPa (re-pick); round 2 moves it by 0.5 std of the
    constants the picks were made with: a fixed point, no second re-pick."""
    an, given = _loop(monkeypatch, [{"E1": (94e9, 6e9)}, {"E1": (91e9, 6e9)}, {"E1": (95e9, 6e9)}])
    its = an.features["analysis"]["iterations"]
    assert len(given) == 1 and len(its) == 2
    assert its[0]["constants_shift_std"] == pytest.approx((136.7 - 94) / 6)
    assert its[1]["constants_shift_std"] == pytest.approx(0.5)
    assert "added" in its[0] and "curve_shift_sigma" in its[0] and "added" not in its[1]
    assert an.notes[-1].startswith("pick <-> identify: converged after 2 round(s)")


def test_a_constant_no_longer_determined_keeps_its_last_value(monkeypatch):
    """G13 determined in round 1 and not in round 2 (relative std 0.5): the round-2 re-pick keeps
    round 1's G13, not the file's 5.08 GPa; the curves moving 1.5 sigma a round keep it going."""
    an, given = _loop(monkeypatch, [{"E1": (94e9, 6e9), "G13": (3.5e9, 0.5e9)},
                                    {"E1": (80e9, 6e9), "G13": (3.0e9, 1.5e9)},
                                    {"E1": (94e9, 6e9)}, {"E1": (80e9, 6e9)}])
    assert [g["G13"] for g in given[:2]] == [3.5e9, 3.5e9]
    assert given[1]["E1"] == 80e9
    its = an.features["analysis"]["iterations"]
    assert len(its) == 4 and its[1]["curve_shift_sigma"] > 1.0
    assert "still changing after 4 rounds" in an.notes[-1]
