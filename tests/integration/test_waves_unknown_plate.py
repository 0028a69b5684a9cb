"""Guided waves on a plate whose constants the specimen file does not know (issue 24).

The simulated rig synthesises a plate whose moduli are the specimen file's times
``[simulation] truth_scale``; the wave analysis works from the file's constants. The references
are outside the method: the group velocity of the TRUE plate from the independent model of
bench/independent/legendre_safe.py (hierarchical Legendre elements, no code of engine.safe),
and the rig file's own numbers. No pick is compared with the model that made its window (the
windows come from the file's constants, 40 % off)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bench.independent.legendre_safe import LegendrePlate, branches, layers_of
from labid.base.errors import UserError
from labid.cli.main import main
from labid.inputs.rig import parse_truth_scale, rig_from_text
from labid.inputs.specimen import load_specimen
from labid.workflows.acquisition import AcquisitionSession
from labid.workflows.analysis import wave_features
from mock_hw.rig import SimulatedDevice, truth_laminate

BENCH = Path(__file__).resolve().parents[2] / "bench" / "rigs"


def test_truth_scale_parses_a_factor_a_table_and_refuses_nonsense():
    assert parse_truth_scale(0.7) == (("*", 0.7),)
    assert parse_truth_scale({"G13": 0.6, "E2": 1.3}) == (("G13", 0.6), ("E2", 1.3))
    assert parse_truth_scale("G13=0.6,E2=1.3") == (("G13", 0.6), ("E2", 1.3))
    assert parse_truth_scale("0.714") == (("*", 0.714),)
    for bad in ("G13=9", "nu12=0.9", "x", {"G13": "a"}):
        with pytest.raises(UserError, match="truth_scale"):
            parse_truth_scale(bad)


def test_the_simulated_plate_has_the_scaled_moduli():
    lam = load_specimen("cfrp").laminate
    m0 = lam.plies[0].material
    m = truth_laminate(lam, (("*", 0.5), ("G13", 2.0))).plies[0].material
    assert (m.E1, m.E2, m.G12, m.G23) == pytest.approx((0.5 * m0.E1, 0.5 * m0.E2, 0.5 * m0.G12, 0.5 * m0.G23))
    assert m.G13 == pytest.approx(m0.G13)                 # 0.5 then 2.0
    assert (m.nu12, m.density) == (m0.nu12, m0.density)


def test_acquire_truth_is_for_the_simulated_rig_only(tmp_path, capsys):
    code = main(["acquire", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"), "--backend", "nidaqmx",
                 "--truth", "0.7"])
    assert code == 2 and "--truth" in capsys.readouterr().err
    assert not (tmp_path / "r.h5").exists()


def test_a_burst_sweep_cycles_its_centre_frequencies_shot_by_shot():
    text = (BENCH / "cfrp_pzt_sweep_2dir.toml").read_text()
    rig = rig_from_text(text, "sweep")
    assert rig.wave_source.burst.sweep_hz == (60e3, 100e3, 150e3, 200e3, 250e3)
    dev = SimulatedDevice(rig, load_specimen(str(BENCH / "cfrp_large.toml")), "wave")
    assert [dev.shot_rig(k).wave_source.burst.frequency_hz for k in (0, 1, 6)] == [60e3, 100e3, 100e3]
    with pytest.raises(UserError, match="frequency_hz"):
        rig_from_text(text.replace("frequency_hz = [60.0e3", "frequency_hz = [-60.0e3"), "sweep")


@pytest.fixture(scope="module")
def stiff_file():
    """The 1 m CFRP bench plate, pencil at the centre, the MFC pair along 0 deg only, 2 shots;
    the plate's moduli 0.714 x the file's: the file is 40 % too stiff."""
    text = (BENCH / "cfrp_pencil_2dir.toml").read_text()
    text = text.split('[[devices.waves.channels]]\nname = "y1"')[0]
    rig = rig_from_text(text, "bench")
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", 1 / 1.4),)))
    spec = load_specimen(str(BENCH / "cfrp_large.toml"))
    dev = SimulatedDevice(rig, spec, "wave", None, 0)
    d = rig.device("wave")
    dev.configure(d.channels, d.timing, d.trigger)
    session = AcquisitionSession.__new__(AcquisitionSession)     # only its _read
    recs = [session._read(dev, d) for _ in range(2)]
    notes: list[str] = []
    feats, curves, _, _, info = wave_features(recs, rig, spec, notes=notes)
    return spec, rig, feats, notes, info


@pytest.mark.slow
def test_a0_is_measured_from_the_records_when_the_file_is_40_percent_off(stiff_file):
    """At least 8 independent A0 points, every one within 1 % of the TRUE plate's group
    velocity (independent model) and within 3 of its own sigma."""
    spec, rig, feats, notes, info = stiff_file
    a0 = next(w for w in feats if w["mode"] == "A0" and w["direction_deg"] == 0.0)
    f = np.array(a0["frequency_hz"])
    v, s = np.array(a0["group_velocity_m_s"]), np.array(a0["sigma_m_s"])
    true = truth_laminate(spec.laminate, rig.sim.truth_scale)
    ref = branches(LegendrePlate(layers_of(true.plies, 0.0), 4), f.max() * 1.05).at(0, 2 * np.pi * f)[1]
    assert f.size >= 8
    assert np.max(np.abs(v / ref - 1)) < 0.01
    assert np.max(np.abs(v - ref) / s) < 3.0


@pytest.mark.slow
def test_the_contradiction_is_said_in_one_line_and_kept_in_the_features(stiff_file):
    """The file's A0 is ~15 % too fast at these frequencies: the analysis says so (arrives later
    than predicted) and puts it in analysis.nominal_mismatch."""
    spec, rig, feats, notes, info = stiff_file
    mm = [m for m in info["mismatch"] if m["mode"] == "A0"]
    assert len(mm) == 1 and 0.75 < mm[0]["velocity_ratio"] < 0.92
    assert "A0 along 0 deg arrives" in mm[0]["message"] and "later than the nominal" in mm[0]["message"]
    assert mm[0]["message"] in notes
