"""Issue 15: no silent data loss, the exit-code contract, atomic writes.

Every kill here waits on an event (a line the child prints at the moment of interest),
never on a sleep budget.
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

from drivers.protocol import ChannelConfig, Record, Timing, Trigger
from labid.base import atomic
from labid.cli import main as cli
from labid.base.errors import UserError
from labid.base.jsonio import to_jsonable
from labid.store import RunStore, WriterLock
from labid.store.lock import lock_path

ROOT = Path(__file__).resolve().parents[2]
CH = (ChannelConfig("force", "force", "ai0", sensitivity=2.25e-3),
      ChannelConfig("acc1", "accelerometer", "ai1", sensitivity=1.02e-3, x=0.02, y=0.03))


def record(i: int, n: int = 256) -> Record:
    rng = np.random.default_rng(i)
    return Record(data={c.name: rng.standard_normal(n) for c in CH}, channels=CH,
                  timing=Timing(10_000.0, n, 16), trigger=Trigger("force", 0.02, "rising"),
                  overload={}, timestamp=1.7e9 + i, backend="mock", meta={"i": i})


def small_run(path: Path, shots: int = 3, result: dict | None = None) -> Path:
    with RunStore(path) as st:
        st.write_config('name = "x"\n', "")
        for i in range(shots):
            st.append_shot(record(i), "hammer")
        if result is not None:
            st.write_result("analysis", result)
    return path


def child(code: str, *args: str, env: dict | None = None) -> subprocess.Popen:
    """A Python child with this tree first on its path; its stdout is the event channel."""
    full = f"import sys; sys.path.insert(0, {str(ROOT)!r})\n" + textwrap.dedent(code)
    return subprocess.Popen([sys.executable, "-c", full, *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})})


def one_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def plain(x):
    """A result as plain JSON values (arrays as lists), for comparing."""
    return json.loads(json.dumps(to_jsonable(x)))


def siblings(path: Path) -> set[str]:
    return {p.name for p in path.parent.iterdir()}


def temps(path: Path, suffix: str) -> set[str]:
    """The temporary files beside ``path`` a writer made (``.NAME.XXXXXXXX<suffix>``, mkstemp)."""
    return {n for n in siblings(path) if n.startswith(f".{path.name}.") and n.endswith(suffix)}


# ------------------------------------------------------------------ one writer at a time
HOLDER = """
from labid.store import RunStore
st = RunStore(sys.argv[1])
print("holding", flush=True)
for line in sys.stdin:
    if line.strip() == "append":
        from tests.integration.test_reliability import record
        print(st.append_shot(record(100), "hammer"), flush=True)
    else:
        break
st.close()
print("closed", flush=True)
"""


def test_a_second_writer_is_refused_in_one_line_naming_the_holder(tmp_path, capsys):
    p = small_run(tmp_path / "run.h5")
    proc = child(HOLDER, str(p))
    try:
        assert proc.stdout.readline().strip() == "holding"
        with pytest.raises(UserError, match=rf"PID {proc.pid} on host"):
            RunStore(p, "a")
        assert cli.main(["analyze", str(p), "-q"]) == 2
        line = one_line(capsys.readouterr().err)
        assert f"PID {proc.pid}" in line and "one writer at a time" in line
        assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(p), "--hits", "1",
                         "--waves", "0", "-q"]) == 2
        assert f"PID {proc.pid}" in one_line(capsys.readouterr().err)
        with RunStore(p, "r") as st:              # readers are welcome, and never repair
            assert st.n_shots("hammer") == 3
        # the first writer's later shot lands in the file everybody sees
        proc.stdin.write("append\n")
        proc.stdin.flush()
        assert proc.stdout.readline().strip() == "hammer_0004"
        proc.stdin.write("close\n")
        proc.stdin.flush()
        assert proc.stdout.readline().strip() == "closed"
    finally:
        proc.kill()
        proc.wait()
    with RunStore(p, "r") as st:
        assert [r.meta["i"] for r in st.shots("hammer")] == [0, 1, 2, 100]
    assert not lock_path(p).exists()


def test_the_lock_dies_with_its_holder(tmp_path):
    """SIGKILL frees the lock (the kernel drops a flock): no stale lock after a crash."""
    p = small_run(tmp_path / "run.h5")
    proc = child(HOLDER, str(p))
    assert proc.stdout.readline().strip() == "holding"
    proc.kill()
    proc.wait()
    with RunStore(p) as st:                       # repaired if needed, then appended to
        assert st.append_shot(record(5), "hammer") == "hammer_0004"
    assert siblings(p) == {"run.h5"}


def test_lock_is_reentrant_within_one_process_and_released(tmp_path):
    p = tmp_path / "run.h5"
    with WriterLock(p):
        with RunStore(p) as st:
            st.append_shot(record(0), "hammer")
        assert lock_path(p).exists()
    assert not lock_path(p).exists()


def flagged_run(path):
    """A run left flagged by a writer killed outside SWMR mode (3 shots, a result)."""
    p = small_run(path, result={"f": [1.0, 2.0]})
    proc = child("""
        from labid.store import RunStore
        st = RunStore(sys.argv[1])
        st.write_config_text("note", "x")          # normal mode: the flags are set
        print("ready", flush=True); sys.stdin.readline()
    """, str(p))
    assert proc.stdout.readline().strip() == "ready"
    proc.kill()
    proc.wait()
    with pytest.raises(OSError, match="consistency flags"):
        h5py.File(p, "r")
    return p


def test_a_reader_never_writes_copies_or_repairs(tmp_path):
    """A file left flagged by a writer killed outside SWMR mode is read as it is."""
    p = flagged_run(tmp_path / "run.h5")
    before = (p.stat().st_ino, p.stat().st_mtime_ns, p.read_bytes())
    names = siblings(p)
    with RunStore(p, "r") as st:
        assert st.n_shots() == 3 and st.read_result("analysis") == {"f": [1.0, 2.0]}
        assert siblings(p) == names                # no copy made while reading
    assert (p.stat().st_ino, p.stat().st_mtime_ns, p.read_bytes()) == before


# ------------------------------------------------------------------ crash-safe results
KILL_WHILE_WRITING = """
import labid.store.tree as tree
orig, calls = tree.write_tree, []

def hooked(g, data):
    calls.append(1)
    if len(calls) == 3 and g.file.filename.endswith(".results"):
        g.file.flush()                      # half the new results are on disk
        print("writing", flush=True)
        sys.stdin.readline()                # SIGKILL arrives here
    return orig(g, data)

tree.write_tree = hooked
{body}
"""


def _kill_when_writing(body: str, *args: str) -> None:
    proc = child(KILL_WHILE_WRITING.format(body=textwrap.dedent(body)), *args)
    try:
        line = proc.stdout.readline().strip()
        assert line == "writing", proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL


@pytest.mark.parametrize("trial", range(3))
def test_sigkill_while_results_are_written_keeps_the_earlier_results(tmp_path, trial):
    old = {"peaks": {"frequency_hz": np.arange(1.0, 40.0)}, "note": f"trial {trial}",
           "nested": {"a": {"b": [1, 2, 3]}}}
    p = small_run(tmp_path / "run.h5", result=old)
    with RunStore(p, "r") as st:
        expected = st.read_result("analysis")
    _kill_when_writing("""
        from labid.store import RunStore
        with RunStore(sys.argv[1]) as st:
            st.write_result("analysis", {"peaks": {"frequency_hz": list(range(999))}, "x": {"y": {"z": 1}}})
    """, str(p))
    with RunStore(p, "r") as st:                  # the earlier results, whole
        assert st.read_result("analysis") == expected
    assert temps(p, ".results")                   # the killed writer's copy, never the run
    with RunStore(p) as st:                       # the next writer clears it, and writes
        st.write_result("analysis", {"v": 2})
    assert siblings(p) == {"run.h5"}
    with RunStore(p, "r") as st:
        assert st.read_result("analysis") == {"v": 2}


@pytest.fixture(scope="module")
def analysed_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("analysed")
    run = d / "run.h5"
    assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "2",
                     "--waves", "0", "--quiet"]) == 0
    assert cli.main(["analyze", str(run), "--quiet"]) == 0
    return run


def test_sigkill_during_analyze_and_identify_writes_keeps_earlier_results(analysed_run, tmp_path):
    p = tmp_path / "run.h5"
    shutil.copyfile(analysed_run, p)
    with RunStore(p, "r") as st:
        before = plain(st.read_result("analysis"))
    _kill_when_writing("""
        from labid.cli.main import main
        sys.exit(main(["analyze", sys.argv[1], "--quiet", "--out", sys.argv[2]]))
    """, str(p), str(tmp_path / "again.features.json"))
    with RunStore(p, "r") as st:
        assert plain(st.read_result("analysis")) == before
    again = tmp_path / "again.features.json"
    assert not again.exists() or json.loads(again.read_text())   # never half a JSON
    # identify stores its result through services.store_for_features: killed there too
    feats = tmp_path / "run.features.json"
    shutil.copyfile(analysed_run.with_name("run.features.json"), feats)
    _kill_when_writing("""
        from labid import services
        services.store_for_features(sys.argv[1], "identification", {"parameters": {"E1": {"value": 1.0}}})
    """, str(feats))
    with RunStore(p, "r") as st:
        assert plain(st.read_result("analysis")) == before
        assert "identification" not in st.result_names()
    assert cli.main(["report", str(p), "--out", str(tmp_path / "r.html"), "--quiet"]) == 0


# ------------------------------------------------------------------ atomic outputs
def test_atomic_write_leaves_the_old_file_when_the_rename_fails(tmp_path, monkeypatch):
    out = tmp_path / "f.json"
    out.write_text("old")

    def no_space(src, dst):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(atomic.os, "replace", no_space)
    with pytest.raises(UserError, match="No space left on device") as ei:
        atomic.write_text(out, "new")
    assert str(out) in str(ei.value)
    assert out.read_text() == "old" and siblings(out) == {"f.json"}


def test_atomic_outputs_get_the_permissions_of_a_plain_write(tmp_path):
    """mkstemp makes its file 0600; the published file is 0666 less the umask, as open() gives."""
    atomic.write_text(tmp_path / "a.txt", "x")
    (tmp_path / "b.txt").write_text("x")
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == (tmp_path / "b.txt").stat().st_mode & 0o777


def test_run_files_keep_the_permissions_of_a_plain_write(tmp_path):
    """A run created (a temporary renamed), its results stored (a copy renamed over it) and a
    repair keep the mode a plain file gets, never mkstemp's 0600."""
    (tmp_path / "plain").write_text("x")
    mode = (tmp_path / "plain").stat().st_mode & 0o777
    p = small_run(tmp_path / "run.h5", result={"x": 1.0})
    assert p.stat().st_mode & 0o777 == mode
    os.chmod(p, 0o640)
    with RunStore(p) as st:
        st.write_result("analysis", {"x": 2.0})
    assert p.stat().st_mode & 0o777 == 0o640


def test_json_output_is_replaced_atomically(tmp_path):
    out = tmp_path / "m.json"
    out.write_text("previous")
    ino = out.stat().st_ino
    assert cli.main(["modes", "aluminium", "--n", "2", "--mesh", "4x4", "--json", str(out), "-q"]) == 0
    assert json.loads(out.read_text())["frequencies_hz"] and out.stat().st_ino != ino
    assert siblings(out) == {"m.json"}


# ------------------------------------------------------------------ the door
def damage(path: Path, how: str) -> None:
    if how == "bitflips":
        data = bytearray(path.read_bytes())
        rng = np.random.default_rng(len(data))
        for i in rng.integers(0, len(data), 200):
            data[i] ^= 0xFF
        path.write_bytes(bytes(data))
        return
    if how == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 3])
        return
    if how == "not_hdf5":
        path.write_bytes(b"hello, I am not HDF5\n" * 10)
        return
    with h5py.File(path, "a") as f:
        g = f["shots/hammer"]
        if how == "schema_one":
            f.attrs["labid_schema"] = "one"
        elif how == "no_shots":
            del f["shots"]
        elif how == "no_committed":
            del g["committed"]
        elif how == "bad_json_attr":
            g.attrs["channels"] = "{not json"
        elif how == "rate_zero":
            g.attrs["rate_hz"] = 0.0
        elif how == "rate_nan":
            g.attrs["rate_hz"] = float("nan")
        elif how == "short_table":
            g["acc1"].resize(1, axis=0)
        elif how == "channels_not_list":
            g.attrs["channels"] = json.dumps({"a": 1})


DAMAGES = ("bitflips", "truncated", "not_hdf5", "schema_one", "no_shots", "no_committed",
           "bad_json_attr", "rate_zero", "rate_nan", "short_table", "channels_not_list")


@pytest.mark.parametrize("how", DAMAGES)
def test_damaged_run_files_are_one_line_exit_2(tmp_path, how, capsys):
    p = small_run(tmp_path / "run.h5", result={"x": 1.0})
    damage(p, how)
    for argv in (["analyze", str(p)], ["report", str(p), "--out", str(tmp_path / "r.html")],
                 ["export", str(p), "--csv", str(tmp_path / "csv")]):
        rc = cli.main([*argv, "-q"])
        err = capsys.readouterr().err
        if how == "bitflips" and rc == 0:          # flips that missed everything read
            continue
        assert rc == 2, (argv, err)
        assert str(p) in one_line(err)


def test_internal_failure_is_exit_1_with_the_traceback_in_a_file(tmp_path, monkeypatch, capsys):
    import labid.cli.modes as cm

    def boom(args):
        raise ZeroDivisionError("deliberate")
    monkeypatch.setattr(cm, "run", boom)
    monkeypatch.setenv("LABID_CRASH_DIR", str(tmp_path))
    monkeypatch.delenv("LABID_DEBUG", raising=False)
    assert cli.main(["modes", "cfrp"]) == 1
    line = one_line(capsys.readouterr().err)
    where = Path(line.split("traceback in ")[1].split(" (exit 1)")[0])
    assert where.parent == tmp_path and "ZeroDivisionError: deliberate" in where.read_text()
    monkeypatch.setenv("LABID_DEBUG", "1")
    assert cli.main(["modes", "cfrp"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_engine_errors_on_unphysical_input_are_exit_2(monkeypatch, capsys):
    import labid.cli.modes as cm
    from engine.plate import FEError

    def fe(args):
        raise FEError("mesh cannot hold a 3.3e8 m plate")
    monkeypatch.setattr(cm, "run", fe)
    assert cli.main(["modes", "cfrp"]) == 2
    assert "3.3e8 m plate" in one_line(capsys.readouterr().err)


SIGNALLED = """
import signal, labid.cli.modes as cm

def waits(args):
    print("running", flush=True)
    signal.pause()
cm.run = waits
from labid.cli.main import main
sys.exit(main(["modes", "cfrp"]))
"""


@pytest.mark.parametrize("sig, rc, word", [(signal.SIGTERM, 143, "terminated"),
                                           (signal.SIGINT, 130, "interrupted")])
def test_sigterm_is_handled_like_ctrl_c(sig, rc, word):
    proc = child(SIGNALLED)
    assert proc.stdout.readline().strip() == "running"
    proc.send_signal(sig)
    _, err = proc.communicate()
    assert proc.returncode == rc
    assert word in one_line(err)


def test_gui_without_a_display_is_one_line_exit_2(capsys):
    from labid.cli.gui import check_display
    with pytest.raises(UserError, match="QT_QPA_PLATFORM=offscreen"):
        check_display({}, "linux")
    check_display({"DISPLAY": ":0"}, "linux")
    check_display({"QT_QPA_PLATFORM": "offscreen"}, "linux")
    proc = subprocess.run([sys.executable, "-m", "labid.cli.main", "gui"], capture_output=True, text=True,
                          env={k: v for k, v in os.environ.items()
                               if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
                          | {"PYTHONPATH": str(ROOT)})
    assert proc.returncode == 2
    assert "offscreen" in one_line(proc.stderr)


# ------------------------------------------------------------------ full disk, read-only directory
@pytest.fixture
def tiny_fs(tmp_path):
    """A 2 MiB tmpfs (skipped where mounting is impossible: not root, no CAP_SYS_ADMIN)."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    if shutil.which("mount") is None or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def fill(d: Path) -> None:
    with open(d / "filler", "wb") as fh:
        try:
            while True:
                fh.write(b"\0" * 65536)
                fh.flush()
        except OSError as e:
            assert e.errno == errno.ENOSPC


def test_full_disk_is_one_line_and_keeps_the_run(tiny_fs, capsys):
    p = small_run(tiny_fs / "run.h5", shots=2, result={"x": 1.0})
    fill(tiny_fs)
    size = p.stat().st_size
    for argv in (["modes", "aluminium", "--n", "2", "--mesh", "4x4", "--json", str(tiny_fs / "m.json")],
                 ["report", str(p), "--out", str(tiny_fs / "r.html")],
                 ["acquire", "--specimen", "cfrp", "--out", str(p), "--hits", "1", "--waves", "0"]):
        rc = cli.main([*argv, "-q"])
        err = capsys.readouterr().err
        assert rc == 2, err
        one_line(err)
    # results to a full disk: refused, the run file unchanged and readable
    with pytest.raises(UserError, match="the run file is unchanged"):
        with RunStore(p) as st:
            st.write_result("analysis", {"big": np.zeros(200_000)})
    with RunStore(p, "r") as st:
        assert st.n_shots() == 2 and st.read_result("analysis") == {"x": 1.0}
    assert p.stat().st_size == size
    assert siblings(p) == {"run.h5", "filler"}


def test_read_only_directory_reads_and_refuses_writes_in_one_line(tiny_fs, capsys):
    p = small_run(tiny_fs / "run.h5", shots=2, result={"x": 1.0})
    assert subprocess.run(["mount", "-o", "remount,ro", str(tiny_fs)], capture_output=True).returncode == 0
    with RunStore(p, "r") as st:
        assert st.n_shots() == 2
    for argv in (["analyze", str(p)], ["report", str(p)],
                 ["acquire", "--specimen", "cfrp", "--out", str(p), "--hits", "1", "--waves", "0"],
                 ["modes", "aluminium", "--n", "2", "--json", str(tiny_fs / "m.json")]):
        rc = cli.main([*argv, "-q"])
        err = capsys.readouterr().err
        assert rc == 2, (argv, err)
        one_line(err)


# ------------------------------------------------------------------ drivers
def _nidaq():
    pytest.importorskip("nidaqmx")
    from tests.unit.drivers.test_nidaq import E, FakeRig, configured
    return E, FakeRig, configured


def test_daqmx_buffer_overflow_says_what_happened_and_what_to_do():
    E, FakeRig, configured = _nidaq()
    from drivers.nidaq import DaqmxError
    rig = FakeRig()
    dev = configured(rig)
    rig.fail["read"] = E.DaqReadError("The application is not able to keep up with the hardware "
                                      "acquisition.\nIncreasing the buffer size...", -200279, 0)
    dev.arm()
    with pytest.raises(DaqmxError) as ei:
        dev.read(timeout_s=1.0)
    msg = str(ei.value)
    assert "\n" not in msg and "overflow" in msg and "sample rate" in msg and "-200279" in msg
    assert ei.value.code == -200279


def test_a_device_vanishing_mid_read_is_one_line_and_keeps_earlier_shots(tmp_path):
    """Shot 1 is read; the chassis is unplugged during shot 2 (DAQmx -201003, then
    every call fails). The error names the device; the shot read before is in the run."""
    E, FakeRig, configured = _nidaq()
    from drivers.nidaq import DeviceNotFound
    rig = FakeRig()
    dev = configured(rig)
    dev.arm()
    first = dev.read(timeout_s=1.0)
    p = tmp_path / "run.h5"
    with RunStore(p) as st:
        st.append_shot(first, "hammer")
        gone = E.DaqReadError("Device cannot be accessed.\nDevice: PXI1Slot2", -201003, 0)
        rig.fail["read"] = gone
        dev.arm()
        with pytest.raises(DeviceNotFound) as ei:
            dev.read(timeout_s=1.0)
        assert "\n" not in str(ei.value) and "PXI1Slot2" in str(ei.value) and "unplugged" in str(ei.value)
        rig.fail["start"] = gone               # nothing answers any more: re-arming fails too
        with pytest.raises(DeviceNotFound):
            dev.arm()
        dev.close()                             # releasing a vanished device does not raise
    with RunStore(p, "r") as st:
        assert st.n_shots("hammer") == 1


# ------------------------------------------------------------------ errors at the door (issue 17)
def _spec(**change) -> dict:
    import tomllib
    from importlib import resources
    doc = tomllib.loads(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text())
    for path, value in change.items():
        *head, last = path.split("__")
        node = doc
        for k in head:
            node = node[k]
        node[last] = value
    return doc


def test_unknown_specimen_keys_are_named():
    from labid.inputs.specimen import specimen_from_dict
    for path, key in (("plate__lenght", "plate.lenght"), ("materials__T300__E_1", "materials.T300.E_1"),
                      ("layup__angle_deg", "layup.angle_deg"), ("thickness", "thickness")):
        with pytest.raises(UserError) as ei:
            specimen_from_dict(_spec(**{path: 1.0}), "s.toml")
        assert ei.value.key == key and "unknown key" in str(ei.value)


def test_optional_uncertainty_and_report_tables_are_accepted_and_typed():
    from labid.inputs.specimen import specimen_from_dict
    s = specimen_from_dict(_spec(uncertainty={"thickness": 2e-5, "density": 5.0, "path_length": 1e-3},
                                 report={"lab": "L", "revision": 2, "temperature_c": 22.5}), "s.toml")
    assert s.length == 0.33
    with pytest.raises(UserError, match="uncertainty.thickness"):
        specimen_from_dict(_spec(uncertainty={"thickness": -1.0}), "s.toml")
    with pytest.raises(UserError, match="report.lab"):
        specimen_from_dict(_spec(report={"lab": ["x"]}), "s.toml")


def test_a_modulus_in_gpa_typed_as_pa_is_named():
    from labid.workflows.identification.estimation import parse_assignments
    from labid.inputs.specimen import specimen_from_dict
    with pytest.raises(UserError, match="GPa typed as Pa") as ei:
        specimen_from_dict(_spec(materials__T300__E1=136.7), "s.toml")
    assert ei.value.key == "materials.T300.E1" and "1.367e+11" in str(ei.value)
    with pytest.raises(UserError, match="GPa typed as Pa"):
        parse_assignments("E1=136.7")
    assert parse_assignments("E1=136.7e9,nu12=0.3") == {"E1": 136.7e9, "nu12": 0.3}


@pytest.mark.parametrize("change, key", [
    ({"plate__width": 3.3e8}, "plate.width"), ({"materials__T300__density": 1e30}, "materials.T300.density"),
    ({"layup__angles_deg": [1e300]}, "layup.angles_deg[0]"), ({"layup__ply_thickness": float("inf")},
                                                              "layup.ply_thickness"),
    ({"layup__angles_deg": []}, "layup.angles_deg"), ({"layup__material": ["a"]}, "layup.material")])
def test_absurd_specimens_are_refused_with_the_key(change, key):
    from labid.inputs.specimen import specimen_from_dict
    with pytest.raises(UserError) as ei:
        specimen_from_dict(_spec(**change), "s.toml")
    assert ei.value.key == key


def test_features_mode_index_round_trips_and_is_checked(tmp_path):
    from labid.inputs.features import features_document, parse_features, validate_features
    doc = {"specimen": "aluminium", "modal": {"frequencies_hz": [20.0, 30.0, 45.0], "mode_index": [1, None, 3]},
           "waves": [{"mode": "A0", "frequency_hz": [5e3], "group_velocity_m_s": [800.0], "dropped": {"weak": 2}}],
           "analysis": {"dropped": {"x": 1}, "anything": [1]}}
    pf = parse_features(doc)
    assert pf.features.mode_index == (1, None, 3)
    assert features_document(pf.features, "aluminium")["modal"]["mode_index"] == [1, None, 3]
    assert parse_features({**doc, "modal": {"frequencies_hz": [20.0]}}).features.mode_index is None
    for bad in ([-1, 1, 2], [1, 2], [1.5, 2, 3], ["1", 2, 3]):
        with pytest.raises(UserError, match="modal.mode_index"):
            validate_features({**doc, "modal": {"frequencies_hz": [20.0, 30.0, 45.0], "mode_index": bad}})
    with pytest.raises(UserError) as ei:
        validate_features({**doc, "modal": {"frequencies_hz": [20.0], "sigmahz": [1.0]}}, "f.json")
    assert ei.value.key == "modal.sigmahz"


def test_features_specimen_path_only_regular_small_files(tmp_path):
    from labid.inputs.features import MAX_SPECIMEN_BYTES, specimen_of
    secret = tmp_path / "secret.toml"
    secret.write_text('password = "hunter2"\n')
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (MAX_SPECIMEN_BYTES + 1))
    for path, words in (("/dev/zero", "not a regular file"), (str(tmp_path), "not a regular file"),
                        (str(big), "at most"), (str(secret), "unknown key")):
        with pytest.raises(UserError, match=words) as ei:
            specimen_of({"specimen": path}, tmp_path, "f.json")
        assert "hunter2" not in str(ei.value)


def test_stray_temporary_files_of_a_killed_writer_are_removed_by_the_next_writer_only(tmp_path):
    p = small_run(tmp_path / "run.h5")
    for suffix in (".repair", ".new", ".results", ".unlocked"):
        (tmp_path / f"run.h5{suffix}").write_bytes(b"half")            # an earlier version's names
        (tmp_path / f".run.h5.k3_9abcd{suffix}").write_bytes(b"half")  # mkstemp's
    keep = {"run.h5x.results", ".run.h5.x.h5.abcdefgh.results", ".run.h5.abcdefgh.results.bak"}
    for name in keep:                                                  # not the temporaries of run.h5
        (tmp_path / name).write_bytes(b"other")
    with RunStore(p, "r") as st:                   # a reader leaves them (it never writes)
        assert st.n_shots() == 3
    assert len(siblings(p)) == 12
    with RunStore(p) as st:
        st.append_shot(record(9), "hammer")
    assert siblings(p) == {"run.h5"} | keep


@pytest.mark.parametrize("argv", [["modes", "/dev/zero"], ["identify", "/dev/zero"],
                                  ["acquire", "--rig", "/dev/zero", "--specimen", "cfrp", "--out", "X"],
                                  ["modes", "a\0b"]])
def test_device_files_and_nul_paths_are_refused_without_reading(argv, tmp_path, capsys):
    """/dev/zero read to the end exhausted the memory (the process was killed)."""
    argv = [str(tmp_path / "r.h5") if a == "X" else a for a in argv]
    assert cli.main([*argv, "-q"]) == 2
    line = one_line(capsys.readouterr().err)
    assert "not a regular file" in line or "NUL" in line
    assert not (tmp_path / "r.h5").exists()


def test_a_refused_acquire_never_deletes_the_new_file_of_the_writer_holding_it(tmp_path, capsys):
    """Two sessions started on one new file: the second is refused and must not discard
    the first one's (still empty) run file as its own."""
    p = tmp_path / "new.h5"
    proc = child("""
        from labid.store import RunStore
        st = RunStore(sys.argv[1])                 # created, no shot yet
        print("holding", flush=True); sys.stdin.readline()
    """, str(p))
    try:
        assert proc.stdout.readline().strip() == "holding"
        assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(p), "--hits", "1",
                         "--waves", "0", "-q"]) == 2
        assert "one writer at a time" in one_line(capsys.readouterr().err)
        # what a refused session that saw no file at its start calls: it must keep the holder's file
        from labid import services
        assert services.discard_empty_run(p) is False
        assert p.exists()
    finally:
        proc.kill()
        proc.wait()


@pytest.mark.parametrize("how", ["truncate", "flip", "rate_hz=0", "channels={bad", "labid_schema=one",
                                 "samples=99999999999"])
def test_the_panel_opens_a_damaged_run_without_an_uncaught_exception(tmp_path, how, monkeypatch):
    """On main, 16 of 24 such files raised out of MainWindow (MemoryError of 745 GiB among them)."""
    pytest.importorskip("PySide6")
    from tests.fuzzcases import damaged_copy
    base = small_run(tmp_path / "base.h5", shots=2)
    assert panel_exceptions(damaged_copy(base, tmp_path / "d.h5", how, 3), monkeypatch) == []


def panel_exceptions(run: Path, monkeypatch) -> list:
    """The uncaught exceptions (sys.excepthook calls) of opening ``run`` in the panel and closing it."""
    from PySide6.QtWidgets import QApplication

    from labid.gui.main_window import MainWindow
    app = QApplication.instance() or QApplication(["labid-test"])
    hooked = []
    monkeypatch.setattr(sys, "excepthook", lambda *a: hooked.append(a))
    w = MainWindow(str(run))
    app.processEvents()
    w.close()
    w.deleteLater()
    app.processEvents()
    return hooked


def test_a_reader_leaving_the_pipe_loses_no_result(tmp_path, monkeypatch, capsys):
    """``labid ... | head``: a broken stdout pipe drops the console text, not the results:
    the command still writes its --json file and exits 0, with no crash report."""
    import io

    class Gone(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def fileno(self):
            raise io.UnsupportedOperation("no descriptor")

    monkeypatch.setattr(sys, "stdout", Gone())
    out = tmp_path / "disp.json"
    assert cli.main(["dispersion", "cfrp", "--fmax", "50000", "--n", "20", "--json", str(out)]) == 0
    assert json.loads(out.read_text())
    assert "internal error" not in capsys.readouterr().err
