"""Pairing measured peaks with predicted modes when peaks are missing or spurious.

A peak list from a real plate is neither complete nor clean: a mode with a nodal line
at the response point (or the hammer point) is not seen, and a peak may come from
something else (a suspension mode, a harmonic, noise). :func:`assign` compares every
candidate assignment by its likelihood with penalties:

* a peak i paired with predicted mode j costs ``((f_i - f_j) / s_i)^2`` with
  ``s_i^2 = sigma_i^2 + (tau f_i)^2`` (``tau``: the relative tolerance of the model at
  the current constants, large at a datasheet start, small near the optimum);
* a peak left unexplained costs ``SPURIOUS`` (a 4-sigma pairing would cost as much);
* a predicted mode inside the measured band that no peak explains costs
  ``MISS * min(1, (v_j / V_SEEN)^2)``, ``v_j`` its :func:`visibility` at the response
  (and drive) points: a mode with a node there is *expected* to be missing (cost ~0),
  one with a large response is not (cost MISS); MISS_UNKNOWN when no response point
  is known.

The minimum is found exactly as a rectangular assignment problem (Hungarian,
``scipy.optimize.linear_sum_assignment``): columns are the predicted modes (cost
minus their miss penalty) plus one "unexplained" column per peak.

Units: Hz; visibility is dimensionless (0 to 1).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["Assignment", "assign", "miss_penalties", "visibility", "SPURIOUS", "MISS", "MISS_UNKNOWN", "V_SEEN", "GRID"]

#: cost (chi^2 units) of a peak no predicted mode explains
SPURIOUS = 16.0
#: cost of skipping a predicted in-band mode with a full response at the sensor
MISS = 25.0
#: the same when the visibility is unknown (no response point declared): a skip costs 3 sigma
MISS_UNKNOWN = 9.0
#: relative response (amplitude at the points / peak amplitude on the plate) above which a
#: mode counts as fully visible
V_SEEN = 0.25
#: grid (per direction) on which a mode's peak amplitude over the plate is sampled
GRID = 15


class Assignment(NamedTuple):
    """``index[i]``: predicted mode of peak i (-1: unexplained); ``skipped``: predicted
    in-band modes no peak explains; ``cost``: the total penalised misfit."""

    index: np.ndarray
    skipped: np.ndarray
    cost: float


def visibility(model, modes, response_points, drive_points=None, length: float | None = None,
               width: float | None = None) -> np.ndarray:
    """Per mode of ``modes`` (a ``PlateModel``'s): the largest |w| at ``response_points``
    (m, (k, 2)) over the peak |w| on a GRID x GRID grid of the plate, times the same
    ratio at the drive point (the best of ``drive_points``) when given."""
    L = length if length is not None else model.mesh.length
    W = width if width is not None else model.mesh.width
    xs, ys = np.linspace(0, L, GRID), np.linspace(0, W, GRID)
    grid = np.array([[x, y] for x in xs for y in ys])
    peak = np.abs(model.shapes_at(modes, grid)).max(axis=1)
    peak = np.where(peak > 0, peak, np.inf)
    v = np.abs(model.shapes_at(modes, np.asarray(response_points, float))).max(axis=1) / peak
    if drive_points is not None and len(drive_points):
        v = v * np.abs(model.shapes_at(modes, np.asarray(drive_points, float))).max(axis=1) / peak
    return np.clip(v, 0.0, 1.0)


def miss_penalties(predicted_hz, highest_peak_hz: float, visible=None, tau: float = 0.01,
                   miss: float = MISS) -> np.ndarray:
    """Per predicted mode, the cost of no peak explaining it: ``miss`` x min(1, (v / V_SEEN)^2)
    for a mode in band (below the highest peak by more than 3 tolerances), MISS_UNKNOWN
    without visibilities; 0 out of band."""
    fp = np.asarray(predicted_hz, float)
    in_band = fp < highest_peak_hz * (1.0 - 3.0 * tau)
    if visible is None:
        return np.where(in_band, MISS_UNKNOWN if miss == MISS else miss, 0.0)
    return np.where(in_band, miss * np.minimum(1.0, (np.asarray(visible, float) / V_SEEN) ** 2), 0.0)


def assign(measured_hz, sigma_hz, predicted_hz, visible=None, tau: float = 0.01, *,
           spurious: float = SPURIOUS, miss: float = MISS, fixed=None) -> Assignment:
    """The most likely pairing of measured peaks with predicted modes (module docstring).

    ``visible``: per predicted mode, its visibility (None: every mode fully visible).
    A predicted mode is in band when below the highest peak by more than 3 tolerances.
    ``fixed``: per peak a predicted mode index (0-based) it must pair with, or None
    (labels from the features, ``modal.mode_index``).
    """
    f = np.asarray(measured_hz, float)
    s = np.broadcast_to(np.asarray(sigma_hz, float), f.shape)
    fp = np.asarray(predicted_hz, float)
    n, m = f.size, fp.size
    sp = np.sqrt(s ** 2 + (tau * f) ** 2)
    pair = ((f[:, None] - fp[None, :]) / sp[:, None]) ** 2
    in_band = fp < f.max() * (1.0 - 3.0 * tau)
    pen = miss_penalties(fp, f.max(), visible, tau, miss)
    big = 1e12
    cost = np.full((n, m + n), big)
    cost[:, :m] = np.minimum(pair - pen[None, :], big)
    cost[np.arange(n), m + np.arange(n)] = spurious
    for i, j in enumerate(fixed if fixed is not None else ()):
        if j is not None and 0 <= int(j) < m:
            keep = cost[i, int(j)]
            cost[i, :] = big
            cost[:, int(j)] = big
            cost[i, int(j)] = keep
    rows, cols = linear_sum_assignment(cost)
    idx = np.full(n, -1)
    paired = cols < m
    idx[rows[paired]] = cols[paired]
    total = float(cost[rows, cols].sum() + pen.sum())
    skipped = np.array(sorted(set(np.flatnonzero(in_band).tolist()) - set(idx[idx >= 0].tolist())), int)
    return Assignment(idx, skipped, total)
