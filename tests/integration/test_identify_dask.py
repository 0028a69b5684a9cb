"""Multi-start study on a local Dask distributed cluster (``--scheduler``)."""
from __future__ import annotations

import json

import pytest

distributed = pytest.importorskip("distributed")

from labid.cli.main import main  # noqa: E402
from labid.workflows.identification import synthetic_features  # noqa: E402

AL = {"E": 71.04e9, "G": 25.32e9}


@pytest.mark.slow
def test_multi_start_on_local_dask_cluster(tmp_path, capsys):
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 20),))
    doc["specimen"] = "aluminium"
    feats = tmp_path / "f.json"
    feats.write_text(json.dumps(doc))
    out = tmp_path / "r.json"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, worker_dashboard_address=None) as cluster:
        code = main(["identify", str(feats), "--starts", "4", "--scheduler", cluster.scheduler_address,
                     "--json", str(out)])
        workers = set(cluster.scheduler.workers)
    err = capsys.readouterr().err
    assert code == 0, err
    ms = json.loads(out.read_text())["multi_start"]
    assert len(ms) == 4 and len(workers) == 2
    good = [r for r in ms if r["converged"] and r["chi2_per_point"] < 1.0]
    assert good
    for r in good:
        for n in ("E", "G"):
            assert r["values"][n] == pytest.approx(AL[n], rel=1e-3)


@pytest.mark.slow
def test_unreachable_scheduler_is_a_user_error(tmp_path, capsys):
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 5),))
    doc["specimen"] = "aluminium"
    feats = tmp_path / "f.json"
    feats.write_text(json.dumps(doc))
    code = main(["identify", str(feats), "--starts", "2", "--scheduler", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 2 and "--scheduler" in err
