"""Natural frequencies predicted by the plate model, paired with the measured modes.

* :class:`ModalForward` -- frequencies from ``engine.plate`` with analytic
  sensitivities (d omega^2/dp -> d f/dp = (d omega^2/dp) / (8 pi^2 f)), mode
  pairing by MAC when measured mode shapes are given, otherwise by order with
  a mode-switching check (MAC tracking of the predicted shapes).
* :func:`pair_by_frequency` / :class:`SelectedModes` -- pairing fixed once by
  nearest log-frequency (plus 1 - MAC when a few shape points exist), for the
  gap diagnosis when too few shape points are measured for MAC pairing.
* :func:`modal_block` -- the :class:`~engine.fit.DataBlock` of the estimators.

Units SI: Hz, Pa. Parameters use the contract names (``E1 E2 nu12 G12 G13
G23 density`` or ``E G nu density``).
"""
from __future__ import annotations

import weakref
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np

from ..fit import DataBlock, IdentificationError
from .memo import method_lru
from .pairing import Assignment, assign, match, visibility

__all__ = ["mac", "pair_by_mac", "pair_by_frequency", "ModalSolution", "ModalForward", "SelectedModes",
           "modal_block", "MIN_MAC_POINTS", "PAIR_REL_FREQ", "extra_modes", "params_key", "MODES_KEPT"]

#: fewer shape points than this: measured modes are paired once, at the nominal
#: model, by log-frequency distance / PAIR_REL_FREQ + (1 - MAC) (Hungarian)
MIN_MAC_POINTS = 6
PAIR_REL_FREQ = 0.05


def mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between rows of ``a`` (m, p) and rows of ``b`` (n, p)."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    num = np.abs(a @ b.T) ** 2
    den = np.outer(np.einsum("ij,ij->i", a, a), np.einsum("ij,ij->i", b, b))
    return num / np.where(den > 0, den, np.inf)


def pair_by_mac(measured: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predicted mode index for each measured mode (one-to-one, maximal total MAC).

    Returns ``(index, mac_value)`` arrays of length ``len(measured)``.
    """
    M = mac(measured, predicted)
    idx = match(-M)
    return idx, M[np.arange(M.shape[0]), idx]


def pair_by_frequency(measured_hz, predicted_hz, mac_values: np.ndarray | None = None,
                      rel: float = PAIR_REL_FREQ) -> np.ndarray:
    """Predicted mode index for each measured frequency (one-to-one, Hungarian).

    Cost: |log f_measured - log f_predicted| / ``rel``, plus ``1 - MAC`` when
    ``mac_values`` (measured x predicted) is given; predicted modes may be
    left unpaired (missing measured modes).
    """
    cost = np.abs(np.log(np.asarray(measured_hz, float))[:, None]
                  - np.log(predicted_hz)[None, :]) / rel
    if mac_values is not None:
        cost = cost + 1.0 - mac_values
    return match(cost)


#: parameter sets whose modes a ModalForward keeps (each ~1.4 MB for 56 modes of 3125 DOF)
MODES_KEPT = 8


def params_key(params: Mapping[str, float]) -> tuple:
    """A hashable key of a parameter set (``dict(key)`` gives the set back)."""
    return tuple(sorted((k, float(v)) for k, v in params.items()))


def _weak(obj):
    """A weak reference to ``obj`` (a callable giving None when it cannot be weakly referenced)."""
    try:
        return weakref.ref(obj)
    except TypeError:
        return lambda: None


class ModalSolution(NamedTuple):
    """One evaluation: the model's ``Modes``, the predicted mode index of each
    measured mode, and the pairing warnings of this evaluation."""

    modes: Any
    index: np.ndarray
    warnings: tuple[str, ...] = ()


class ModalForward:
    """Predicted natural frequencies paired with the measured ones.

    ``model`` is an ``engine.plate.PlateModel`` (with any point masses or
    springs already added). With ``points``/``shapes`` (measured mode shapes,
    ``shapes[i][j]`` = mode i at point j) every prediction solves
    ``n_measured + n_extra`` modes and pairs them by MAC; otherwise mode i is
    paired with predicted mode i and a warning reports likely mode switching
    (the predicted shapes no longer match, by MAC, those at the first
    evaluation in the same order).

    State: the last solution (a one-entry cache), the reference shapes of the
    mode-switching check and :attr:`warnings`, the distinct warnings since
    the last :meth:`reset_tracking` (what a fit reports); :attr:`pairing` and
    :attr:`mac_values` are those of the last solution.
    """

    def __init__(self, model, n_measured: int, *, points=None, shapes=None,
                 material: str | None = None, n_extra: int = 4, min_mac: float = 0.6,
                 correction: np.ndarray | None = None, observed=None, sigma=None,
                 response_points=None, drive_points=None, tau0: float = 0.005, labels=None):
        self.model, self.n, self.material = model, int(n_measured), material
        #: likelihood pairing (engine.forward.pairing) when the measured frequencies are
        #: given and no shapes: missing and spurious peaks allowed; the assignment is
        #: fixed between calls of :meth:`repair` (the fit's outer loop), -1 = unexplained
        self.observed = None if observed is None or shapes is not None else np.asarray(observed, float)
        self.sigma_obs = None if sigma is None else np.broadcast_to(np.asarray(sigma, float), (self.n,))
        self.response_points = None if response_points is None else np.asarray(response_points, float)
        self.drive_points = None if drive_points is None else np.asarray(drive_points, float)
        self.tau0 = tau0
        self.labels = None if labels is None else list(labels)
        self.assignment: Assignment | None = None
        self.visible: np.ndarray | None = None
        #: per measured peak, the estimated discretisation error left after the correction (Hz)
        self.model_error_hz: np.ndarray | None = None
        #: per predicted mode (ascending), f_fine / f_model: the discretisation correction
        #: (engine.plate.convergence.mode_corrections); None = the model's own frequencies
        self.correction = None if correction is None else np.asarray(correction, float)
        self.points = None if points is None else np.asarray(points, float)
        self.shapes = None if shapes is None else np.asarray(shapes, float)
        if self.shapes is not None:
            if self.points is None or self.shapes.shape != (self.n, len(self.points)):
                raise IdentificationError(
                    f"mode_shapes: expected values of shape ({self.n}, n_points) with points (n_points, 2)")
        self.n_solve = self.n + (n_extra if self.shapes is not None or self.observed is not None else 0)
        self.min_mac = min_mac
        self._cache: tuple | None = None
        #: the plate model's modes at the last few parameter sets: the fit re-solves the same
        #: constants (Jacobian after a rejected trial, re-pairing, the global stage, the
        #: verdict); measured: 12 of 91 solves of `labid identify` on the demo's features were
        #: repeats (~1.2 s CPU)
        self._modes_of_key = method_lru(self._solve_key, MODES_KEPT)
        #: eigenvalue sensitivities of the last few (constants, names): the fit's last step, its
        #: covariance, the consistency check and the identifiability table ask at the same
        #: estimate; measured on the demo's features: 10 Jacobians, 4 distinct (~0.02 s CPU each)
        self._dlam: dict = {}
        self._ref_shapes: np.ndarray | None = None
        self.warnings: list[str] = []
        self.pairing: np.ndarray = np.arange(self.n)
        self.mac_values: np.ndarray | None = None

    def solve(self, params: Mapping[str, float]) -> ModalSolution:
        """Modes of the model at ``params``, the pairing and its warnings."""
        key = params_key(params)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        modes = self.modes_at(params)
        found: list[str] = []
        if self.shapes is not None:
            pred = self.model.shapes_at(modes, self.points)
            idx, mv = pair_by_mac(self.shapes, pred)
            self.pairing, self.mac_values = idx, mv
            low = np.flatnonzero(mv < self.min_mac)
            if low.size:
                found.append(f"modal: weak MAC pairing for measured mode(s) {low.tolist()} "
                             f"(MAC {np.round(mv[low], 2).tolist()})")
        elif self.observed is not None:
            if self.assignment is None:
                self._assign(modes, self.tau0)
            idx = self.assignment.index
            self.pairing = idx
        else:
            idx = np.arange(self.n)
            phi = modes.shapes[:, :self.n].T
            if self._ref_shapes is None:
                self._ref_shapes = phi
            else:
                best = np.argmax(mac(phi, self._ref_shapes), axis=1)
                moved = np.flatnonzero(best != idx)
                if moved.size:
                    found.append("modal: likely mode switching: predicted mode(s) "
                                 f"{moved.tolist()} now resemble start mode(s) {best[moved].tolist()}; "
                                 "pairing by order may be wrong (supply mode shapes for MAC pairing)")
        for msg in found:
            if msg not in self.warnings:
                self.warnings.append(msg)
        sol = ModalSolution(modes, idx, tuple(found))
        self._cache = (key, sol)
        return sol

    def modes_at(self, params: Mapping[str, float]):
        """The model's ``n_solve`` lowest elastic modes at ``params`` (memoised: the last
        MODES_KEPT parameter sets; the solve is deterministic)."""
        return self._modes_of_key(params_key(params))

    def _solve_key(self, key: tuple):
        return self.model.solve(self.n_solve, params=dict(key), material=self.material)

    @property
    def likelihood_pairing(self) -> bool:
        return self.observed is not None

    def _assign(self, modes, tau: float) -> Assignment:
        if self.response_points is not None and len(self.response_points):
            self.visible = visibility(self.model, modes, self.response_points, self.drive_points)
        a = assign(self.observed, self.sigma_obs if self.sigma_obs is not None else 1e-3 * self.observed,
                   self.corrected_hz(modes), self.visible, tau, fixed=self.labels)
        self.assignment = a
        return a

    def repair(self, params: Mapping[str, float], tau: float) -> bool:
        """Re-pair (likelihood pairing) at ``params`` with relative tolerance ``tau``;
        True when the assignment changed. The cached solution is dropped."""
        old = None if self.assignment is None else self.assignment.index.copy()
        modes = self.modes_at(params)
        a = self._assign(modes, tau)
        self._cache = None
        return old is None or not np.array_equal(old, a.index)

    def repair_fixed(self, index: np.ndarray) -> None:
        """Set the likelihood assignment's peak -> mode index (-1: unexplained) directly."""
        self.assignment = self.assignment._replace(index=np.asarray(index, int))
        self._cache = None

    def repair_fixed_assignment(self, assignment: Assignment) -> None:
        """Restore a whole likelihood assignment (e.g. the one of the best of several fits)."""
        self.assignment, self._cache = assignment, None

    def reset_pairing(self) -> None:
        """Forget the likelihood assignment (the next solve pairs afresh at tau0)."""
        self.assignment, self._cache = None, None

    def reset_tracking(self) -> None:
        """Forget the warnings and the reference shapes of the mode-switching check
        (the next solve becomes the reference), e.g. before a new fit."""
        self.warnings.clear()
        self._ref_shapes = None

    def corrected_hz(self, modes) -> np.ndarray:
        """Frequencies (Hz) of ``modes`` (ascending) with the discretisation correction."""
        f = modes.frequencies_hz
        if self.correction is None:
            return f
        c = np.ones(f.size)
        k = min(f.size, self.correction.size)
        c[:k] = self.correction[:k]
        return f * c

    def predict(self, params: Mapping[str, float]) -> np.ndarray:
        sol = self.solve(params)
        idx = sol.index
        f = self.corrected_hz(sol.modes)[np.maximum(idx, 0)]
        if self.observed is not None:   # an unexplained peak predicts itself (no residual)
            f = np.where(idx >= 0, f, self.observed)
        return f

    def jacobian(self, params: Mapping[str, float], names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        modes, idx, _ = self.solve(params)
        ok = idx >= 0
        j = np.maximum(idx, 0)
        key = (params_key(params), tuple(names))
        hit = self._dlam.get(key)
        if hit is None or hit[0]() is not modes:    # the same Modes object: the same solve
            hit = (_weak(modes), self.model.eigen_sensitivities(modes, list(names), params=dict(params),
                                                                material=self.material))
            if key not in self._dlam and len(self._dlam) >= MODES_KEPT:
                self._dlam.pop(next(iter(self._dlam)))
            self._dlam[key] = hit
        dlam = hit[1][j]
        f0 = modes.frequencies_hz[j]
        f = self.corrected_hz(modes)[j]
        J = (f / f0)[:, None] * dlam / (8.0 * np.pi ** 2 * f0)[:, None]
        if not ok.all():
            f = np.where(ok, f, self.observed)
            J[~ok] = 0.0
        return f, J


class SelectedModes:
    """A :class:`ModalForward` over n + extra modes (by order) restricted to a fixed
    selection ``sel`` (one predicted mode index per measured mode)."""

    def __init__(self, inner: ModalForward, sel: np.ndarray):
        self.inner, self.sel, self.model = inner, sel, inner.model

    def predict(self, params):
        return self.inner.predict(params)[self.sel]

    def jacobian(self, params, names):
        f, J = self.inner.jacobian(params, names)
        return f[self.sel], J[self.sel]

    def solve(self, params) -> ModalSolution:
        sol = self.inner.solve(params)
        return ModalSolution(sol.modes, sol.index[self.sel], sol.warnings)


def extra_modes(n_measured: int, n_extra: int = 4) -> int:
    """Predicted modes solved beyond the measured count under likelihood pairing (room
    for missing modes: at least 8, a quarter of the peaks)."""
    return max(n_extra, 8 + n_measured // 4)


def modal_block(model, frequencies_hz, sigma_hz, *, points=None, shapes=None,
                material: str | None = None, name: str = "modal", n_extra: int = 4,
                correction: np.ndarray | None = None, model_error_rel: np.ndarray | None = None,
                pairing: str = "order", response_points=None, drive_points=None, labels=None
                ) -> tuple[DataBlock, ModalForward]:
    """Natural-frequency data block (Hz) and its forward model (for warnings/pairing).

    ``correction`` (per predicted mode, ascending): f_fine / f_model, applied to every
    prediction; ``model_error_rel`` (same length): the relative error remaining after it,
    added in quadrature to each measured mode's sigma: the largest error among the predicted
    modes of the same rank and the two above (missing modes only move a peak's partner up).
    ``pairing``: ``order`` (mode i with predicted mode i) or ``likelihood``
    (:mod:`engine.forward.pairing`, with the modes' visibility at ``response_points`` and
    ``drive_points``, m; ``labels``: per peak a predicted mode index or None, kept fixed);
    ignored when ``shapes`` are given (MAC)."""
    f = np.asarray(frequencies_hz, float)
    sig = np.broadcast_to(np.asarray(sigma_hz, float), f.shape)
    like = pairing == "likelihood" and shapes is None
    fwd = ModalForward(model, len(f), points=points, shapes=shapes, material=material,
                       n_extra=n_extra if not like else extra_modes(len(f), n_extra),
                       correction=correction, observed=f if like else None, sigma=sig if like else None,
                       response_points=response_points, drive_points=drive_points, labels=labels)
    if model_error_rel is not None:
        err = np.asarray(model_error_rel, float)
        # the error of the measured mode's most likely partner: the mode of the same rank
        # or above (missing modes only push the partner up); the max over ranks i..i+2
        rank = np.argsort(np.argsort(f))
        e = np.array([err[min(r, err.size - 1):min(r + 3, err.size)].max() for r in rank])
        sig = np.sqrt(sig ** 2 + (e * f) ** 2)
        fwd.model_error_hz = e * f     # systematic (same sign for every mode): see identify.py
    if like:
        fwd.sigma_obs = sig
    return DataBlock(name, f, sig, fwd.predict, fwd.jacobian, kind="modal"), fwd
