"""How many BLAS/OpenMP threads labid's maths libraries may use.

labid's linear algebra is small (147-DOF SAFE models, 1875-DOF plate blocks,
80x80 element matrices): BLAS threads cost more than they give there, and on
a machine where anything else runs they oversubscribe the cores (measured in
``bench/RESULTS.md``: ``labid identify`` 22.3 s wall with default threads,
4.9 s with one). labid therefore decides its own threading, at every entry
point (the command line and the panel, process and Dask workers, the test
suite), in this order of precedence:

1. ``--threads N`` on the command line;
2. the ``LABID_THREADS`` environment variable;
3. any of the standard variables (``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``,
   ``MKL_NUM_THREADS``, ...) that the user set: labid then leaves threading to
   them;
4. otherwise one thread per process.

Where labid decides, it sets the standard variables for libraries loaded later
and for child processes, and limits the libraries already loaded with
``threadpoolctl``. Before numpy is imported no BLAS/OpenMP library is loaded (labid
loads them through numpy): the variables are then enough, and the command line decides
that early (``labid.cli.main``), sparing threadpoolctl's import and library scan
(~5-8 ms of ``labid dispersion``'s ~0.35 s CPU; issue 29, session 26). Parallelism that pays is explicit: processes
(multi-start, ``--workers``), never BLAS threads.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass

from .errors import UserError

#: the variables BLAS and OpenMP runtimes read at load time
STANDARD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                 "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
DEFAULT_THREADS = 1


@dataclass(frozen=True)
class ThreadChoice:
    """The decision: ``threads`` per process (None: left to the user's variables) and why."""

    threads: int | None
    source: str     # "--threads", "LABID_THREADS", "environment" or "default"


def _parse(value: object, key: str) -> int:
    try:
        n = int(str(value).strip())
    except ValueError:
        n = 0
    if n < 1:
        raise UserError(f"value {value!r}: expected a whole number of threads >= 1", key=key)
    return n


def decide(threads: int | None = None, environ: os._Environ | dict | None = None) -> ThreadChoice:
    """The thread count labid will use, by the precedence in the module docstring."""
    env = os.environ if environ is None else environ
    if threads is not None:
        return ThreadChoice(_parse(threads, "--threads"), "--threads")
    if env.get("LABID_THREADS", "").strip():
        return ThreadChoice(_parse(env["LABID_THREADS"], "LABID_THREADS"), "LABID_THREADS")
    if any(env.get(v, "").strip() for v in STANDARD_VARS):
        return ThreadChoice(None, "environment")
    return ThreadChoice(DEFAULT_THREADS, "default")


_applied: int | None = None
_at_load: int | None = None     # the count applied before numpy (and so any BLAS) was loaded


def apply(threads: int) -> None:
    """Limit every BLAS/OpenMP library to ``threads``, now and for later loads and children."""
    global _applied, _at_load
    for v in STANDARD_VARS:
        os.environ[v] = str(threads)
    if "numpy" not in sys.modules:              # nothing loaded yet: the variables are read at load
        _at_load = threads
    elif _at_load != threads:                   # loaded under another count: limit them now
        from threadpoolctl import threadpool_limits
        threadpool_limits(limits=threads)
        _at_load = None
    _applied = threads


def configure(threads: int | None = None) -> ThreadChoice:
    """Decide (``decide``) and apply; returns the choice. Called by every entry point."""
    choice = decide(threads)
    if choice.threads is not None:
        apply(choice.threads)
    return choice


def worker_init(threads: int | None) -> None:
    """Initializer of worker processes (process pools, Dask tasks): apply once per process."""
    if threads is not None and _applied != threads:
        apply(threads)


def for_workers() -> int | None:
    """Threads for worker processes: what this process applied, else the decision
    (None: the user's variables, which the workers inherit)."""
    return _applied if _applied is not None else decide().threads
