"""The one identification flow: features document -> ``labid.base.results.Identification``.

``labid identify``, the panel's Identification tab and the demo all run :func:`identify`
(through ``labid.services.run_identification``): the problem of the features
(``estimation.problem_from_features``), the estimate (``estimation.run``: parameter
selection, held constants, global stage, Birge refit, verdict), and on request the MCMC
posterior, a multi-start study (paper Fig. 3) and the GUM uncertainty budget. What a caller
can get wrong (the ``[uncertainty]`` table, unknown names) is checked before the fit.

Progress: every model evaluation reports ``("eval", n)``, each start of the study
``("start", i, n)``, the budget ``("budget",)``; ``should_stop()`` raises ``Cancelled`` at
the next evaluation or start. Units SI.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from ...base.errors import Cancelled, UserError
from ...base.results import Identification
from ..budget import budget_of_problem, uncertainty_table
from .estimation import problem_from_features, run, start_values
from .multistart import distinct_minima, multi_start, random_starts

__all__ = ["identify", "cancellable"]

Progress = Callable[[Any], None]
ShouldStop = Callable[[], bool]


def cancellable(blocks, should_stop: ShouldStop, progress: Progress):
    """Data blocks whose model evaluations report ``("eval", n)`` and raise ``Cancelled``
    once ``should_stop()``."""
    count = {"n": 0}

    def wrap(fn):
        if fn is None:
            return None

        def inner(*a, **kw):
            if should_stop():
                raise Cancelled()
            count["n"] += 1
            progress(("eval", count["n"]))
            return fn(*a, **kw)
        return inner

    return [replace(b, predict=wrap(b.predict), jacobian=wrap(b.jacobian)) for b in blocks]


def identify(doc: Mapping, *, base_dir: str | Path = ".", src: str = "<features>", specimen=None,
             names: Sequence[str] | None = None, start: Mapping[str, float] | None = None, method: str = "lm",
             prior: float | None = None, n_starts: int = 0, seed: int = 0, workers: int = 1, executor=None,
             mcmc: int = 0, budget: bool = False, progress: Progress | None = None,
             should_stop: ShouldStop | None = None) -> Identification:
    """Identify the constants ``names`` (None: what the data constrain) of a features
    document (specimen path relative to ``base_dir``, or ``specimen`` given) from ``start``
    (SI; default nominal) with ``method`` and ``prior`` (``estimation.run``).

    ``n_starts``: also a multi-start study from that many random starts within +-50 % of the
    start (``seed``), on ``workers`` processes or through ``executor`` (a
    ``concurrent.futures.Executor``, e.g. Dask's). ``mcmc``: also the posterior by emcee
    with that many steps per walker. ``budget``: also the GUM uncertainty budget of the
    specimen's ``[uncertainty]`` table (checked before the fit; a budget that fails after
    it leaves ``budget_error`` and never loses the identification)."""
    start = dict(start or {})
    problem = problem_from_features(doc, base_dir=base_dir, src=src, specimen=specimen)
    if budget:
        uncertainty_table(problem.specimen, src)     # a bad table: one line, before the fit
    if should_stop is not None or progress is not None:
        problem.blocks = cancellable(problem.blocks, should_stop or (lambda: False), progress or (lambda obj: None))
    est = run(problem, names, start or None, method=method, prior=prior)
    posterior = None
    if mcmc:
        from engine.fit import sample_posterior  # noqa: PLC0415 - emcee only when asked for
        posterior = sample_posterior(problem.blocks, est, prior=prior if method == "lm" else None, n_steps=mcmc,
                                     seed=seed).to_dict()
    runs: list[dict] = []
    minima: list[dict] = []
    if n_starts:
        st0 = start_values(problem, est.names, {k: v for k, v in start.items() if k in est.names})
        starts = random_starts(st0, est.names, n_starts, seed=seed, problem=problem)
        runs = multi_start(doc, starts, est.names, specimen=problem.specimen, base_dir=base_dir, method=method,
                           prior=prior, executor=executor, max_workers=workers, progress=progress,
                           should_stop=should_stop)
        minima = distinct_minima(runs, est.names)
    bud = err = None
    if budget:
        if progress:
            progress(("budget",))
        try:
            bud = budget_of_problem(problem, est, doc, base_dir)
        except Cancelled:
            raise
        except Exception as e:  # noqa: BLE001 - a failed budget must not lose the identification
            err = str(e) if isinstance(e, UserError) else f"{type(e).__name__}: {e}"
    nominal = problem.nominal
    return Identification(est.to_dict(), problem.kinds, problem.specimen.name,
                          {n: float(nominal[n]) for n in est.names if n in nominal}, bud, err,
                          tuple(runs), tuple(minima), posterior)
