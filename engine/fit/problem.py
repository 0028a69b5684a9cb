"""The whitened least-squares problem every estimator of :mod:`engine.fit` works on.

Every data set is a :class:`DataBlock` holding observations ``y`` (any unit),
their standard deviations ``sigma`` and a forward function
``predict(params) -> y_model`` (optionally with an analytic Jacobian).
Parameters are plain dicts ``{name: value}`` in SI units. :class:`Coords` maps
them to the fitted coordinates theta (``log(p / scale)`` or ``p / scale``);
:class:`Problem` gives the whitened residual ``(y_model - y) / sigma`` of all
blocks and its Jacobian in theta (analytic, forward differences, or Broyden
updates in between).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

__all__ = ["IdentificationError", "DataBlock", "Prior", "Params", "Coords", "check_start",
           "prior_arrays", "Problem", "whitened_jacobian", "linearised_block"]

Params = Mapping[str, float]


class IdentificationError(ValueError):
    """Bad estimator input (unknown parameter, non-positive start, empty data...)."""


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class DataBlock:
    """One data set: observations, their sigmas and a forward model.

    ``predict(params)`` returns the model values (same shape and unit as
    ``observed``). ``jacobian(params, names)``, if given, returns
    ``(predicted, dpred/dp)`` with the derivative in linear parameter units,
    shape ``(n, len(names))``; otherwise forward differences in
    log-parameters are used. ``kind`` groups blocks in the residual report
    (``"modal"`` or ``"waves"``). Forward models may raise ``ValueError``
    for unphysical parameters; the estimators then shorten the step.
    """

    name: str
    observed: np.ndarray
    sigma: np.ndarray
    predict: Callable[[Params], np.ndarray]
    jacobian: Callable[[Params, Sequence[str]], tuple[np.ndarray, np.ndarray]] | None = None
    kind: str = "data"

    def __post_init__(self) -> None:
        y = np.atleast_1d(np.asarray(self.observed, dtype=float))
        s = np.broadcast_to(np.asarray(self.sigma, dtype=float), y.shape).copy()
        if y.ndim != 1 or y.size == 0:
            raise IdentificationError(f"block {self.name!r}: expected a non-empty 1-D array of observations")
        if not np.all(np.isfinite(y)):
            raise IdentificationError(f"block {self.name!r}: observations must be finite")
        if not np.all(np.isfinite(s) & (s > 0)):
            raise IdentificationError(f"block {self.name!r}: sigmas must be positive and finite")
        object.__setattr__(self, "observed", y)
        object.__setattr__(self, "sigma", s)


@dataclass(frozen=True)
class Prior:
    """Independent Gaussian prior on the fitted coordinates.

    ``mean`` in parameter units; ``rel_std`` is the standard deviation of
    log(p) (``space="log"``) or of p / p_start (``space="linear"``): 0.5
    means roughly +-50 %. ``None`` for a parameter means no prior on it.
    """

    mean: Mapping[str, float]
    rel_std: Mapping[str, float | None]

# ---------------------------------------------------------------------------
# parameter maps
# ---------------------------------------------------------------------------
class Coords:
    """theta <-> p: log(p / scale) or p / scale, per parameter."""

    def __init__(self, names: Sequence[str], scale: np.ndarray, space: str):
        if space not in ("log", "linear"):
            raise IdentificationError(f"space={space!r}: expected 'log' or 'linear'")
        self.names, self.scale, self.space = tuple(names), np.asarray(scale, float), space

    def p(self, theta: np.ndarray) -> np.ndarray:
        return self.scale * (np.exp(theta) if self.space == "log" else theta)

    def theta(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        return np.log(p / self.scale) if self.space == "log" else p / self.scale

    def dp_dtheta(self, theta: np.ndarray) -> np.ndarray:
        return self.p(theta) if self.space == "log" else self.scale.copy()

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.p(theta))}


def check_start(names: Sequence[str], start: Params) -> np.ndarray:
    if not names:
        raise IdentificationError("no parameters to identify")
    if len(set(names)) != len(names):
        raise IdentificationError(f"parameters {list(names)} listed twice")
    missing = [n for n in names if n not in start]
    if missing:
        raise IdentificationError(f"no start value for parameter(s) {missing}")
    p0 = np.array([float(start[n]) for n in names])
    bad = [n for n, v in zip(names, p0) if not (np.isfinite(v) and v > 0)]
    if bad:
        raise IdentificationError(f"start value of {bad} = {[start[n] for n in bad]}: expected positive finite values")
    return p0


def prior_arrays(prior: Prior | float | None, coords: Coords, p_start: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(theta_mean, sqrt precision) of the prior; precision 0 means none."""
    k = len(coords.names)
    if prior is None:
        return np.zeros(k), np.zeros(k)
    if isinstance(prior, (int, float)):
        prior = Prior(mean=dict(zip(coords.names, p_start)), rel_std={n: float(prior) for n in coords.names})
    mean = np.array([float(prior.mean.get(n, p)) for n, p in zip(coords.names, p_start)])
    if np.any(mean <= 0):
        raise IdentificationError("prior means must be positive")
    sd = np.array([prior.rel_std.get(n) or 0.0 for n in coords.names], float)
    if np.any(sd < 0):
        raise IdentificationError("prior rel_std must be positive")
    w = np.where(sd > 0, 1.0 / np.where(sd > 0, sd, 1.0), 0.0)
    return coords.theta(mean), w



class Problem:
    """Whitened residual vector and Jacobian over all blocks (theta coords)."""

    def __init__(self, blocks: Sequence[DataBlock], coords: Coords, fd_step: float = 1e-5):
        if not blocks:
            raise IdentificationError("no data to fit")
        self.blocks, self.coords, self.fd_step = tuple(blocks), coords, fd_step
        self.n_eval = 0
        self._last: tuple[np.ndarray, list[np.ndarray]] | None = None
        # quasi-Newton (Broyden) state of finite-difference blocks: theta, y, dy/dtheta
        self._fd_state: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self.quasi_used = False

    def predict(self, theta: np.ndarray) -> list[np.ndarray]:
        par = self.coords.as_dict(theta)
        self.n_eval += 1
        out = []
        for b in self.blocks:
            y = np.asarray(b.predict(par), float)
            if y.shape != b.observed.shape or not np.all(np.isfinite(y)):
                raise ValueError(f"block {b.name!r}: model returned {y.shape} / non-finite values")
            out.append(y)
        self._last = (np.array(theta, float), out)
        return out

    def _cached(self, theta: np.ndarray) -> list[np.ndarray] | None:
        if self._last is not None and np.array_equal(self._last[0], theta):
            return self._last[1]
        return None

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return np.concatenate([(y - b.observed) / b.sigma for b, y in zip(self.blocks, self.predict(theta))])

    def block_jacobians(self, theta: np.ndarray, quasi: bool = False
                        ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Predictions and whitened Jacobians d((y-obs)/sigma)/dtheta per block.

        Blocks without an analytic Jacobian use forward differences (backward
        at the edge of the physical domain); with ``quasi`` their previous
        Jacobian is instead updated by Broyden's rank-one formula from the
        change of predictions (no extra model evaluations).
        """
        par = self.coords.as_dict(theta)
        dpdt = self.coords.dp_dtheta(theta)
        names = self.coords.names
        preds, jacs = [], []
        fd_blocks = []
        cached = self._cached(theta)
        for i, b in enumerate(self.blocks):
            if b.jacobian is not None:
                y, dy = b.jacobian(par, names)
                y, dy = np.asarray(y, float), np.asarray(dy, float).reshape(len(b.observed), len(names))
                preds.append(y); jacs.append(dy * dpdt[None, :] / b.sigma[:, None])
            else:
                preds.append(None); jacs.append(None); fd_blocks.append(i)
        self.n_eval += 1
        self.quasi_used = False
        if not fd_blocks:
            return preds, jacs
        if cached is not None:
            base = {i: cached[i] for i in fd_blocks}
        else:
            base = {i: np.asarray(self.blocks[i].predict(par), float) for i in fd_blocks}
        if quasi and all(i in self._fd_state for i in fd_blocks):
            h = self.fd_step if self.coords.space == "log" else self.fd_step * np.abs(theta).clip(1e-3)
            for i in fd_blocks:
                t0, y0, J0 = self._fd_state[i]
                dt = theta - t0
                nrm = float(dt @ dt)
                # a secant over a step shorter than the difference step is a worse derivative
                # than the one held: the model's own noise over |dt|. Measured on the demo's
                # combined fit: SAFE noise 1e-8 sigma over a 1e-12 LM step put 790 into a
                # Jacobian entry of 3e4, and 30 solves went into damping trials of a model
                # that promised a 0.2 chi^2 decrease where 2e-5 remained
                small = bool(np.all(np.abs(dt) < h))
                J = J0 if (nrm == 0 or small) else J0 + np.outer(base[i] - y0 - J0 @ dt, dt) / nrm
                self._fd_state[i] = (theta.copy(), base[i], J)
                preds[i] = base[i]
                jacs[i] = J / self.blocks[i].sigma[:, None]
            self.quasi_used = True
            return preds, jacs
        h = self.fd_step if self.coords.space == "log" else self.fd_step * np.abs(theta).clip(1e-3)
        h = np.broadcast_to(h, theta.shape)
        cols: dict[int, list[np.ndarray]] = {i: [] for i in fd_blocks}
        for j in range(len(theta)):
            for sgn in (1.0, -1.0):   # backward difference at the edge of the physical domain
                t = theta.copy(); t[j] += sgn * h[j]
                pj = self.coords.as_dict(t)
                self.n_eval += 1
                try:
                    ys = [np.asarray(self.blocks[i].predict(pj), float) for i in fd_blocks]
                    if not all(np.all(np.isfinite(y)) for y in ys):
                        raise ValueError("non-finite model values")
                    break
                except ValueError:
                    if sgn < 0:
                        raise
            for i, y in zip(fd_blocks, ys):
                cols[i].append((y - base[i]) / (sgn * h[j]))
        for i in fd_blocks:
            J = np.column_stack(cols[i])
            self._fd_state[i] = (theta.copy(), base[i], J)
            preds[i] = base[i]
            jacs[i] = J / self.blocks[i].sigma[:, None]
        return preds, jacs


def whitened_jacobian(blocks: Sequence[DataBlock], params: Params, names: Sequence[str],
                      space: str = "log") -> dict[str, np.ndarray]:
    """Whitened sensitivities d((y - obs)/sigma)/d theta per block at ``params``.

    With ``space="log"``, theta = log p, so column j is p_j dy/dp_j / sigma.
    """
    p = check_start(names, params)
    coords = Coords(names, p, space)
    prob = Problem(blocks, coords)
    _, jacs = prob.block_jacobians(coords.theta(p))
    return {b.name: J for b, J in zip(blocks, jacs)}


def linearised_block(block: DataBlock, params: Params, names: Sequence[str],
                     observed: np.ndarray | None = None) -> DataBlock:
    """A block whose model is ``block`` linearised in log-parameters at ``params``.

    ``y(p) = y(p*) + dY/dlog p (log p - log p*)``: exact Gauss-Markov setting
    for calibration studies; ``observed`` replaces the observations.
    """
    J = whitened_jacobian([block], params, names)[block.name] * block.sigma[:, None]
    y0 = np.asarray(block.predict(dict(params)), float)
    lp0 = np.log([params[n] for n in names])

    def predict(par: Params) -> np.ndarray:
        return y0 + J @ (np.log([par[n] for n in names]) - lp0)

    def jacobian(par: Params, nm: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        idx = [list(names).index(n) for n in nm]
        pv = np.array([par[n] for n in nm])
        return predict(par), J[:, idx] / pv[None, :]

    return DataBlock(block.name, block.observed if observed is None else observed, block.sigma,
                     predict, jacobian, block.kind)
