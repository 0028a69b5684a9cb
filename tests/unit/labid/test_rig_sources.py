"""Rig files as labs have them (issue 14): source kinds, wave-only and modal-only rigs,
sensor faces and responses, separate acquisitions; every mistake one line, exit 2."""
from __future__ import annotations

import pytest

from labid.cli.main import main
from labid.base.errors import UserError
from labid.inputs.rig import load_rig, read_rig_text, rig_from_text

WAVE_ONLY = """
name = "wave-only: a tone-burst force and one sensor"
[wave_source]
kind = "tone_burst"
x = 0.2
y = 0.5
frequency_hz = 100.0e3
cycles = 3.5
window = "hamming"
force_n = 2.0
[devices.scope]
role = "wave"
rate_hz = 2.0e6
samples = 1024
pretrigger = 100
trigger = { channel = "s1", level_v = 0.01 }
[[devices.scope.channels]]
name = "s1"
sensitivity = 1.0
distance_m = 0.2
face = "bottom"
highpass_hz = 500.0
resonance_hz = 300.0e3
resonance_q = 8.0
"""

MODAL_ONLY = """
[hammer]
x = 0.1
y = 0.1
[devices.vib]
role = "hammer"
rate_hz = 10000.0
samples = 1000
[[devices.vib.channels]]
name = "acc"
kind = "accelerometer"
sensitivity = 1e-3
x = 0.2
y = 0.2
"""


def test_wave_only_rig_needs_no_hammer_table():
    r = rig_from_text(WAVE_ONLY, "w.toml")
    assert r.hammer is None and r.device("hammer") is None
    src = r.wave_source
    assert (src.kind, src.burst.frequency_hz, src.burst.cycles, src.burst.window, src.burst.amplitude) == \
        ("tone_burst", 100e3, 3.5, "hamming", 2.0)
    assert src.burst.duration_s == pytest.approx(3.5 / 100e3)
    (s,) = r.wave_sensors
    assert (s.face, s.highpass_hz, s.resonance_hz, s.resonance_q, s.acquisition) == ("bottom", 500.0, 300e3, 8.0, 0)
    r.check_specimen(1.0, 1.0)


def test_modal_only_rig_needs_no_wave_source():
    r = rig_from_text(MODAL_ONLY, "m.toml")
    assert r.device("wave") is None and r.wave_source is r.hammer


def test_builtin_pitch_catch_rig():
    r = load_rig("pzt-aluminium")
    src = r.wave_source
    assert (src.kind, src.channel, src.diameter_m, src.face, src.pair) == ("pzt", "exc", 0.010, "top", None)
    assert (src.burst.frequency_hz, src.burst.cycles, src.burst.window, src.burst.amplitude) == \
        (180e3, 5.0, "hann", 10.0)
    d = r.device("wave")
    assert d.crosstalk_db == -60.0 and d.acquisitions == (("exc", "s1", "s2"),) and r.sim.reflections == 1
    assert [w.distance_m for w in r.wave_sensors] == [0.12, 0.42]


@pytest.mark.parametrize("edit,words", [
    (('window = "hamming"', 'window = "kaiser"'), ["wave_source.window", "'kaiser'", "hann"]),
    (("frequency_hz = 100.0e3\n", ""), ["wave_source.frequency_hz", "missing key"]),
    (('kind = "tone_burst"', 'kind = "laser"'), ["wave_source.kind", "'laser'", "pzt"]),
    (("cycles = 3.5", "cycles = 3.5\nrise_s = 1e-6"), ["wave_source.rise_s", "unknown key"]),
    (('face = "bottom"', 'face = "left"'), ["channels[0].face", "'left'", "top"]),
    (("resonance_q = 8.0", "resonance_q = 0.1"), ["channels[0].resonance_q", "quality factor"]),
    (("[wave_source]", "[wave_source]\nchannel = \"nope\""), ["wave_source.channel", "'nope'"]),
    (("[wave_source]", "[wave_source]\nchannel = \"s1\""), ["wave_source.channel", "not a sensor"]),
])
def test_bad_source_and_sensor_keys_name_the_key(edit, words):
    text = WAVE_ONLY.replace(*edit)
    assert text != WAVE_ONLY
    with pytest.raises(UserError) as e:
        rig_from_text(text, "w.toml")
    msg = str(e.value)
    for w in words:
        assert w in msg, (w, msg)


def test_pzt_source_and_pair_keys():
    text = WAVE_ONLY.replace('''kind = "tone_burst"
x = 0.2
y = 0.5
frequency_hz = 100.0e3
cycles = 3.5
window = "hamming"
force_n = 2.0''', '''kind = "pzt"
x = 0.2
y = 0.5
diameter_m = 0.007
pair = "antisymmetric"
excitation = { frequency_hz = 60e3, cycles = 4, amplitude_v = 20.0 }''')
    src = rig_from_text(text, "p.toml").wave_source
    assert (src.kind, src.diameter_m, src.pair, src.burst.frequency_hz, src.burst.amplitude) == \
        ("pzt", 0.007, "antisymmetric", 60e3, 20.0)
    with pytest.raises(UserError, match="excitation"):
        rig_from_text(text.replace("excitation = { frequency_hz = 60e3, cycles = 4, amplitude_v = 20.0 }", ""),
                      "p.toml")


def test_a_wave_rig_without_any_source_and_a_hammer_rig_without_hammer_exit_2(tmp_path, capsys):
    bad = WAVE_ONLY.split("[devices.scope]")
    no_source = "[devices.scope]".join([bad[0].split("[wave_source]")[0], bad[1]])
    p = tmp_path / "rig.toml"
    p.write_text(no_source)
    code = main(["acquire", "--rig", str(p), "--specimen", "aluminium", "--out", str(tmp_path / "r.h5")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "wave_source" in err[0] and "missing table" in err[0]
    p.write_text(MODAL_ONLY.replace("[hammer]\nx = 0.1\ny = 0.1\n", ""))
    code = main(["acquire", "--rig", str(p), "--specimen", "aluminium", "--out", str(tmp_path / "r.h5")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "hammer" in err[0] and "missing table" in err[0]


def test_separate_acquisitions_are_numbered_without_gaps():
    text = WAVE_ONLY.replace("resonance_q = 8.0", "resonance_q = 8.0\nacquisition = 1")
    with pytest.raises(UserError, match="acquisition 0 has no channel"):
        rig_from_text(text, "w.toml")


def test_default_rig_still_parses_with_its_pencil_and_hammer():
    text, _ = read_rig_text("default")
    r = rig_from_text(text)
    assert r.wave_source.kind == "pencil" and r.hammer.kind == "hammer" and r.sim.reflections == 1
