"""Issue 27: the last faults, one test (or more) per row of the issue's table, and the import/
export friction of issue 26 item 8.

Every case is an observable behaviour from outside: an exit code, the stderr lines, the bytes
of a file planted or kept. Disk full is a file-size limit (``RLIMIT_FSIZE``, what ``ulimit -f``
sets) in a child process, so it runs everywhere and never skips. Kills and signals wait on
events (a line the child prints at the moment of interest), never on a sleep; where the code
before the fix could run for minutes, the child's CPU time is bounded (``RLIMIT_CPU``), not
its wall time.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from labid.cli import main as cli
from labid.store import RunStore
from labid.store.lock import lock_path
from tests.integration.test_reliability import ROOT, child, one_line, panel_exceptions

LIMITED = """
import resource, signal, sys
sys.path.insert(0, {root!r})
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)        # as the brief says; labid ignores it itself too
fsize, cpu = int(sys.argv[1]), int(sys.argv[2])
if fsize:
    resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
if cpu:
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))
from labid.cli.main import main
sys.argv = ["labid", *sys.argv[3:]]
sys.exit(main())
"""


def labid_limited(argv: list, fsize: int = 0, cpu: int = 0, env: dict | None = None) -> subprocess.CompletedProcess:
    """``labid ARGV`` in a child whose files may not grow past ``fsize`` bytes (``ulimit -f``)
    and whose CPU time is bounded to ``cpu`` s (0: no limit)."""
    code = LIMITED.format(root=str(ROOT))
    return subprocess.run([sys.executable, "-c", code, str(fsize), str(cpu), *map(str, argv)],
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})})


def error_lines(err: str) -> list[str]:
    """stderr lines that are not warnings (a warning line may precede the one error line)."""
    return [ln for ln in err.strip().splitlines() if ln.strip() and "warning" not in ln]


def strays(d: Path) -> set[str]:
    """Temporary files left in ``d`` (mkstemp's ``.NAME.XXXXXXXX.*`` or the fixed names of before)."""
    return {p.name for p in d.iterdir() if p.name.startswith(".") or p.name.endswith(
        (".tmp", ".new", ".repair", ".results", ".unlocked", ".lock"))}


@pytest.fixture(scope="module")
def analysed(tmp_path_factory) -> Path:
    """One hammer hit on the simulated rig (cfrp), analysed: ``run.h5`` and ``run.features.json``."""
    d = tmp_path_factory.mktemp("faults")
    run = d / "run.h5"
    assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "1", "--waves", "0", "-q"]) == 0
    assert cli.main(["analyze", str(run), "-q"]) == 0
    return run


def copy_run(src: Path, d: Path, name: str = "run.h5") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    dst = d / name
    shutil.copyfile(src, dst)
    return dst


@pytest.fixture(scope="module")
def modal_features(tmp_path_factory) -> Path:
    """A cheap features file (aluminium, four modal peaks 1 % above the nominal plate's)."""
    d = tmp_path_factory.mktemp("feats")
    m = d / "m.json"
    assert cli.main(["modes", "aluminium", "--n", "4", "--mesh", "6x6", "--json", str(m), "-q"]) == 0
    f = [round(1.01 * x, 4) for x in json.loads(m.read_text())["frequencies_hz"]]
    p = d / "f.json"
    p.write_text(json.dumps({"specimen": "aluminium", "modal": {"frequencies_hz": f}}))
    return p


# ------------------------------------------------------------------ 1. disk full (ulimit -f)
def test_disk_full_during_acquire_is_one_line_and_keeps_every_committed_shot(analysed, tmp_path):
    """Was: killed by signal 11 (segfault) after a traceback."""
    run = copy_run(analysed, tmp_path)
    size = run.stat().st_size
    p = labid_limited(["acquire", "--specimen", "cfrp", "--out", run, "--hits", "12", "--waves", "0", "-q"],
                      fsize=size + 1_500_000)
    assert p.returncode == 2, p.stderr[-2000:]
    line = one_line(p.stderr)
    assert str(run) in line and "File too large" in line
    with RunStore(run, "r") as st:                 # every committed shot, readable
        n = st.n_shots("hammer")
        assert 1 < n < 13 and len(st.shots("hammer")) == n
        assert "analysis" in st.result_names()
    assert strays(tmp_path) == set()


def test_disk_full_during_analyze_keeps_the_run_and_leaves_no_part(analysed, tmp_path):
    run = copy_run(analysed, tmp_path)
    before = run.read_bytes()
    p = labid_limited(["analyze", run, "--out", tmp_path / "new.features.json", "-q"], fsize=len(before) // 2)
    assert p.returncode == 2, p.stderr[-2000:]
    assert "File too large" in one_line(p.stderr)
    assert run.read_bytes() == before
    out = tmp_path / "new.features.json"
    assert not out.exists() or json.loads(out.read_text())        # whole or absent, never a part
    assert strays(tmp_path) == set()


def test_disk_full_during_identify_json_leaves_no_part(modal_features, tmp_path):
    out = tmp_path / "id.json"
    out.write_text('{"old": true}')
    p = labid_limited(["identify", modal_features, "--params", "E", "--json", out, "-q"], fsize=2000)
    assert p.returncode == 2, p.stderr[-2000:]
    assert "File too large" in one_line(p.stderr)
    assert json.loads(out.read_text()) == {"old": True}
    assert strays(tmp_path) == set()


def test_disk_full_during_report_leaves_no_part(analysed, tmp_path):
    run = copy_run(analysed, tmp_path)
    p = labid_limited(["report", run, "--out", tmp_path / "r.html", "-q"], fsize=20_000)
    assert p.returncode == 2, p.stderr[-2000:]
    assert "File too large" in one_line(p.stderr)
    assert not (tmp_path / "r.html").exists() and strays(tmp_path) == set()


@pytest.mark.parametrize("what", ["--uff", "--csv"])
def test_disk_full_during_export_leaves_no_part(analysed, tmp_path, what):
    """Was: --uff exit 1 with a partial UFF at the final path; --csv a 0-byte CSV."""
    run = copy_run(analysed, tmp_path)
    target = tmp_path / ("run.uff" if what == "--uff" else "csv")
    p = labid_limited(["export", run, what, target, "-q"], fsize=300)
    assert p.returncode == 2, p.stderr[-2000:]
    assert "File too large" in one_line(p.stderr)
    if what == "--uff":
        assert not target.exists()
    else:
        assert not target.exists() or list(target.iterdir()) == []
    assert strays(tmp_path) == set()


# ------------------------------------------------------------------ 2. atomic outputs under a kill
KILL_IN_UFF = """
import pyuff
orig, n = pyuff.UFF._write_set, [0]

def write_set(self, dset, mode="add", force_double=True):
    out = orig(self, dset, mode, force_double)
    n[0] += 1
    if n[0] == 5:                     # five data sets are on disk
        print("writing", flush=True)
        sys.stdin.readline()          # SIGKILL arrives here
    return out

pyuff.UFF._write_set = write_set
from labid.cli.main import main
sys.exit(main(["export", sys.argv[1], "--uff", sys.argv[2], "-q"]))
"""


def test_sigkill_during_export_uff_leaves_the_old_file_whole(analysed, tmp_path):
    """Was: a half-written run.uff (5 of 70 data sets) at the final path."""
    run = copy_run(analysed, tmp_path)
    uff = tmp_path / "run.uff"
    uff.write_text("the previous export\n")
    proc = child(KILL_IN_UFF, str(run), str(uff))
    try:
        assert proc.stdout.readline().strip() == "writing", proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()
    assert uff.read_text() == "the previous export\n"


# ------------------------------------------------------------------ 3. planted links
@pytest.fixture
def victim(tmp_path) -> Path:
    v = tmp_path / "elsewhere" / "victim.txt"
    v.parent.mkdir()
    v.write_text("precious\n")
    return v


def test_a_lock_file_planted_as_a_symlink_is_never_written_through(analysed, tmp_path, victim, capsys):
    """Was: the file behind the symlink overwritten with 'PID ... on host ...'."""
    run = copy_run(analysed, tmp_path / "d")
    os.symlink(victim, lock_path(run))
    assert cli.main(["analyze", str(run), "-q"]) == 2
    assert "symbolic link" in one_line(capsys.readouterr().err)
    assert victim.read_text() == "precious\n"


def test_a_lock_file_planted_as_a_hard_link_is_never_written_through(analysed, tmp_path, victim, capsys):
    run = copy_run(analysed, tmp_path / "d")
    os.link(victim, lock_path(run))
    assert cli.main(["analyze", str(run), "-q"]) == 2
    assert "hard link" in one_line(capsys.readouterr().err)
    assert victim.read_text() == "precious\n"


def test_symlinks_at_the_old_predictable_temporary_names_are_never_written_through(analysed, tmp_path, victim,
                                                                                 capsys):
    """Was: the atomic writer's '.NAME.PID.tmp' and the run's 'RUN.h5.results' followed."""
    d = tmp_path / "d"
    run = copy_run(analysed, d)
    out = d / "m.json"
    planted = [d / f".m.json.{os.getpid()}.tmp"] + [run.with_name(run.name + s) for s in
                                                  (".results", ".new", ".repair", ".unlocked")]
    for p in planted:
        os.symlink(victim, p)
    assert cli.main(["modes", "aluminium", "--n", "2", "--mesh", "4x4", "--json", str(out), "-q"]) == 0
    assert json.loads(out.read_text())["frequencies_hz"]
    assert cli.main(["analyze", str(run), "-q"]) == 0        # stores /results/analysis through a copy
    capsys.readouterr()
    assert victim.read_text() == "precious\n"


@pytest.mark.parametrize("output", ["json", "csv", "uff", "html", "png", "features"])
def test_an_output_path_planted_as_a_symlink_is_replaced_never_written_through(analysed, tmp_path, victim,
                                                                              output, capsys):
    """Every file a command writes: the link is replaced by the new file; the file behind
    it keeps its bytes (was: CSV and PNG written through the link)."""
    d = tmp_path / "d"
    run = copy_run(analysed, d)
    target = {"json": d / "m.json", "csv": d / "csv" / "features_modal.csv", "uff": d / "run.uff",
              "html": d / "r.html", "png": d / "disp.png", "features": d / "f.json"}[output]
    target.parent.mkdir(exist_ok=True)
    os.symlink(victim, target)
    argv = {"json": ["modes", "aluminium", "--n", "2", "--mesh", "4x4", "--json", str(target)],
            "csv": ["export", str(run), "--csv", str(target.parent)],
            "uff": ["export", str(run), "--uff", str(target)],
            "html": ["report", str(run), "--out", str(target)],
            "png": ["dispersion", "aluminium", "--fmax", "20000", "--n", "8", "--plot", str(target)],
            "features": ["analyze", str(run), "--out", str(target)]}[output]
    assert cli.main([*argv, "-q"]) == 0, capsys.readouterr().err
    assert victim.read_text() == "precious\n"
    assert target.is_file() and not target.is_symlink()


def test_a_run_path_that_is_a_symlink_is_refused_for_writing(analysed, tmp_path, capsys):
    other = copy_run(analysed, tmp_path / "elsewhere")
    before = other.read_bytes()
    link = tmp_path / "run.h5"
    os.symlink(other, link)
    assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(link), "--hits", "1", "--waves", "0", "-q"]) == 2
    assert "symbolic link" in one_line(capsys.readouterr().err)
    assert other.read_bytes() == before


def test_the_crash_report_is_never_written_through_a_planted_link(tmp_path, victim, monkeypatch, capsys):
    """The traceback file of an internal error: was 'labid-crash-CMD-TIME-PID.txt', predictable."""
    import labid.cli.modes as cm

    def boom(args):
        raise ZeroDivisionError("deliberate")
    monkeypatch.setattr(cm, "run", boom)
    monkeypatch.setenv("LABID_CRASH_DIR", str(tmp_path))
    monkeypatch.delenv("LABID_DEBUG", raising=False)
    now = time.time()
    for dt in range(-1, 4):                        # the names of the next seconds
        stamp = time.strftime("%Y%m%dT%H%M%S", time.localtime(now + dt))
        os.symlink(victim, tmp_path / f"labid-crash-modes-{stamp}-{os.getpid()}.txt")
    assert cli.main(["modes", "cfrp"]) == 1
    where = Path(one_line(capsys.readouterr().err).split("traceback in ")[1].split(" (exit 1)")[0])
    assert "ZeroDivisionError: deliberate" in where.read_text() and not where.is_symlink()
    assert victim.read_text() == "precious\n"


HOLDER = """
from labid.store import RunStore
st = RunStore(sys.argv[1])
print("holding", flush=True)
sys.stdin.readline()
st.close()
"""


def test_two_names_of_one_run_cannot_both_write(analysed, tmp_path, capsys):
    """Was: two analyze through two hard links both succeeded (the lock was per name)."""
    run = copy_run(analysed, tmp_path)
    other = tmp_path / "same.h5"
    os.link(run, other)
    proc = child(HOLDER, str(run))
    try:
        assert proc.stdout.readline().strip() == "holding"
        assert cli.main(["analyze", str(other), "-q"]) == 2
        assert "another writer" in one_line(capsys.readouterr().err)
    finally:
        proc.kill()
        proc.wait()
    assert cli.main(["analyze", str(other), "-q"]) == 0          # the holder gone: writable again


# ------------------------------------------------------------------ 4. the exit-code contract
def default_rig(tmp_path: Path, old: str, new: str) -> Path:
    from labid.inputs.rig import read_rig_text
    text, _ = read_rig_text("default")
    assert old in text
    p = tmp_path / "rig.toml"
    p.write_text(text.replace(old, new, 1))
    return p


@pytest.mark.parametrize("old, new", [('kind = "force"\n', ""),                 # a channel without kind
                                      ('name = "acc1"', 'name = "a/b"'),
                                      ('name = "acc1"', 'name = "committed"'),
                                      ('name = "acc1"', 'name = "timestamp"')])
def test_rig_channel_mistakes_are_one_line_exit_2(tmp_path, old, new, capsys):
    """Was: exit 1 (KeyError) for a channel without kind; a crash for '/', 'committed', 'timestamp'."""
    rig = default_rig(tmp_path, old, new)
    out = tmp_path / "r.h5"
    assert cli.main(["acquire", "--rig", str(rig), "--specimen", "cfrp", "--out", str(out), "--hits", "1",
                     "--waves", "0", "-q"]) == 2
    line = one_line(capsys.readouterr().err)
    assert str(rig) in line and "devices.vib" in line
    assert not out.exists()


def garbage_results(run: Path, how: str) -> None:
    with h5py.File(run, "a") as f:
        if how == "dataset":
            f["results/identification"] = 5.0
        elif how == "list_params":
            g = f["results"].create_group("identification")
            g["json"] = json.dumps({"parameters": [1, 2], "fit": "x"})
        elif how == "analysis_list":
            del f["results/analysis"]
            f["results"].create_group("analysis")["json"] = json.dumps([1, 2, 3])
        elif how == "gap_number":
            f["results"].create_group("diagnosis")["json"] = json.dumps({"gap": 3, "effects": {"a": 1}})
        elif how == "features_text":
            del f["results/analysis/features"]
            f["results/analysis"].create_group("features")["json"] = json.dumps({"modal": "x"})
        elif how == "short_column":          # found by the fuzz (session 23): export's IndexError
            feats = json.loads(f["results/analysis/features/json"][()])
            feats["modal"]["confidence"] = feats["modal"]["confidence"][:-1]
            del f["results/analysis/features/json"]
            f["results/analysis/features"]["json"] = json.dumps(feats)


@pytest.mark.parametrize("how", ["dataset", "list_params", "analysis_list", "gap_number", "features_text",
                                 "short_column"])
def test_report_and_export_refuse_garbage_results_in_one_line(analysed, tmp_path, how, capsys):
    """Was: report exit 1 (AttributeError) on a results group holding garbage; export too."""
    run = copy_run(analysed, tmp_path)
    garbage_results(run, how)
    for argv in (["report", str(run), "--out", str(tmp_path / "r.html")],
                 ["export", str(run), "--csv", str(tmp_path / "csv"), "--uff", str(tmp_path / "r.uff")]):
        assert cli.main([*argv, "-q"]) == 2, argv
        line = one_line(capsys.readouterr().err)
        assert str(run) in line and "/results/" in line and "damaged" in line


def test_the_panel_refuses_garbage_results_without_quitting(analysed, tmp_path, monkeypatch):
    pytest.importorskip("PySide6")
    run = copy_run(analysed, tmp_path)
    garbage_results(run, "list_params")
    assert panel_exceptions(run, monkeypatch) == []


def write_csv(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_import_refuses_a_one_row_csv_in_one_line(tmp_path, capsys):
    """Was: exit 1 (LinAlgError), LAPACK's own message on the console."""
    f = write_csv(tmp_path / "one.csv", "time,force [N],acc1 [m/s^2]\n0,1,2\n")
    assert cli.main(["import", str(f), "--rig", "default", "--specimen", "cfrp", "--out",
                     str(tmp_path / "r.h5"), "--map", "force=force,acc1=acc1", "-q"]) == 2
    assert "one.csv" in one_line(capsys.readouterr().err)
    assert not (tmp_path / "r.h5").exists()


IMPORT = ["import", "CSV", "--rig", "default", "--specimen", "cfrp", "--out", "OUT", "--map", "force=force,acc1=acc1"]


@pytest.mark.parametrize("argv", [["analyze", "RUN", "--wavelet", "1e9,1e9"],
                                  [*IMPORT, "--pretrigger", "1000000000000"], [*IMPORT, "--pretrigger", "500"]])
def test_refusals_are_one_line_even_with_progress_shown(analysed, tmp_path, argv, monkeypatch, capsys):
    """Was: exit 2 with two stderr lines (a progress note, then the error), after allocating."""
    monkeypatch.setenv("LABID_PROGRESS", "1")
    csv = write_csv(tmp_path / "three.csv", "time,force [N],acc1 [m/s^2]\n0,1,2\n0.0001,1,2\n0.0002,1,3\n")
    run = copy_run(analysed, tmp_path)
    argv = [{"RUN": str(run), "CSV": str(csv), "OUT": str(tmp_path / "o.h5")}.get(a, a) for a in argv]
    assert cli.main(argv) == 2
    line = one_line(capsys.readouterr().err)
    assert "--wavelet" in line or "pre-trigger" in line or "--pretrigger" in line
    assert not (tmp_path / "o.h5").exists()


def test_an_accelerometer_without_its_mass_is_refused_at_once(tmp_path):
    """Was: identify ran 284 s (90 s CPU; the file intact: ~15 s): the missing mass was read as
    0 kg beside the others' 2 g, the model could not match the measured peaks."""
    doc = {"specimen": "aluminium", "modal": {"frequencies_hz": [10.2, 15.1, 20.3, 27.0]},
           "rig": {"accelerometers": [{"x": 0.02, "y": 0.02, "mass_kg": 0.002}, {"x": 0.2, "y": 0.1}]}}
    f = tmp_path / "f.json"
    f.write_text(json.dumps(doc))
    p = labid_limited(["identify", f, "-q"], cpu=30)
    assert p.returncode == 2, (p.returncode, p.stderr[-500:])
    line = one_line(p.stderr)
    assert "rig.accelerometers[1].mass_kg" in line and "massless" in line


@pytest.mark.parametrize("argv, option, entry", [
    (["identify", "F", "--workers", "1000000", "--starts", "2"], "--workers", "identify._run"),
    (["identify", "F", "--starts", "1000000000"], "--starts", "identify._run"),
    (["identify", "F", "--mcmc", "1000000000"], "--mcmc", "identify._run"),
    (["modes", "cfrp", "--n", "1000000"], "--n", "modes.run"),
    (["dispersion", "cfrp", "--fmax", "1e5", "--n", "1000000000"], "--n", "dispersion.run"),
    (["acquire", "--specimen", "cfrp", "--out", "OUT", "--hits", "1000000000"], "--hits", "acquire.run"),
    (["modes", "cfrp", "--threads", "100000"], "--threads", "modes.run")])
def test_counts_and_sizes_are_bounded_before_any_work(modal_features, tmp_path, argv, option, entry,
                                                     monkeypatch, capsys):
    """Was: --workers 1000000 forked ~700 processes; --starts 1e9, --mcmc grew past GBs. Refused
    where the option is read: the command's work (here a stand-in that fails) never starts."""
    import importlib
    module, func = entry.split(".")

    def work(args):
        raise AssertionError("the command started its work")
    monkeypatch.setattr(importlib.import_module(f"labid.cli.{module}"), func, work)
    argv = [{"F": str(modal_features), "OUT": str(tmp_path / "o.h5")}.get(a, a) for a in argv]
    assert cli.main([*argv, "-q"]) == 2
    assert option in one_line(capsys.readouterr().err)
    assert not (tmp_path / "o.h5").exists()


def nested(kind: str, depth: int) -> str:
    if kind == "json":
        return '{"specimen": "aluminium", "modal": ' + "[" * depth + "]" * depth + "}"
    return "name = 'x'\nthickness = " + "[" * depth + "]" * depth + "\n"


@pytest.mark.parametrize("kind, argv", [("json", ["identify", "F"]), ("toml", ["modes", "F"]),
                                        ("toml", ["acquire", "--rig", "F", "--specimen", "cfrp", "--out", "OUT"])])
def test_deeply_nested_documents_are_one_line_exit_2(tmp_path, kind, argv, capsys):
    """Was: exit 1 (RecursionError) on 30 of 570 fuzzed runs."""
    for depth in (40, 5000, 200_000):
        f = tmp_path / f"deep.{kind}"
        f.write_text(nested(kind, depth))
        a = [{"F": str(f), "OUT": str(tmp_path / "o.h5")}.get(x, x) for x in argv]
        assert cli.main([*a, "-q"]) == 2, depth
        assert str(f) in one_line(capsys.readouterr().err)


def test_an_error_echoes_at_most_80_characters_of_a_value(tmp_path, capsys):
    """Was: the one line echoed the whole 10 MB value."""
    spec = tmp_path / "s.toml"
    spec.write_text("thickness = '" + "x" * 10_000_000 + "'\n")
    feats = tmp_path / "f.json"
    feats.write_text(json.dumps({"specimen": "aluminium", "modal": {"frequencies_hz": [10.2, 15.1, 20.3]}}))
    for argv in (["modes", str(spec)], ["identify", str(feats), "--start", "E=" + "x" * 100_000],
                 ["analyze", str(spec), "--wavelet", "1," + "x" * 100_000]):
        assert cli.main([*argv, "-q"]) == 2
        line = one_line(capsys.readouterr().err)
        assert len(line) < 1000 and "x" * 81 not in line


# ------------------------------------------------------------------ 6. damaged runs
def flip(path: Path, seed: int, n: int = 60) -> None:
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(seed)
    for i in rng.integers(0, len(data), n):
        data[i] ^= int(rng.integers(1, 256))
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("how", ["flip1", "flip2", "truncate", "garbage"])
def test_a_result_the_damaged_run_cannot_take_still_goes_to_json(analysed, modal_features, tmp_path, how,
                                                                 capsys):
    """Was: identify exit 1 on 6 bit-flipped runs, and its --json never written."""
    run = copy_run(analysed, tmp_path)
    feats = tmp_path / "f.json"
    doc = json.loads(modal_features.read_text())
    doc["analysis"] = {"run": "run.h5"}
    feats.write_text(json.dumps(doc))
    if how.startswith("flip"):
        flip(run, int(how[-1]))
    elif how == "truncate":
        run.write_bytes(run.read_bytes()[: run.stat().st_size // 3])
    elif how == "not_hdf5":
        run.write_bytes(b"not HDF5 at all\n" * 100)
    else:
        garbage_results(run, "dataset")
    out = tmp_path / "id.json"
    rc = cli.main(["identify", str(feats), "--params", "E", "--json", str(out), "-q"])
    err = capsys.readouterr().err
    assert rc in (0, 3), err
    assert "Traceback" not in err and not any("error" in ln for ln in err.splitlines()), err
    assert json.loads(out.read_text())["parameters"]["E"]["value"] > 0
    assert all(len(ln) < 1000 for ln in err.splitlines())


def heap_loop(src: Path, dst: Path) -> Path:
    """A copy of ``src`` where the HDF5 library loops when it reads a string: in the first
    global heap collection with free space, the object before that free space grows by
    2048 bytes (one flipped bit of its size field), into the free space. One of 28 runs
    with 60 random byte flips had this (the library spun for minutes in its C code)."""
    import re
    a = bytearray(src.read_bytes())
    for m in re.finditer(b"GCOL", a):
        g, size = m.start(), int.from_bytes(a[m.start() + 8:m.start() + 16], "little")
        p, last = g + 16, None
        while p < g + size:
            idx, osz = int.from_bytes(a[p:p + 2], "little"), int.from_bytes(a[p + 8:p + 16], "little")
            if idx == 0:
                if last is not None and osz > 2048 + 64:
                    a[last + 9] = (a[last + 9] + 8) & 0xFF
                    dst.write_bytes(bytes(a))
                    return dst
                break
            last = p
            p += 16 + ((osz + 7) // 8) * 8
    raise AssertionError("no global heap collection with free space in the run")


def test_a_run_the_hdf5_library_would_loop_on_is_refused_in_one_line(analysed, tmp_path):
    """Reading its string attributes spun in the library's C code, beyond any signal handler:
    the read is tried in a child with bounded CPU first (store.probe); the command's own CPU
    is bounded here too, so the test ends whatever the code does."""
    run = heap_loop(analysed, tmp_path / "loop.h5")
    p = labid_limited(["report", run, "--out", tmp_path / "r.html", "-q"], cpu=60, env={"LABID_PROBE_CPU_S": "2"})
    assert p.returncode == 2, (p.returncode, p.stderr[-500:])
    assert "loops" in one_line(p.stderr) and str(run) in p.stderr


# ------------------------------------------------------------------ readers (issue 27 rows, issue 26 item 8)
def recording(tmp_path: Path, kind: str) -> Path:
    import scipy.io
    from scipy.io import wavfile
    if kind == "empty.mat":
        p = tmp_path / "e.mat"
        p.write_bytes(b"")
    elif kind == "zero.wav":
        p = tmp_path / "z.wav"
        wavfile.write(p, 10000, np.zeros((0, 2), np.int16))
    elif kind == "string.tdms":
        from nptdms import ChannelObject, TdmsWriter
        p = tmp_path / "s.tdms"
        with TdmsWriter(p) as w:
            w.write_segment([ChannelObject("g", "force", np.array(["a", "b", "c"]))])
    elif kind == "garbage.tdms":
        p = tmp_path / "g.tdms"
        p.write_bytes(b"TDSm" + b"\0" * 40)
    else:
        p = tmp_path / "v.mat"
        scipy.io.savemat(p, {"x": np.zeros((2, 2, 2))})
    return p


@pytest.mark.parametrize("kind", ["empty.mat", "zero.wav", "string.tdms", "garbage.tdms"])
def test_unreadable_recordings_are_one_line_exit_2(tmp_path, kind, capsys):
    """Was: exit 1 for an empty MAT, a 0-frame WAV, a TDMS string channel; npTDMS warnings
    made 3 errors multi-line."""
    f = recording(tmp_path, kind)
    assert cli.main(["import", str(f), "--rig", "default", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"),
                     "--map", "force=force", "-q"]) == 2
    assert f.name in one_line(capsys.readouterr().err)


def test_csv_columns_with_units_map_onto_rig_channels_without_map(tmp_path, capsys):
    """Was: 'force [N]' not matched to the rig's force, though docs/import-export.md says it is."""
    n = 400
    t = np.arange(n) / 1e4
    rows = "\n".join(f"{float(t[i])!r},{float(np.sin(i / 7))!r},{float(np.cos(i / 5))!r}" for i in range(n))
    f = write_csv(tmp_path / "hit.csv", "time,force [N],acc1 [m/s^2]\n" + rows + "\n")
    assert cli.main(["import", str(f), "--rig", "default", "--specimen", "cfrp", "--out",
                     str(tmp_path / "r.h5"), "--pretrigger", "0", "-q"]) == 0
    capsys.readouterr()
    with RunStore(tmp_path / "r.h5", "r") as st:
        rec = st.shots("hammer")[0]
    assert [c.name for c in rec.channels] == ["force", "acc1"]
    np.testing.assert_allclose(rec.scaled("force"), np.sin(np.arange(n) / 7), rtol=1e-15)


def test_decimal_comma_semicolon_csv_and_a_folder_of_recordings(tmp_path, capsys):
    """Issue 26 item 8: the usual European CSV ('1,5;2,25'), a folder given as the recording."""
    d = tmp_path / "hits"
    d.mkdir()
    n = 300
    for k in range(2):
        rows = "\n".join(f"{i / 1e4:.4f};{(k + 1) * 0.5 + i * 1e-3:.3f};{-i * 1e-3:.3f}".replace(".", ",")
                         for i in range(n))
        write_csv(d / f"hit{k}.csv", "time [s];force [N];acc1 [m/s^2]\n" + rows + "\n")
    (d / "notes.txt.bak").write_text("not a recording")
    assert cli.main(["import", str(d), "--rig", "default", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"),
                     "--pretrigger", "0", "-q"]) == 0
    capsys.readouterr()
    with RunStore(tmp_path / "r.h5", "r") as st:
        recs = st.shots("hammer")
    assert len(recs) == 2
    assert [float(r.scaled("force")[0]) for r in recs] == [0.5, 1.0]            # 0,5 and 1,0: decimal commas
    assert float(recs[0].scaled("acc1")[10]) == pytest.approx(-0.01, rel=1e-12)


def test_a_uff_written_by_export_reimports_without_a_map(tmp_path, capsys):
    """Issue 26 item 8: hammer and wave shots of one UFF, each device's as its kind, unchanged."""
    run = tmp_path / "run.h5"
    assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "1", "--waves", "1", "-q"]) == 0
    uff = tmp_path / "run.uff"
    assert cli.main(["export", str(run), "--uff", str(uff), "-q"]) == 0
    back = tmp_path / "back.h5"
    assert cli.main(["import", str(uff), "--rig", "default", "--specimen", "cfrp", "--out", str(back), "-q"]) == 0
    capsys.readouterr()
    for kind in ("hammer", "wave"):
        with RunStore(run, "r") as a, RunStore(back, "r") as b:
            ra, rb = a.shots(kind), b.shots(kind)
        assert len(ra) == len(rb) == 1
        assert rb[0].timing.pretrigger == ra[0].timing.pretrigger
        for c in ra[0].channels:
            np.testing.assert_array_equal(rb[0].scaled(c.name), ra[0].scaled(c.name))     # binary UFF: exact


def test_an_unwritable_uff_path_is_exit_2(analysed, tmp_path, capsys):
    """Issue 26 item 8: was exit 1."""
    run = copy_run(analysed, tmp_path)
    for target in (tmp_path / "no" / "such" / "dir" / "r.uff", tmp_path):
        assert cli.main(["export", str(run), "--uff", str(target), "-q"]) == 2
        assert str(target) in one_line(capsys.readouterr().err)


def test_a_nul_character_in_an_argument_is_one_line_exit_2(analysed, tmp_path, capsys):
    """Found by the fuzz bench (session 23): ``export --uff "\\0"`` was exit 1 (ValueError:
    embedded null byte, from os.open). A shell cannot pass one; a caller of main() can."""
    run = copy_run(analysed, tmp_path)
    for argv in (["export", str(run), "--uff", "\0"], ["modes", "cfrp\0x"], ["report", str(run), "--out", "a\0.html"]):
        assert cli.main([*argv, "-q"]) == 2
        assert "NUL" in one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == [run]


def test_no_library_warning_reaches_the_console(tmp_path, capsys):
    """A float WAV with a 'PEAK' chunk (SoX and Audacity write one; scipy warns 'Chunk (non-data)
    not understood') imports with no warning line."""
    from scipy.io import wavfile
    p = tmp_path / "f.wav"
    wavfile.write(p, 10000, (0.1 * np.sin(np.arange(600) / 9)).astype(np.float32))
    data = p.read_bytes()                          # insert the PEAK chunk before 'data'
    i = data.index(b"data")
    payload = (1).to_bytes(4, "little") + (0).to_bytes(4, "little") + np.float32(0.1).tobytes() + (5).to_bytes(4, "little")
    peak = b"PEAK" + len(payload).to_bytes(4, "little") + payload
    body = data[12:i] + peak + data[i:]
    p.write_bytes(b"RIFF" + (len(body) + 4).to_bytes(4, "little") + b"WAVE" + body)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")             # any warning the reader lets through fails the test
        assert cli.main(["import", str(p), "--rig", "default", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"),
                         "--map", "1=force", "--units", "force=2.5V", "--pretrigger", "0", "-q"]) == 0
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------ 7. signals
ACQUIRE_PAUSED = """
import mock_hw.rig as mr
orig, n, at = mr.SimulatedDevice.read, [0], int(sys.argv[2])

def read(self, timeout_s=10.0):
    n[0] += 1
    if n[0] == at:
        print("reading", flush=True)               # Ctrl-C arrives during this shot
        sys.stdin.readline()
    return orig(self, timeout_s)

mr.SimulatedDevice.read = read
from labid.cli.main import main
sys.argv = ["labid", "acquire", "--specimen", "cfrp", "--out", sys.argv[1], "--hits", "3", "--waves", "0", "-q"]
sys.exit(main())
"""


@pytest.mark.parametrize("during", [1, 3])
def test_ctrl_c_during_acquire_always_exits_130(tmp_path, during):
    """Was: exit 0 once in four (Ctrl-C during the last shot: the shot was kept, the exit code lost)."""
    run = tmp_path / "r.h5"
    proc = child(ACQUIRE_PAUSED, str(run), str(during))
    try:
        assert proc.stdout.readline().strip() == "reading", proc.stderr.read()
        proc.send_signal(signal.SIGINT)
        proc.stdin.write("go\n")
        proc.stdin.flush()
        _, err = proc.communicate()
    finally:
        proc.kill()
    assert proc.returncode == 130, err[-1000:]
    with RunStore(run, "r") as st:                 # the shot under way when Ctrl-C came is kept
        assert st.n_shots("hammer") == during


@pytest.mark.parametrize("after", [1, 2])
def test_resume_after_a_kill_completes_exactly_the_requested_count(tmp_path, after):
    """Was: twice, 7 hammer shots after a resume that should have completed 5."""
    run = tmp_path / "r.h5"
    proc = subprocess.Popen([sys.executable, "-m", "labid.cli.main", "acquire", "--specimen", "cfrp", "--out",
                             str(run), "--hits", "5", "--waves", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    seen = 0
    for line in proc.stderr:                       # kill on the event: the after-th shot recorded
        seen += "recorded" in line
        if seen == after:
            proc.kill()
            break
    proc.communicate()
    assert cli.main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "5", "--waves", "0",
                     "--total", "-q"]) == 0
    with RunStore(run, "r") as st:
        assert st.n_shots("hammer") == 5
        assert [r.meta["shot"] for r in st.shots("hammer")] == [f"hammer_{i:04d}" for i in range(1, 6)]
    assert not lock_path(run).exists()
