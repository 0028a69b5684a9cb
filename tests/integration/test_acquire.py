"""``labid acquire`` and the AcquisitionSession: rig errors, retries, stop, SIGKILL, resume."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from labid.workflows.acquisition import AcquisitionSession
from labid.cli.main import main
from labid.base.errors import UserError
from labid.inputs.rig import load_rig, read_rig_text, rig_from_text
from labid.store import RunStore
from labid.inputs.specimen import load_specimen
from mock_hw.rig import SimulatedDevice

ROOT = Path(__file__).resolve().parents[2]


def rig_text(*edits: tuple[str, str]) -> str:
    text, _ = read_rig_text("default")
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    return text


def run_cli(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.err


def test_acquire_records_hits_and_json_summary(tmp_path, capsys):
    out, js = tmp_path / "run.h5", tmp_path / "s.json"
    code, err = run_cli(["acquire", "--specimen", "cfrp", "--out", str(out), "--hits", "2",
                         "--waves", "0", "--json", str(js)], capsys)
    assert code == 0, err
    assert "hammer 2/2: recorded hammer_0002" in err
    summary = json.loads(js.read_text())
    assert summary["recorded"] == {"hammer": 2, "wave": 0} and summary["complete"]
    with RunStore(out, "r") as s:
        assert s.n_shots("hammer") == 2
        assert "[devices.vib]" in s.rig_toml() and "T300" in s.specimen_toml()
        r = s.shots("hammer")[0]
    assert r.backend == "mock" and {c.name for c in r.channels} == {"force", "acc1", "acc2", "acc3"}


@pytest.mark.parametrize("edit, words", [
    (("rate_hz = 10000.0", "rate_hz = [10000.0"), ["malformed TOML", "rig.toml"]),
    (('channel = "force", level_v', 'channel = "hammer", level_v'),
     ["devices.vib.trigger.channel", "'hammer'", "unknown channel"]),
    (("rate_hz = 2.0e6", "rate_hz = 8.0e6"), ["devices.waves.rate_hz", "8e+06", "impossible sample rate",
                                              "max_rate_hz"]),
    (("rate_hz = 10000.0", "rate_hz = 0.0"), ["devices.vib.rate_hz", "impossible sample rate"]),
    (("samples = 4096", "samples = 4096.5"), ["devices.waves.samples", "expected an integer"]),
    (("x = 0.31", "x = 0.45"), ["devices.vib.channels.acc2", "outside"]),
])
def test_bad_rig_files_exit_2_naming_the_cause(tmp_path, capsys, edit, words):
    rig = tmp_path / "rig.toml"
    rig.write_text(rig_text(edit))
    code, err = run_cli(["acquire", "--rig", str(rig), "--specimen", "cfrp",
                         "--out", str(tmp_path / "r.h5"), "--hits", "1"], capsys)
    assert code == 2
    line = err.strip().splitlines()[-1]
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    for w in words:
        assert w in line, (w, line)
    assert not (tmp_path / "r.h5").exists()


def test_missing_ni_driver_is_one_line_exit_2(tmp_path, capsys):
    code, err = run_cli(["acquire", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"),
                         "--backend", "nidaqmx", "--hits", "1"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--backend mock" in err
    assert not (tmp_path / "r.h5").exists()          # no empty run file left behind


def test_bad_effect_exit_2(tmp_path, capsys):
    code, err = run_cli(["acquire", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"),
                         "--effects", "gravity=2"], capsys)
    assert code == 2 and "--effects" in err and "sensor_mass" in err


def test_missed_and_overloaded_shots_are_redone_or_given_up(tmp_path):
    spec = load_specimen("cfrp")
    rig = rig_from_text(rig_text(("miss_probability = 0.0", "miss_probability = 0.5")), "miss.toml")
    events = []
    with RunStore(tmp_path / "a.h5") as s:
        summary = AcquisitionSession(rig, spec, s, seed=2).run(4, 0, progress=events.append)
        assert s.n_shots("hammer") == 4
    assert summary["recorded"]["hammer"] == 4 and summary["redone"] > 0
    assert any(e["status"] == "no trigger" for e in events)
    # an accelerometer range far too small: every hit overloads, the session gives up
    rig = rig_from_text(rig_text(('sensitivity = 1.02e-3    # V/(m/s^2), 10 mV/g\nrange_v = 5.0',
                                  'sensitivity = 1.02e-3\nrange_v = 0.01')), "over.toml")
    with RunStore(tmp_path / "b.h5") as s:
        summary = AcquisitionSession(rig, spec, s).run(2, 0)
        assert s.n_shots() == 0
    assert summary["gave_up"]["hammer"] == 1 and not summary["complete"]
    assert "overload on acc1" in summary["problems"][0]


def test_double_hits_are_redone(tmp_path):
    rig = rig_from_text(rig_text(("double_hit_probability = 0.0", "double_hit_probability = 0.5")), "d.toml")
    with RunStore(tmp_path / "d.h5") as s:
        summary = AcquisitionSession(rig, load_spec(), s, seed=1).run(4, 0)
        recs = s.shots("hammer")
    assert any("double hit" in p for p in summary["problems"])
    assert len(recs) == 4 and not any(r.meta["sim_double_hit"] for r in recs)


def load_spec():
    return load_specimen("cfrp")


def test_should_stop_keeps_what_was_recorded_and_resume_appends(tmp_path):
    p = tmp_path / "r.h5"
    n = {"k": 0}

    def progress(ev):
        n["k"] += ev["status"] == "recorded"

    with RunStore(p) as s:
        summary = AcquisitionSession(None, "cfrp", s, seed=4).run(
            5, 0, progress=progress, should_stop=lambda: n["k"] >= 2)
    assert summary["interrupted"] and summary["recorded"]["hammer"] == 2
    with RunStore(p) as s:
        summary = AcquisitionSession(None, "cfrp", s, seed=4).run(5, 0, total=True)
        recs = s.shots("hammer")
    assert summary["recorded"]["hammer"] == 3 and len(recs) == 5
    # the resumed session continued the simulator's sequence: no shot repeated
    assert [r.meta["shot_index"] for r in recs] == [0, 1, 2, 3, 4]


def _spawn(args: list[str]) -> subprocess.Popen:
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "labid.cli.main", "acquire", *args],
                            stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)


def _wait_recorded(proc: subprocess.Popen, k: int) -> list[str]:
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if sum("recorded hammer_" in ln for ln in lines) >= k:
            return lines
    raise AssertionError("".join(lines))


@pytest.mark.slow
def test_sigkill_keeps_every_completed_shot_identical(tmp_path):
    """SIGKILL `labid acquire` part-way: the file opens, every shot reported before the
    kill is there, and each equals a fresh re-synthesis with the same seed."""
    p = tmp_path / "run.h5"
    proc = _spawn(["--specimen", "cfrp", "--out", str(p), "--hits", "200", "--waves", "0",
                   "--seed", "11"])
    lines = _wait_recorded(proc, 4)
    proc.kill()
    proc.wait()
    reported = [ln.split("recorded ")[1].strip() for ln in lines if "recorded hammer_" in ln]
    with RunStore(p, "r") as s:
        recs = s.shots("hammer")
    names = [r.meta["shot"] for r in recs]
    assert names[:len(reported)] == reported and len(recs) < 200
    rig, spec = load_rig(), load_specimen("cfrp")
    dev = SimulatedDevice(rig, spec, "hammer", seed=11)
    d = rig.device("hammer")
    dev.configure(d.channels, d.timing, d.trigger)
    for r in recs:
        dev.shot_index = r.meta["shot_index"]
        dev.arm()
        again = dev.read()
        for c in d.channels:
            lsb = 2 * c.range_v / 2**d.adc_bits
            assert np.max(np.abs(r.data[c.name] - again.data[c.name])) <= lsb * 1.01
        assert r.meta["sim_force_peak_n"] == again.meta["sim_force_peak_n"]
    # resume to the planned size: the killed file is repaired and appended to
    code = subprocess.run([sys.executable, "-m", "labid.cli.main", "acquire", "--specimen", "cfrp",
                           "--out", str(p), "--hits", str(len(recs) + 2), "--waves", "0", "--total",
                           "--seed", "11", "--quiet"], cwd=ROOT, capture_output=True, text=True,
                          env=dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT)))
    assert code.returncode == 0, code.stderr
    with RunStore(p, "r") as s:
        after = s.shots("hammer")
    assert len(after) == len(recs) + 2
    for a, b in zip(recs, after):
        np.testing.assert_array_equal(a.data["acc1"], b.data["acc1"])


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_with_summary(tmp_path):
    p, js = tmp_path / "run.h5", tmp_path / "s.json"
    proc = _spawn(["--specimen", "cfrp", "--out", str(p), "--hits", "200", "--waves", "0",
                   "--json", str(js)])
    _wait_recorded(proc, 2)
    proc.send_signal(signal.SIGINT)
    _, rest = proc.communicate()              # the process ends on the event it was sent, at its pace
    assert proc.returncode == 130, rest
    summary = json.loads(js.read_text())
    assert summary["interrupted"] and summary["recorded"]["hammer"] >= 2
    with RunStore(p, "r") as s:
        assert s.n_shots("hammer") == summary["recorded"]["hammer"]


def test_documented_example_rig_records_hammer_triggered_waves(tmp_path):
    text = (ROOT / "docs" / "rig-file.md").read_text()
    example = text.split("## Minimal example")[1].split("```toml")[1].split("```")[0]
    rig = rig_from_text(example, "docs example")
    assert rig.device("wave").trigger.channel == "hammer_hf"
    assert rig.wave_sensor("strain1").distance_m == 0.375
    with RunStore(tmp_path / "ex.h5") as s:
        summary = AcquisitionSession(rig, "aluminium", s).run(None, 1)   # no hammer device
        rec = s.shots("wave")[0]
        with pytest.raises(UserError, match="role 'hammer'"):
            AcquisitionSession(rig, "aluminium", s).run(1, 0)
    assert summary["complete"] and rec.scaled("hammer_hf").max() > 10.0   # N, of the 20 N hit


def test_rig_features_block_follows_the_contract():
    f = load_rig().features()
    assert [a["mass_kg"] for a in f["accelerometers"]] == [0.002] * 3
    assert f["supports"][0] == {"x": 0.03, "y": 0.33}
    assert f["wave_path_m"] == pytest.approx(0.15) and f["sensor_length_m"] == 0.0


class ScriptedDevice:
    """A protocol-only device replaying a script: 'miss', 'over' or 'ok' per read."""

    def __init__(self, spec, script):
        self.name, self.spec, self.script, self.calls = spec.name, spec, list(script), []

    def configure(self, channels, timing, trigger):
        self.calls.append("configure")
        self.cfg = (channels, timing, trigger)

    def arm(self):
        self.calls.append("arm")

    def read(self, timeout_s=10.0):
        from drivers.protocol import NoTrigger, Record
        self.calls.append("read")
        what = self.script.pop(0)
        if what == "miss":
            raise NoTrigger(f"{self.name}: no trigger")
        channels, timing, trigger = self.cfg
        data = {c.name: np.full(timing.samples, 0.001 * (len(self.calls))) for c in channels}
        over = {c.name: what == "over" and c.kind == "accelerometer" for c in channels}
        return Record(data, channels, timing, trigger, over, backend="scripted")

    def close(self):
        self.calls.append("close")


def test_workflow_uses_only_the_protocol_and_redoes_bad_shots(tmp_path):
    """Any Device works; a missed and an overloaded read are redone, good ones stored
    in order, and the device is configured once and closed at the end."""
    devs = {}

    def factory(spec):
        devs[spec.role] = ScriptedDevice(spec, ["miss", "ok", "over", "ok"] if spec.role == "hammer"
                                         else ["ok"])
        return devs[spec.role]

    with RunStore(tmp_path / "s.h5") as s:
        summary = AcquisitionSession(None, "cfrp", s, device_factory=factory).run(2, 1)
        recs = s.shots("hammer")
    assert summary["recorded"] == {"hammer": 2, "wave": 1} and summary["redone"] == 2
    assert devs["hammer"].calls == ["configure"] + ["arm", "read"] * 4 + ["close"]
    assert [r.data["force"][0] for r in recs] == [0.001 * 5, 0.001 * 9]   # reads 2 and 4
    assert all(r.backend == "scripted" for r in recs)
