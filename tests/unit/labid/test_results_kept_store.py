"""Storing a kept result costs the same with any history (issue 29, session 27): its
number comes from group names and one integer, the older one is moved aside in the same
file copy as the new one is written, and a kill or an error at any moment of that
combined write leaves the run file as it was. Every kill waits on an event (a line the
child prints at the moment of interest), never on a sleep budget."""
from __future__ import annotations

import os
import shutil
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest

from labid import services
from labid.base.errors import UserError
from labid.store import RunStore
import labid.store.probe as probe_module
import labid.store.results as results_module
import labid.store.tree as tree_module

from tests.integration.test_reliability import child, temps

NAME = "identification"


def result(e: float) -> dict:
    """An identification-shaped result: nested values, an array, a list of records."""
    return {"parameters": {"E1": {"value": e, "std": 0.1 * e}}, "data": ["modal", "waves"],
            "blocks": {"modal": {"kind": "modal", "relative": np.linspace(0, e, 7), "rms_rel": e}},
            "history": [{"iteration": 1, "cost": e, "params": {"E1": e}}]}


def kept_run(path: Path, n: int) -> Path:
    with RunStore(path, "a"):
        pass
    for i in range(1, n + 1):
        services.store_result(path, NAME, result(float(i)), by=f"test {i}")
    return path


def test_n_stores_keep_every_result_numbered_readable_and_unchanged(tmp_path, monkeypatch):
    run = kept_run(tmp_path / "run.h5", 5)
    hist = services.result_history(run, NAME)
    assert [h["number"] for h in hist] == [1, 2, 3, 4, 5]
    assert [h["by"] for h in hist] == [f"test {i}" for i in range(1, 6)]
    assert [h["path"] for h in hist] == [f"/results/history/{NAME}/{i}" for i in range(1, 5)] + [f"/results/{NAME}"]
    for i in range(1, 6):
        got = services.read_result(run, NAME, i)
        assert got["parameters"]["E1"]["value"] == float(i) and got["stored"]["number"] == i
    with RunStore(run, "r") as st:                # the structured twin moved whole: arrays, records
        g = st.read_group(f"history/{NAME}/2")
    assert np.allclose(g["blocks"]["modal"]["relative"], np.linspace(0, 2.0, 7)) and g["history"][0]["cost"] == 2.0
    # the sixth store: one copy of the file, no kept tree read; the file grows by about one result
    copies, trees = [], []
    real_copy = shutil.copyfile
    monkeypatch.setattr(tree_module.shutil, "copyfile", lambda *a, **k: copies.append(a) or real_copy(*a, **k))
    monkeypatch.setattr(results_module, "read_tree", lambda g: trees.append(g.name) or tree_module.read_tree(g))
    sizes = [run.stat().st_size]
    for i in (6, 7):
        note = services.store_result(run, NAME, result(float(i)))
        sizes.append(run.stat().st_size)
        assert note == f"/results/{NAME}, no. {i}; no. {i - 1} kept at /results/history/{NAME}/{i - 1}"
    assert len(copies) == 2 and trees == []
    one = kept_run(tmp_path / "one.h5", 1).stat().st_size - kept_run(tmp_path / "none.h5", 0).stat().st_size
    assert 0 < sizes[2] - sizes[1] <= 1.5 * one, (sizes, one)
    assert [h["number"] for h in services.result_history(run, NAME)] == list(range(1, 8))


def test_a_json_only_result_gives_its_number_to_the_history(tmp_path):
    run = kept_run(tmp_path / "run.h5", 0)
    with RunStore(run, "a") as st:                # a result whose structure HDF5 could not hold
        st.write_group(NAME, {"json": '{"parameters": {}, "stored": {"number": 4, "time": "t", "by": "x"}}'})
    note = services.store_result(run, NAME, result(5.0))
    assert note == f"/results/{NAME}, no. 5; no. 4 kept at /results/history/{NAME}/4"
    assert [(h["number"], h["by"]) for h in services.result_history(run, NAME)] == [(4, "x"), (5, "labid")]


def test_an_error_in_the_combined_write_leaves_the_file_as_it_was(tmp_path, monkeypatch):
    run = kept_run(tmp_path / "run.h5", 2)
    before = run.read_bytes()

    def fails(g, data):
        assert f"history/{NAME}/2" in g.file          # the older one was already moved, in the copy
        raise RuntimeError("a library error half-way through the new result")
    monkeypatch.setattr(tree_module, "write_tree", fails)
    with pytest.raises(UserError, match="results not written"):
        services.store_result(run, NAME, result(3.0))
    monkeypatch.undo()
    assert run.read_bytes() == before and not temps(run, ".results")
    assert services.read_result(run, NAME)["stored"]["number"] == 2
    assert services.store_result(run, NAME, result(3.0)).startswith(f"/results/{NAME}, no. 3; no. 2 kept")


#: a store_result stopped at a chosen moment of its combined write
STORER = """
import os
import numpy as np
import labid.store.tree as tree
from labid import services
moment = sys.argv[2]
orig_write, orig_replace = tree.write_tree, os.replace


def write_tree(g, data):
    if moment == "moved" and g.name == "/results/identification":
        g.file.flush()                            # the move is on disk in the copy
        print("moved", flush=True)
        sys.stdin.readline()                      # SIGKILL arrives here
    return orig_write(g, data)


def replace(a, b):
    if moment == "renaming" and str(a).endswith(".results"):
        print("renaming " + str(a), flush=True)   # the copy is complete, synced, not renamed
        sys.stdin.readline()                      # SIGKILL arrives here
    return orig_replace(a, b)


tree.write_tree, os.replace = write_tree, replace
services.store_result(sys.argv[1], "identification", {"parameters": {"E1": {"value": 3.0, "std": 0.3}}})
print("finished", flush=True)
"""


@pytest.mark.parametrize("moment", ["moved", "renaming"])
def test_a_kill_during_the_combined_write_leaves_the_earlier_results(tmp_path, moment):
    run = kept_run(tmp_path / "run.h5", 2)
    before = run.read_bytes()
    proc = child(STORER, str(run), moment)
    try:
        line = proc.stdout.readline().strip()
        assert line.split()[:1] == [moment], proc.stderr.read()
        if moment == "renaming":                  # the copy holds both: the older one moved, the new one
            with h5py.File(line.split()[1], "r") as f:
                assert int(f[f"results/history/{NAME}/2/stored/number"][()]) == 2
                assert int(f[f"results/{NAME}/stored/number"][()]) == 3
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert run.read_bytes() == before and temps(run, ".results")
    assert [h["number"] for h in services.result_history(run, NAME)] == [1, 2]
    assert services.read_result(run, NAME)["parameters"]["E1"]["value"] == 2.0
    # the next writer clears the killed writer's copy and numbers on
    assert services.store_result(run, NAME, result(3.0)).startswith(f"/results/{NAME}, no. 3; no. 2 kept")
    assert not temps(run, ".results")


def test_a_run_this_process_wrote_is_not_probed_again_a_run_changed_elsewhere_is(tmp_path, monkeypatch):
    made = kept_run(tmp_path / "made.h5", 2)
    run = tmp_path / "run.h5"
    shutil.copyfile(made, run)                    # a file this process never opened
    forks = []
    real = probe_module._fork
    monkeypatch.setattr(probe_module, "_fork", lambda fn: forks.append(1) or real(fn))
    services.store_result(run, NAME, result(3.0))
    assert len(forks) == 1                        # the first open of this file is probed, in a child
    assert services.read_result(run, NAME)["stored"]["number"] == 3
    assert len(forks) == 1                        # what it wrote itself is read in-process
    st = os.stat(run)
    os.utime(run, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))   # another program changed it
    assert services.read_result(run, NAME)["stored"]["number"] == 3
    assert len(forks) >= 2
