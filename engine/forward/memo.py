"""Per-instance memo of a method, without a reference cycle.

``self._f = lru_cache(n)(self._method)`` makes a cycle (instance -> cache -> bound method
-> instance): the instance, and every plate model, matrix and mode set its cache holds, is
then freed only when Python's cyclic collector next runs, not when the last reference goes.
In a gap diagnosis, whose refits make a forward model per trial effect, that kept ~30 dead
plate models alive at once (a 3-constant sensor-mass diagnosis at 347 MiB peak RSS, 6 models
alive after ``gc.collect()``; bench/RESULTS.md, issue 29 session 24). :func:`method_lru`
holds the method weakly, so reference counting frees the instance and its cache at once.
"""
from __future__ import annotations

import weakref
from functools import lru_cache
from typing import Callable

__all__ = ["method_lru"]


def method_lru(method, maxsize: int) -> Callable:
    """``functools.lru_cache(maxsize)`` of the bound ``method``, holding its instance weakly."""
    ref = weakref.WeakMethod(method)

    def call(*args):
        return ref()(*args)
    return lru_cache(maxsize=maxsize)(call)
