"""Nothing lost (issue 26, item 3): a new identification or diagnosis is kept beside the
older one in the run file; a bad output path of ``labid identify``/``labid diagnose`` costs
one line (exit 2) before any fitting, and the stored result stays as it was."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from labid import services
from labid.cli.main import main
from labid.store import RunStore
from labid.workflows.identification import flow, synthetic_features
from labid.workflows import diagnosis


def _run(tmp_path: Path) -> Path:
    p = tmp_path / "run.h5"
    with RunStore(p, "a"):
        pass
    return p


def test_a_new_result_is_kept_beside_the_older_one_and_replace_says_so(tmp_path):
    run = _run(tmp_path)
    first = services.store_result(run, "identification", {"parameters": {"E": {"value": 1.0, "std": 0.1}}})
    second = services.store_result(run, "identification", {"parameters": {"E": {"value": 2.0, "std": 0.1}}},
                                   by="labid identify")
    assert first == "/results/identification, no. 1"
    assert second.endswith("no. 1 kept at /results/history/identification/1")
    # readers get the newest at the usual place, the older one by its number
    assert services.read_result(run, "identification")["parameters"]["E"]["value"] == 2.0
    assert services.read_result(run, "identification", 1)["parameters"]["E"]["value"] == 1.0
    assert services.open_run(run).results["identification"]["stored"]["by"] == "labid identify"
    third = services.store_result(run, "identification", {"parameters": {"E": {"value": 3.0, "std": 0.1}}},
                                  replace=True)
    assert "replaced" in third
    hist = services.result_history(run, "identification")
    assert [h["number"] for h in hist] == [1, 2]
    assert services.read_result(run, "identification", 2)["parameters"]["E"]["value"] == 3.0
    assert services.read_result(run, "identification", 1)["parameters"]["E"]["value"] == 1.0
    # the analysis (not a kept result) is overwritten as before; history is not a result
    services.store_result(run, "analysis", {"a": 1})
    services.store_result(run, "analysis", {"a": 2})
    assert services.read_result(run, "analysis") == {"a": 2}
    assert set(services.open_run(run).results) == {"identification", "analysis"}


def test_a_result_stored_before_numbering_gets_a_number_when_moved_aside(tmp_path):
    run = _run(tmp_path)
    with RunStore(run, "a") as st:                   # as labid wrote it before the history
        st.write_result("diagnosis", {"verdict": "none"})
    note = services.store_result(run, "diagnosis", {"verdict": "temperature"})
    assert note == "/results/diagnosis, no. 2; no. 1 kept at /results/history/diagnosis/1"
    assert services.read_result(run, "diagnosis", 1) == {"verdict": "none"}


@pytest.fixture(scope="module")
def features_of_a_run(tmp_path_factory):
    """A features file that refers to a run holding an identification and a diagnosis."""
    d = tmp_path_factory.mktemp("kept")
    run = _run(d)
    services.store_result(run, "identification", {"parameters": {"E": {"value": 1.0, "std": 0.1}}})
    services.store_result(run, "diagnosis", {"verdict": "none"})
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 5),))
    doc["specimen"] = "aluminium"
    doc["analysis"] = {"run": run.name}
    f = d / "f.json"
    f.write_text(json.dumps(doc))
    return f, run


def _stored(run: Path) -> str:
    with RunStore(run, "r") as st:
        return json.dumps([st.read_result(n) for n in sorted(st.result_names())], sort_keys=True)


@pytest.mark.parametrize("command", ["identify", "diagnose"])
@pytest.mark.parametrize("option", ["--csv", "--plot", "--json"])
def test_a_bad_output_path_exits_2_before_any_fit_and_the_run_is_unchanged(features_of_a_run, tmp_path,
                                                                           monkeypatch, capsys, command, option):
    feats, run = features_of_a_run
    before = _stored(run)
    calls = []
    monkeypatch.setattr(flow, "run", lambda *a, **k: calls.append(a) or pytest.fail("the fit started"))
    monkeypatch.setattr(diagnosis, "run_diagnosis", lambda *a, **k: pytest.fail("the diagnosis started"))
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    bad = {"--csv": str(blocker / "tables"), "--plot": str(tmp_path / "no_such_dir" / "f.png"),
           "--json": str(tmp_path / "no_such_dir" / "r.json")}[option]
    extra = ["--starts", "2"] if command == "identify" and option == "--plot" else []
    code = main([command, str(feats), option, bad] + extra)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and option in err[0] and "Traceback" not in err[0], err
    assert not calls and _stored(run) == before


def test_an_unknown_figure_format_is_refused_before_any_fit(features_of_a_run, tmp_path, monkeypatch, capsys):
    feats, _ = features_of_a_run
    monkeypatch.setattr(diagnosis, "run_diagnosis", lambda *a, **k: pytest.fail("the diagnosis started"))
    assert main(["diagnose", str(feats), "--plot", str(tmp_path / "gap.xyz")]) == 2
    assert "figure format 'xyz' unknown" in capsys.readouterr().err
