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

This module is the project's one matcher and one visibility: :func:`match` (a cost matrix,
optionally an "unexplained" cost per row -> one column per row or -1) is the Hungarian step
of :func:`assign`, of ``engine.forward.modal.pair_by_mac`` / ``pair_by_frequency`` and of
``engine.gap.pairing.propose_pairing``; :func:`visibility` (on a GRID x GRID grid) serves the
identification's pairing and the gap diagnosis alike.

Units: Hz; visibility is dimensionless (0 to 1).
"""
from __future__ import annotations

import importlib.machinery
import importlib.util
import os
import sys
from typing import NamedTuple

import numpy as np
import scipy

__all__ = ["Assignment", "assign", "match", "miss_penalties", "visibility", "SPURIOUS", "MISS", "MISS_UNKNOWN",
           "V_SEEN", "GRID", "BIG"]

#: cost (chi^2 units) of a peak no predicted mode explains
SPURIOUS = 16.0
#: cost of skipping a predicted in-band mode with a full response at the sensor
MISS = 25.0
#: the same when the visibility is unknown (no response point declared): a skip costs 3 sigma
MISS_UNKNOWN = 9.0
#: relative response (amplitude at the points / peak amplitude on the plate) above which a
#: mode counts as fully visible
V_SEEN = 0.25
#: grid (per direction) on which a mode's peak amplitude over the plate is sampled: 21
#: (was 15 here and 21 in the gap diagnosis). Measured against a 141 x 141 grid over the first
#: 56 modes: the 15-grid peak was up to 16 % low (CFRP, 11 modes below 99 %), the 21-grid peak
#: up to 11 % low (6 modes)
GRID = 21
#: the cost of a forbidden pair (never chosen while another assignment exists)
BIG = 1e12


def _linear_sum_assignment():
    """``scipy.optimize.linear_sum_assignment``, without importing the ``scipy.optimize``
    package when it is not loaded yet: the function is its compiled module ``_lsap``, while the
    package's ``__init__`` loads linprog, shgo, scipy.spatial, scipy.fft and the rest, ~0.15-0.3 s
    CPU of every ``labid identify`` whose default path used nothing else from it (bench/RESULTS.md,
    issue 29 session 27). The module is registered under its own name, so a later
    ``import scipy.optimize`` uses this very module; the public import whenever the file is
    not where scipy keeps it."""
    name = "scipy.optimize._lsap"
    mod = sys.modules.get(name)
    if mod is None and "scipy.optimize" not in sys.modules:
        folder = os.path.join(os.path.dirname(scipy.__file__), "optimize")
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = os.path.join(folder, "_lsap" + suffix)
            if os.path.isfile(path):
                try:
                    spec = importlib.util.spec_from_file_location(name, path)
                    mod = importlib.util.module_from_spec(spec)
                    spec.loader.exec_module(mod)
                except ImportError:
                    mod = None
                else:
                    sys.modules[name] = mod
                break
    if mod is None or not hasattr(mod, "linear_sum_assignment"):
        from scipy.optimize import linear_sum_assignment  # noqa: PLC0415
        return linear_sum_assignment
    return mod.linear_sum_assignment


linear_sum_assignment = _linear_sum_assignment()


class Assignment(NamedTuple):
    """``index[i]``: predicted mode of peak i (-1: unexplained); ``skipped``: predicted
    in-band modes no peak explains; ``cost``: the total penalised misfit."""

    index: np.ndarray
    skipped: np.ndarray
    cost: float


def match(cost, unexplained=None) -> np.ndarray:
    """The one-to-one assignment of rows (measured) to columns (predicted) of least total
    ``cost`` (n, m) (Hungarian, ``scipy.optimize.linear_sum_assignment``): per row its
    column, -1 when it is left unpaired. ``unexplained`` (a number or one per row): the cost
    of leaving a row unpaired (one extra column per row; BIG forbids it); None: every row
    is paired while columns last."""
    cost = np.asarray(cost, float)
    n, m = cost.shape
    if unexplained is not None:
        full = np.full((n, m + n), BIG)
        full[:, :m] = cost
        full[np.arange(n), m + np.arange(n)] = np.broadcast_to(np.asarray(unexplained, float), (n,))
        cost = full
    rows, cols = linear_sum_assignment(cost)
    idx = np.full(n, -1)
    paired = cols < m
    idx[rows[paired]] = cols[paired]
    return idx


def visibility(model, modes, response_points, drive_points=None, length: float | None = None,
               width: float | None = None) -> np.ndarray:
    """Per mode of ``modes`` (a ``PlateModel``'s): the largest |w| at ``response_points``
    (m, (k, 2)) over the peak |w| on a GRID x GRID grid of the plate (corners and edges
    included), times the same ratio at the drive point (the best of ``drive_points``)
    when given; 1 for every mode without response points."""
    L = length if length is not None else model.mesh.length
    W = width if width is not None else model.mesh.width
    if response_points is None or not len(response_points):
        return np.ones(len(modes.frequencies_hz))
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
    cost = np.minimum(pair - pen[None, :], BIG)
    unexplained = np.full(n, float(spurious))
    for i, j in enumerate(fixed if fixed is not None else ()):
        if j is not None and 0 <= int(j) < m:
            keep = cost[i, int(j)]
            cost[i, :] = BIG
            unexplained[i] = BIG
            cost[:, int(j)] = BIG
            cost[i, int(j)] = keep
    idx = match(cost, unexplained)
    rows = np.arange(n)
    total = float(np.where(idx >= 0, cost[rows, np.maximum(idx, 0)], unexplained).sum() + pen.sum())
    skipped = np.array(sorted(set(np.flatnonzero(in_band).tolist()) - set(idx[idx >= 0].tolist())), int)
    return Assignment(idx, skipped, total)
