"""labid.workflows.waveloop.pick_changes: how two rounds' wave curves differ (exact counts)."""
from __future__ import annotations

import pytest

from labid.workflows.waveloop import pick_changes


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
