"""A run's shots: averaged in groups when there are many (``stack_shots``, before the picks)
and their curves combined into one (``combine_shots``, after). Moved out of
``engine.wavefeatures.pipeline`` (issue 24, session 28), which re-exports them. Units: m/s, Hz.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .. import waves

__all__ = ["MAX_CURVES", "TARGET_REL", "combine_shots", "stack_shots", "more_shots_note"]


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
    """At most ``max_curves`` records per channel: beyond that, consecutive shots averaged in
    groups of ONE size (aligned on their trigger, as recorded), so every group has the same
    noise: the curves are measured per group and their scatter over the groups gives the sigma
    as over shots (a scatter of groups of 1 and 2 shots mixes two noise levels; issue 24,
    session 28), and each group's noise falls as 1 / sqrt(size), raising the SNR of a weak
    band edge before its pick. The size: from ceil(n / max_curves) up to n // 4 (at least 4
    groups for a scatter), the one that leaves the fewest shots over (then the smallest); the
    shots left over (fewer than a group) are not used and the note says so. Returns the records
    and a note ('' when nothing was averaged)."""
    n = len(shots)
    if n <= max_curves:
        return list(shots), ""
    lo = -(-n // max_curves)
    size = min(range(lo, max(lo, n // 4) + 1), key=lambda g: (n % g, g))
    k = n // size
    out = [{ch: np.mean([shots[j][ch] for j in range(i * size, (i + 1) * size)], axis=0) for ch in shots[0]}
           for i in range(k)]
    left = n - k * size
    return out, (f"{n} wave shots averaged in {k} groups of {size} (aligned on their trigger); curves and their "
                 "scatter from the groups"
                 + (f"; the last {left} shot(s), fewer than a group, not used" if left else ""))


#: the relative sigma more shots should bring a point to: the 1 % the features are held to, at 2 sigma
TARGET_REL = 0.005


def more_shots_note(curve: str, points, held: float = 0.01, target: float = TARGET_REL) -> str:
    """A console line for the points of ``curve`` (e.g. 'S0 along 0 deg') whose sigma exceeds
    ``held`` of their velocity: how many shots per burst would bring each to ``target`` at the
    least, sigma x sqrt(n / N) (the shots' noise alone; on the sweep rig, 3 noise seeds, both
    files, the median sigma fell to 0.58-0.64 of its 2-shot value with 6 shots (sqrt: 0.58) and
    to 0.40-0.56 with 16 (0.35): the bias terms in it do not fall; bench/RESULTS.md, issue 24,
    session 28).
    ``points``: (frequency Hz, sigma / velocity, shots per burst (of the run without a sweep),
    [centre frequencies Hz of the bursts combined in it, none without a sweep]). '' when none
    exceeds."""
    parts = []
    for f, rel, n, bursts in points:
        if not (rel > held and n > 0):
            continue
        need = math.ceil(n * (rel / target) ** 2)
        which = " and ".join(f"{b / 1e3:.4g}" for b in bursts)
        of = f" of the {which} kHz burst{'s' if len(bursts) > 1 else ''}" if bursts else ""
        parts.append(f"{f / 1e3:.0f} kHz: sigma {100 * rel:.1f} % from {n} shots{of}; {100 * target:.1f} % needs "
                     f"{need} or more")
    if not parts:
        return ""
    return (f"more shots: {curve}, " + "; ".join(parts) + f" (sigma x sqrt(shots / N), the shots' noise alone; "
            f"the features are held to {100 * held:.0f} %)")
