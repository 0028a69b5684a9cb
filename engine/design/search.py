"""Where to put the accelerometers and where to tap: a coordinate-exchange search.

Candidate points are a grid on the plate inside an edge margin, away from the supports.
A layout is ``ns`` sensor points and one tap point, at least ``min_gap`` apart (a sensor
cannot be struck, two sensors cannot share a spot). The search (coordinate exchange,
Meyer & Nachtsheim 1995) moves one element at a time to the candidate that lowers the
robust criterion most (``engine.design.fisher.criterion``: every candidate of that
element is evaluated in one vectorised call), pass after pass until no move helps; it
starts from the user's layout (when given), from a spread layout and from a few random
ones, and keeps the best. Units: m.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .fisher import DesignProblem, criterion, evaluate

__all__ = ["candidate_grid", "Layout", "optimise", "snap", "MAX_PASSES"]

MAX_PASSES = 8


def candidate_grid(length: float, width: float, n: int, margin: float,
                   keepout: Sequence[tuple[float, float]] = (), keepout_r: float = 0.0) -> np.ndarray:
    """(C, 2) points of an n x n grid over [margin, L - margin] x [margin, W - margin] (m),
    without those within ``keepout_r`` of a ``keepout`` point (supports)."""
    if not (0 <= margin < 0.5 * min(length, width)):
        raise ValueError(f"edge margin {margin!r} m: expected 0 <= margin < half the shorter side")
    xs = np.linspace(margin, length - margin, n)
    ys = np.linspace(margin, width - margin, n)
    pts = np.array([[x, y] for y in ys for x in xs])
    if len(keepout) and keepout_r > 0:
        k = np.asarray(keepout, float)
        d = np.hypot(pts[:, None, 0] - k[None, :, 0], pts[:, None, 1] - k[None, :, 1]).min(axis=1)
        pts = pts[d >= keepout_r]
    return pts


@dataclass(frozen=True)
class Layout:
    """Sensor and tap point indices (into the problem's points) and the criterion value."""

    sensors: tuple[int, ...]
    tap: int
    value: float = np.inf

    def elements(self) -> list[int]:
        return list(self.sensors) + [self.tap]


def snap(points: np.ndarray, xy: Sequence[float], allowed: np.ndarray) -> int:
    """Index of the allowed point nearest to ``xy``."""
    d = np.hypot(points[:, 0] - xy[0], points[:, 1] - xy[1])
    d = np.where(allowed, d, np.inf)
    return int(np.argmin(d))


def _value(prob: DesignProblem, sensors, tap, kind: str) -> float:
    return float(criterion(evaluate(prob, [list(sensors)], [tap]), kind)[0])


def _exchange(prob: DesignProblem, layout: Layout, allowed: np.ndarray, dist: np.ndarray, min_gap: float,
              kind: str, should_stop: Callable[[], bool] | None) -> Layout:
    sensors, tap = list(layout.sensors), layout.tap
    best = _value(prob, sensors, tap, kind)
    for _ in range(MAX_PASSES):
        improved = False
        for k in range(len(sensors) + 1):
            if should_stop is not None and should_stop():
                return Layout(tuple(sensors), tap, best)
            others = [e for j, e in enumerate(sensors + [tap]) if j != k]
            ok = allowed & (dist[:, others] >= min_gap).all(axis=1) if others else allowed.copy()
            cand = np.flatnonzero(ok)
            if cand.size == 0:
                continue
            if k < len(sensors):
                S = np.array(sensors)[None, :].repeat(cand.size, 0)
                S[:, k] = cand
                vals = criterion(evaluate(prob, S, np.full(cand.size, tap)), kind)
            else:
                vals = criterion(evaluate(prob, np.array(sensors)[None, :].repeat(cand.size, 0), cand), kind)
            j = int(np.argmin(vals))
            if vals[j] < best - 1e-9 * max(1.0, abs(best)):
                best = float(vals[j])
                if k < len(sensors):
                    sensors[k] = int(cand[j])
                else:
                    tap = int(cand[j])
                improved = True
        if not improved:
            break
    return Layout(tuple(sensors), tap, best)


def _spread(points: np.ndarray, allowed: np.ndarray, ns: int, dist: np.ndarray, min_gap: float) -> Layout | None:
    """Sensors as far apart as possible (farthest-point), the tap at the allowed point
    nearest (0.3 L, 0.2 W) of the candidates' box, off the sensors."""
    idx = np.flatnonzero(allowed)
    lo, hi = points[idx].min(axis=0), points[idx].max(axis=0)
    first = idx[np.argmin(np.hypot(*(points[idx] - lo).T))]
    sensors = [int(first)]
    while len(sensors) < ns:
        d = dist[idx][:, sensors].min(axis=1)
        if d.max() < min_gap:
            return None
        sensors.append(int(idx[np.argmax(d)]))
    ok = allowed & (dist[:, sensors] >= min_gap).all(axis=1)
    if not ok.any():
        return None
    tap = snap(points, lo + np.array([0.3, 0.2]) * (hi - lo), ok)
    return Layout(tuple(sensors), tap)


def _random(rng, allowed: np.ndarray, ns: int, dist: np.ndarray, min_gap: float) -> Layout | None:
    chosen: list[int] = []
    for _ in range(ns + 1):
        ok = allowed & (dist[:, chosen] >= min_gap).all(axis=1) if chosen else allowed
        c = np.flatnonzero(ok)
        if c.size == 0:
            return None
        chosen.append(int(rng.choice(c)))
    return Layout(tuple(chosen[:-1]), chosen[-1])


def optimise(prob: DesignProblem, n_sensors: int, allowed, *, min_gap: float = 0.02, kind: str = "MV",
             starts: Sequence[Layout] = (), n_random: int = 2, seed: int = 0,
             should_stop: Callable[[], bool] | None = None) -> tuple[Layout, list[Layout]]:
    """The best layout found and every start's end point (best first). ``allowed`` (C,) marks
    the candidate points (the problem's points beyond them, e.g. the user's exact positions,
    are never chosen)."""
    pts = prob.mset.points
    allowed = np.asarray(allowed, bool)
    dist = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])
    inits = list(starts)
    sp = _spread(pts, allowed, n_sensors, dist, min_gap)
    if sp is not None:
        inits.append(sp)
    rng = np.random.default_rng(seed)
    for _ in range(n_random):
        r = _random(rng, allowed, n_sensors, dist, min_gap)
        if r is not None:
            inits.append(r)
    if not inits:
        raise ValueError(f"no room for {n_sensors} sensors and a tap {min_gap:g} m apart on the candidate grid")
    ends = [_exchange(prob, s, allowed, dist, min_gap, kind, should_stop) for s in inits]
    ends.sort(key=lambda l: l.value)
    return ends[0], ends
