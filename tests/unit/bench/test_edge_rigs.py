"""The edge-break bench rigs (bench/rigs/cfrp_pencil_edge_*.toml, issue 24 session 28): their
synthesis band clears the analysis band, and the 20 / 60 cm rig's echoes come late (image-source
geometry of the 1 m square, worked by hand)."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from bench.bench_unknown_plate import EDGE_BAND
from engine.waves import ray_paths
from labid.inputs.rig import rig_from_text

RIGS = Path(__file__).resolve().parents[3] / "bench" / "rigs"


def _rig(name):
    return rig_from_text((RIGS / name).read_text(), f"bench/rigs/{name}")


@pytest.mark.parametrize("name", ["cfrp_pencil_edge_0.toml", "cfrp_pencil_edge_90.toml",
                                  "cfrp_pencil_edge_0_long.toml"])
def test_the_simulators_band_taper_lies_above_the_edge_analysis_band(name):
    # mock_hw tapers the synthesised spectrum to 0 over the top 10 % of wave_fmax_hz (zero phase);
    # reaching into the analysis band it biased S0 along 0 deg by -0.45 % at 287-307 kHz (h54)
    assert 0.9 * _rig(name).sim.wave_fmax_hz >= 1.5 * EDGE_BAND.wave_band_hz[1]


def test_the_long_edge_rig_has_a_40_cm_baseline_and_its_first_echo_is_half_a_metre_behind():
    rig = _rig("cfrp_pencil_edge_0_long.toml")
    src = rig.wave_source
    d = {w.channel: w.distance_m for w in rig.wave_sensors}
    assert (src.x, src.y) == (0.0, 0.5) and d == {"x1": 0.20, "x2": 0.60}
    for r in d.values():
        paths = sorted(p.length_m for p in ray_paths((0.0, 0.5), (r, 0.5), 1.0, 1.0, order=1))
        # by hand: the direct path r; the far edge's image 2 - r; the side edges' hypot(r, 1);
        # the source's own edge gives the direct path again (the lead sits on it)
        assert paths[0] == pytest.approx(r)
        echoes = [p for p in paths if p > r + 1e-9]
        assert min(echoes) == pytest.approx(min(2.0 - r, math.hypot(r, 1.0)))
        assert min(echoes) - r >= 0.56
