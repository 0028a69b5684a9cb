"""``labid identify --starts N --scheduler ADDR``: the cluster is checked before any fitting,
each refusal in one line (exit 2); an in-process Dask cluster passes the check."""
from __future__ import annotations

import json

import pytest

distributed = pytest.importorskip("distributed")

from labid.workflows import cluster  # noqa: E402
from labid import services  # noqa: E402
from labid.workflows.identification import flow  # noqa: E402
from labid.cli.main import main  # noqa: E402
from labid.base.errors import UserError  # noqa: E402
from labid.workflows.identification import synthetic_features  # noqa: E402


@pytest.fixture
def features(tmp_path):
    doc = synthetic_features("aluminium", n_modes=None, waves=(("A0", 0.0, 50e3, 5),))
    doc["specimen"] = "aluminium"
    f = tmp_path / "f.json"
    f.write_text(json.dumps(doc))
    return f


@pytest.fixture
def no_fit(monkeypatch):
    """Fail the test if the command reaches the features or the fit."""
    def forbidden(*a, **kw):
        raise AssertionError("fitting started before the scheduler was checked")
    monkeypatch.setattr(services, "load_features_file", forbidden)
    monkeypatch.setattr(flow, "run", forbidden)


def one_line_exit_2(code, capsys) -> str:
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_scheduler_without_starts_is_an_error(features, no_fit, capsys):
    err = one_line_exit_2(main(["identify", str(features), "--scheduler", "tcp://127.0.0.1:8786"]), capsys)
    assert "--scheduler without --starts" in err


def test_unreachable_scheduler_is_refused_before_fitting(features, no_fit, capsys):
    err = one_line_exit_2(main(["identify", str(features), "--starts", "2", "--scheduler", "tcp://127.0.0.1:9"]),
                          capsys)
    assert "cannot reach scheduler 'tcp://127.0.0.1:9'" in err


def test_scheduler_without_workers_is_refused(features, no_fit, capsys):
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as c:
        err = one_line_exit_2(main(["identify", str(features), "--starts", "2", "--scheduler",
                                    c.scheduler_address]), capsys)
    assert "has no worker" in err


class FakeClient:
    """Answers ``scheduler_info``, ``run`` and ``get_versions`` as distributed.Client does."""

    def __init__(self, labid: dict, packages: dict):
        self._labid, self._packages = labid, packages

    def scheduler_info(self):
        return {"workers": dict.fromkeys(self._labid, {})}

    def run(self, fn, *args, on_error="raise"):
        return dict(self._labid)

    def get_versions(self, check=False):
        here = {"host": {"python": "3.11.7"}, "packages": {"dask": "2026.8.0", "distributed": "2026.8.0",
                                                           "numpy": "2.4.6"}}
        return {"client": here, "scheduler": here,
                "workers": {w: {"host": {"python": "3.11.7"}, "packages": {**here["packages"], **p}}
                            for w, p in self._packages.items()}}


def test_workers_without_labid_or_with_other_versions_are_one_line():
    mine = cluster.local_version()
    bad = FakeClient({"tcp://w1:1": ModuleNotFoundError("No module named 'labid'"), "tcp://w2:2": "0.0.1",
                      "tcp://w3:3": mine}, {"tcp://w1:1": {}, "tcp://w2:2": {}, "tcp://w3:3": {"distributed": "2024.1.0"}})
    with pytest.raises(UserError) as e:
        cluster.check_workers(bad, "tcp://s:8786")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("--scheduler: workers differ from this machine")
    assert "tcp://w1:1: labid not installed" in msg and "tcp://w2:2: labid 0.0.1" in msg
    assert "tcp://w3:3: distributed 2024.1.0" in msg
    good = FakeClient({"tcp://w1:1": mine}, {"tcp://w1:1": {}})
    assert cluster.check_workers(good) == {"tcp://w1:1": mine}


def test_an_in_process_cluster_passes_and_runs_the_study(features, tmp_path, capsys):
    out = tmp_path / "r.json"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as c:
        assert main(["identify", str(features), "--starts", "2", "--scheduler", c.scheduler_address,
                     "--json", str(out)]) == 0
    ms = json.loads(out.read_text())["multi_start"]
    assert len(ms) == 2 and all(r["converged"] for r in ms)
