"""One shot's picks remembered per direction (issue 29: the cost of the wave analysis).

The wavelet choice (``engine.wavefeatures.pipeline``, step 6) measures the first shot of every
candidate wavelet in both stages; the chosen wavelets then redo exactly those, and the
centre-frequency sweep of the wavelet bias is often a candidate too. A shot's picks depend only
on its record, the wavelet and the direction's state (stage, predictions' scales and margins,
source-onset range): ``key``. They are kept in ``Direction.memo`` with the onset they leave in
``Direction.t0``, so a repeated measurement returns the same objects, bit for bit. Stage 1 and
stage 2 of one wavelet also share the first shot's scalograms (``shot_cache``).
"""
from __future__ import annotations

import numpy as np

from .. import waves
from .picks import Direction

__all__ = ["key", "shot_cache", "keep"]

_SHOT0 = "first shot's scalograms"


def key(d: Direction, wl: waves.Wavelet, j: int) -> tuple:
    """What shot ``j``'s picks depend on besides its record."""
    def arr(v):
        return None if v is None else np.asarray(v, float).tobytes()
    return (wl, j, d.strict, tuple(d.t0), None if d.t0_prior is None else tuple(d.t0_prior),
            tuple(sorted((m, arr(v)) for m, v in d.scale.items())), tuple(sorted(d.margin.items())))


def shot_cache(d: Direction, wl: waves.Wavelet, j: int) -> dict:
    """A fresh per-shot cache; for the first shot, holding the scalograms (and the source's
    arrivals) its last measurement with this wavelet left."""
    if j == 0 and d.memo.get(_SHOT0, (None,))[0] == wl:
        return dict(d.memo[_SHOT0][1])
    return {}


def keep(d: Direction, k: tuple, value: tuple, cache: dict) -> None:
    """Remember a shot's picks; for the first shot also its cache's entries that depend on the
    record and the wavelet alone (not the crosstalk terms, which depend on the onset), for
    one wavelet at a time (memory: a scalogram is nf x n complex)."""
    d.memo[k] = value
    if k[1] == 0:
        d.memo[_SHOT0] = (k[0], {c: v for c, v in cache.items() if c[0] not in ("drive", "xt")})
