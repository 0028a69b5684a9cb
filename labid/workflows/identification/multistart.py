"""Multi-start studies (paper Fig. 3): the estimate repeated from many initial guesses.

``random_starts`` draws the guesses; ``multi_start`` runs them through any
``concurrent.futures`` executor (a process pool by default, or a Dask
``Client.get_executor()``); each worker builds the forward models once and
reuses them for its starts. ``distinct_minima`` clusters the end points and
``minima_summary`` says what was found (issue 12). Figure: ``labid.report.plots.plot_multi_start``.
"""
from __future__ import annotations

import json
import math
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ...base import threads
from ...base.errors import Cancelled, UserError
from ...inputs.features import specimen_of
from .estimation import Problem, problem_from_features, run, start_values
from ...inputs.specimen import Specimen

__all__ = ["random_starts", "multi_start", "distinct_minima", "minima_summary"]


_WORKER_CACHE: dict[str, Problem] = {}


def _job(spec: tuple) -> dict:
    """One start of a multi-start study (runs in a worker process)."""
    key, doc, specimen, names, start, method, prior, n_threads = spec
    threads.worker_init(n_threads)   # Dask workers start with their own settings
    problem = _WORKER_CACHE.get(key)
    if problem is None:
        problem = problem_from_features(doc, specimen=specimen)
        _WORKER_CACHE.clear()
        _WORKER_CACHE[key] = problem
    try:
        # no data-set consistency check: it only adds a warning (not returned here)
        # at the cost of one extra fit per data set
        est = run(problem, names, start, method=method, prior=prior, consistency=False)
    except UserError as e:  # a start that is unphysical: record, do not stop the study
        return {"start": dict(start), "error": str(e)}
    chi2 = sum(r["chi2"] for r in est.residuals.values())
    n = sum(r["n"] for r in est.residuals.values())
    fit = est.fit or {}
    return {"start": dict(start), "values": est.params, "std": dict(zip(est.names, est.std.tolist())),
            "converged": est.converged, "chi2_per_point": chi2 / n, "iterations": est.iterations,
            "residual": est.residual_summary(), "seconds": est.seconds,
            "consistent": bool(fit.get("consistent", False)), "p_value": fit.get("p_value")}


def distinct_minima(results: Sequence[Mapping], names: Sequence[str], rel_tol: float = 1e-3) -> list[dict]:
    """The distinct end points of a multi-start study, best (lowest chi^2) first: each
    ``{values, std, chi2_per_point, consistent, n_starts, starts}`` (``starts``: indices
    into ``results``). Two end points are the same minimum when every constant agrees
    within ``rel_tol`` or within 2 of their combined std."""
    out: list[dict] = []
    order = sorted((i for i, r in enumerate(results) if "values" in r), key=lambda i: results[i]["chi2_per_point"])
    for i in order:
        r = results[i]
        for m in out:
            same = True
            for n in names:
                a, b = r["values"][n], m["values"][n]
                sd = math.hypot(r["std"].get(n, 0.0) or 0.0, m["std"].get(n, 0.0) or 0.0)
                if not (abs(a / b - 1) <= rel_tol or (math.isfinite(sd) and abs(a - b) <= 2 * sd)):
                    same = False
                    break
            if same:
                m["n_starts"] += 1
                m["starts"].append(i)
                break
        else:
            out.append({"values": dict(r["values"]), "std": dict(r["std"]), "chi2_per_point": r["chi2_per_point"],
                        "consistent": bool(r.get("consistent", False)), "n_starts": 1, "starts": [i]})
    return out


def minima_summary(minima: Sequence[Mapping], n_results: int) -> str:
    """One line: how many distinct minima, from how many starts, and whether the best two
    are both acceptable (consistent fits)."""
    if not minima:
        return f"multi-start: no start of {n_results} gave an estimate"
    head = (f"multi-start: {len(minima)} distinct minim{'um' if len(minima) == 1 else 'a'} from {n_results} starts; "
            + "; ".join(f"chi^2/n {m['chi2_per_point']:.3g} ({m['n_starts']} starts"
                        f"{', consistent' if m['consistent'] else ''})" for m in minima[:4]))
    if len(minima) > 1 and minima[0]["consistent"] and minima[1]["consistent"]:
        head += "; the best two are BOTH acceptable: the data do not decide between them"
    return head


def random_starts(nominal: Mapping[str, float], names: Sequence[str], n: int, *,
                  spread: float | Mapping[str, tuple[float, float]] = 0.5, seed: int = 0,
                  problem: Problem | None = None) -> list[dict[str, float]]:
    """``n`` random initial guesses: log-uniform within a factor (1 +- spread) of
    nominal, or uniform within explicit ``{name: (low, high)}`` bounds. With
    ``problem``, unphysical draws (e.g. G < E/3 for an isotropic plate) are
    redrawn."""
    rng = np.random.default_rng(seed)
    out: list[dict[str, float]] = []
    for _ in range(100 * n):
        if len(out) == n:
            break
        st = {}
        for nm in names:
            if isinstance(spread, Mapping):
                lo, hi = spread[nm]
                st[nm] = float(rng.uniform(lo, hi))
            else:
                st[nm] = float(nominal[nm] * np.exp(rng.uniform(np.log(1 - spread), np.log(1 + spread))))
        if problem is not None:
            try:
                start_values(problem, names, st)
            except UserError:
                continue
        out.append(st)
    return out


def multi_start(doc: Mapping, starts: Sequence[Mapping[str, float]], names: Sequence[str], *,
                specimen: Specimen | None = None, base_dir: str | Path = ".", method: str = "lm",
                prior: float | None = None, executor: Executor | None = None,
                max_workers: int = 2, progress: Callable[[Any], None] | None = None,
                should_stop: Callable[[], bool] | None = None) -> list[dict]:
    """Run the estimate from every start, in parallel through ``executor``.

    ``executor`` is any ``concurrent.futures.Executor`` (for instance a Dask
    ``Client.get_executor()``); by default a ``ProcessPoolExecutor`` with
    ``max_workers`` processes (``max_workers`` <= 1: one after the other, in this
    process). Each worker builds the forward models once and reuses them for its starts.
    Each finished start reports ``("start", k, n)`` to ``progress`` as it finishes (k of n,
    in any order; issue 26: a 200-start cluster run took ~1.9 CPU-hours in silence);
    ``should_stop()`` raises ``Cancelled`` before the next one is awaited (pending starts are
    cancelled). Returns one dict per start, in order.
    """
    spec = specimen if specimen is not None else specimen_of(doc, Path(base_dir), "<features>")
    doc = dict(doc)
    doc.pop("specimen", None)
    key = json.dumps(doc, sort_keys=True, default=str) + repr(spec)
    # one BLAS thread per worker process unless the user said otherwise (labid.base.threads)
    n_threads = threads.for_workers()
    jobs = [(key, doc, spec, tuple(names), dict(s), method, prior, n_threads) for s in starts]
    if executor is not None:
        return _in_order(executor, jobs, progress, should_stop)
    if max_workers <= 1:
        out = []
        for j in jobs:
            if should_stop is not None and should_stop():
                raise Cancelled()
            out.append(_job(j))
            if progress is not None:
                progress(("start", len(out), len(jobs)))
        return out
    ex = ProcessPoolExecutor(max_workers=max_workers, initializer=threads.worker_init, initargs=(n_threads,))
    try:
        # one start per task: starts differ in cost (local minima take 2x longer), so
        # larger chunks leave a worker idle at the end; a task costs ~1 ms to send
        return _in_order(ex, jobs, progress, should_stop)
    finally:
        ex.shutdown(wait=True, cancel_futures=True)


def _in_order(ex: Executor, jobs: list, progress, should_stop) -> list[dict]:
    """``_job`` of every job through ``ex``, one task each, reported as they finish; results
    in the order of ``jobs``."""
    futures = [ex.submit(_job, j) for j in jobs]
    try:
        for k, _ in enumerate(as_completed(futures), 1):
            if progress is not None:
                progress(("start", k, len(jobs)))
            if should_stop is not None and should_stop():
                raise Cancelled()
    except BaseException:
        for f in futures:
            f.cancel()
        raise
    return [f.result() for f in futures]
