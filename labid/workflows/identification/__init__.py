"""Identification workflow: a features document -> the constants, with their uncertainty.

:mod:`.estimation` builds the problem of a features document (``problem_from_features``:
specimen, data blocks of ``engine.identify.blocks``), chooses what to fit
(``default_params``, ``start_values``, ``parse_assignments``) and runs the estimate with
its stages and verdict (``run``); :mod:`.multistart` repeats it from many starts (paper
Fig. 3: ``random_starts``, ``multi_start``, ``distinct_minima``, ``minima_summary``);
:mod:`.flow` is the one flow every front-end runs (``identify`` -> the typed
``labid.base.results.Identification``; imported from there, not here: it uses
``labid.workflows.budget``, which builds on :mod:`.estimation`); :mod:`.synthetic` makes
features documents from the forward models (tests, benchmarks).

Units SI throughout (Pa, Hz, m/s, kg/m^3).
"""
from __future__ import annotations

from .estimation import (METHODS, Problem, default_params, parse_assignments, problem_from_features, run,
                         start_values)
from .multistart import distinct_minima, minima_summary, multi_start, random_starts
from .synthetic import synthetic_features

__all__ = ["Problem", "problem_from_features", "default_params", "parse_assignments", "run", "start_values",
           "METHODS", "multi_start", "random_starts", "distinct_minima", "minima_summary", "synthetic_features"]
