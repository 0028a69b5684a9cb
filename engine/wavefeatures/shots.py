"""A run's shots: averaged in groups when there are many (``stack_shots``, before the picks)
and their curves combined into one (``combine_shots``, after). Moved out of
``engine.wavefeatures.pipeline`` (issue 24, session 28), which re-exports them. Units: m/s, Hz.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from .. import waves

__all__ = ["MAX_CURVES", "combine_shots", "stack_shots"]


def combine_shots(curves: list[waves.GroupVelocity], floor: np.ndarray | None = None) -> waves.GroupVelocity:
    """Mean over shots; sigma: the scatter over shots / sqrt(n), not below the mean
    per-shot sigma / sqrt(n) (a single shot: its own sigma), with ``floor`` (a bias
    term, m/s) added in quadrature. A frequency is valid where more than half the shots
    measured it: at the ends of a reassigned range the one shot whose noise moved its
    instantaneous frequency furthest would give the point alone (issue 24, session 27: a
    sweep's S0 90 kHz +7.3 % was one shot's, with 2 and with 12 shots; the 12 shots' mean
    delays there lie within 0.3 % of the true plate's)."""
    f = curves[0].frequencies_hz
    V = np.array([c.velocity_m_s for c in curves])
    S = np.array([c.sigma_m_s for c in curves])
    ok = np.isfinite(V) & np.isfinite(S) & (S > 0)
    n = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(n > 0, np.where(ok, V, 0.0).sum(axis=0) / np.maximum(n, 1), np.nan)
        scatter = np.sqrt(np.where(ok, (V - v) ** 2, 0.0).sum(axis=0) / np.maximum(n - 1, 1))
        noise = np.where(ok, S, 0.0).sum(axis=0) / np.maximum(n, 1)
        s = np.where(n > 1, np.maximum(scatter, noise), noise) / np.sqrt(np.maximum(n, 1))
    if floor is not None:
        s = np.hypot(s, np.where(np.isfinite(floor), floor, 0.0))
    valid = 2 * n > len(curves)
    return waves.GroupVelocity(f, np.where(valid, v, np.nan), np.where(valid, s, np.nan), valid)


MAX_CURVES = 12     # shots beyond this are averaged in groups (bench/RESULTS.md, issue 24: cost)


def stack_shots(shots: Sequence[Mapping[str, np.ndarray]], max_curves: int = MAX_CURVES):
    """At most ``max_curves`` records per channel: consecutive shots averaged in equal groups
    (aligned on their trigger, as recorded) when there are more. The curves are then measured
    per group; their scatter over the groups gives the sigma, as over shots (the group means
    are independent), and the noise of each falls as 1 / sqrt(group size). Returns the records
    and a note ('' when nothing was averaged)."""
    n = len(shots)
    if n <= max_curves:
        return list(shots), ""
    edges = np.linspace(0, n, max_curves + 1).round().astype(int)
    out = [{ch: np.mean([shots[k][ch] for k in range(a, b)], axis=0) for ch in shots[a]}
           for a, b in zip(edges[:-1], edges[1:])]
    return out, (f"{n} wave shots averaged in {max_curves} groups of {n // max_curves}-{-(-n // max_curves)} "
                 "(aligned on their trigger); curves and their scatter from the groups")
