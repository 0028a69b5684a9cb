"""labid.services: results of the command line land in the run their features came
from, and the panel shows them when it opens that run."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from labid import services
from labid.cli.main import main
from labid.inputs.rig import read_rig_text
from labid.store import RunStore


def fast_rig(tmp_path: Path) -> Path:
    """The built-in simulated rig, made small: few modes, short records."""
    text, _ = read_rig_text("default")
    p = tmp_path / "fast_rig.toml"
    p.write_text(text.replace("n_modes = 40", "n_modes = 8").replace("samples = 20000", "samples = 4096"))
    return p


@pytest.fixture(scope="module")
def analysed_run(tmp_path_factory):
    """A run of 3 hammer hits, analysed into a features file in ANOTHER folder."""
    d = tmp_path_factory.mktemp("cli_run")
    run = d / "runs" / "plate.h5"
    assert main(["acquire", "--rig", str(fast_rig(d)), "--specimen", "cfrp", "--out", str(run),
                 "--hits", "3", "--waves", "0", "--quiet"]) == 0
    feats = d / "work" / "plate.json"
    feats.parent.mkdir()
    assert main(["analyze", str(run), "--out", str(feats)]) == 0
    return run, feats


def test_features_refer_to_their_run(analysed_run, tmp_path):
    run, feats = analysed_run
    doc = json.loads(feats.read_text())
    assert doc["analysis"]["run"] == "../runs/plate.h5"
    assert services.run_of_features(feats) == run.resolve()
    # beside the run (the default) the reference is the run's bare name, as before
    assert services.run_reference(run, services.features_path(run)) == "plate.h5"
    # a features file whose run is gone, or that names none, refers to no run
    moved = tmp_path / "plate.json"
    moved.write_text(feats.read_text())
    assert services.run_of_features(moved) is None


@pytest.mark.slow
def test_cli_results_are_stored_in_the_run_and_shown_by_the_panel(analysed_run, tmp_path, capfd, qtbot):
    run, feats = analysed_run
    out = tmp_path / "ident.json"
    assert main(["identify", str(feats), "--params", "E1,E2,G12", "--json", str(out)]) == 0
    assert "result stored in" in capfd.readouterr().err
    ident = json.loads(out.read_text())
    gap_out = tmp_path / "gap.json"
    assert main(["diagnose", str(feats), "--json", str(gap_out)]) == 0
    gap = json.loads(gap_out.read_text())
    with RunStore(run, "r") as st:
        stored_ident = st.read_result("identification")
        stored_gap = st.read_result("diagnosis")
    assert stored_ident["parameters"] == ident["parameters"]
    assert stored_gap["verdict"] == gap["verdict"] and stored_gap["gap"] == gap["gap"]

    from labid.gui.main_window import MainWindow
    win = MainWindow(str(run))
    qtbot.addWidget(win)
    view = win.identification
    assert view.table.rowCount() == 3
    shown = {view.table.item(i, 0).text() for i in range(3)}
    assert shown == {"E1", "E2", "G12"}
    assert win.gap.result["verdict"] == gap["verdict"]
    assert win.gap.verdict.text().startswith(f"verdict: {gap['verdict']}")
    win.close()


def test_results_of_features_without_a_run_are_not_stored(tmp_path, capfd):
    ident = pytest.importorskip("labid.workflows.identification")
    doc = ident.synthetic_features("cfrp", n_modes=4, waves=())
    p = tmp_path / "synthetic.json"
    p.write_text(json.dumps(doc))
    assert main(["identify", str(p), "--params", "E1,E2"]) == 0
    assert "stored" not in capfd.readouterr().err
    assert services.store_for_features(p, "identification", {"x": 1}) is None


def test_a_run_that_cannot_be_written_keeps_the_result_and_says_why(analysed_run):
    """Another process writes the run file (HDF5 locks it): the note says so, nothing raises."""
    run, feats = analysed_run
    code = ("import sys, time\n"
            "from labid.store import RunStore\n"
            f"s = RunStore({str(run)!r}, 'a')\n"
            "print('ready', flush=True); time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[3])
    try:
        assert proc.stdout.readline().strip() == "ready"
        note = services.store_for_features(feats, "identification_test", {"x": 1.0})
    finally:
        proc.kill()
        proc.wait()
    assert note.startswith("warning: result not stored") and str(run.resolve()) in note
