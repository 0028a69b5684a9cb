"""labid demo's second process (issue 29): a job goes to the worker when there is one, and is
computed in this process when the worker is gone (killed) or there is none."""
from __future__ import annotations

import os
import signal

from labid.cli import demo


def test_jobs_run_in_the_worker_and_here_when_it_died():
    pool = demo._pool(2)
    try:
        worker = demo._submit(pool, os.getpid).result()
        assert worker != os.getpid()                       # computed in the second process
        os.kill(worker, signal.SIGKILL)
        assert demo._submit(pool, os.getpid).result() == os.getpid()   # the dead worker's job: here
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def test_one_worker_means_this_process():
    assert demo._pool(1) is None
    assert demo._submit(None, os.getpid).result() == os.getpid()


def test_a_job_done_here_is_computed_once():
    calls = []
    job = demo._submit(None, lambda: calls.append(1) or len(calls))
    assert (job.result(), job.result()) == (1, 1) and calls == [1]


def test_the_reports_figures_are_read_when_placed():
    asked = []
    figs = demo._Awaited({"a": lambda: asked.append("a") or "A", "b": lambda: asked.append("b") or "B"})
    assert set(figs) == {"a", "b"} and asked == []         # listing them waits for none
    assert figs["b"] == "B" and figs["b"] == "B" and asked == ["b"]
