"""GUM uncertainty budget of identified constants (JCGM 100:2008, law of propagation).

Type-B inputs x_i (plate thickness, length, width, density, sensor positions, wave path
length...) are held at their nominal values in the fit; they enter it through the model.
With the whitened residual r(p, x) = (y_model(p, x) - y_obs(x)) / sigma and J = dr/dp at
the estimate p*, the normal equations J^T r = 0 keep holding when x moves, so to first
order (implicit function theorem, Gauss-Newton)

    dp* / dx_i = -J^+ dr/dx_i,       J^+ = (J^T J)^-1 J^T.

Input i then contributes |c_ki| u(x_i) to constant k (c = dp*/dx, the sensitivity
coefficient), and the combined standard uncertainty is

    u_c(p_k)^2 = u_A(p_k)^2 + sum_i (c_ki u(x_i))^2

(the type-A part u_A is the fit's own std; inputs uncorrelated with each other and with
the measurement noise). The expanded uncertainty is U = k u_c with coverage factor
k = 2: a coverage probability of about 95 % when p_k is about normally distributed
(GUM 6.2-6.3). Units: those of the parameters and inputs (SI).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from .problem import DataBlock, whitened_jacobian
from .uncertainty import Estimate

__all__ = ["BudgetInput", "Budget", "sensitivity_coefficients", "gum_budget", "COVERAGE_FACTOR", "COVERAGE"]

#: coverage factor of the expanded uncertainty and the coverage it stands for
COVERAGE_FACTOR = 2.0
COVERAGE = "about 95 % (coverage factor k = 2, normal distribution)"


@dataclass(frozen=True)
class BudgetInput:
    """One type-B input: nominal value, standard uncertainty u (same unit), and the
    change of every model-minus-observation value per unit of the input,
    ``d_residual`` (unwhitened, the blocks' units, all blocks concatenated)."""

    name: str
    value: float
    u: float
    unit: str
    d_residual: np.ndarray
    source: str = "default"


@dataclass(frozen=True)
class Budget:
    """Per constant: type-A std, sensitivity coefficients, contributions, u_c and U."""

    names: tuple[str, ...]
    values: np.ndarray
    u_type_a: np.ndarray
    inputs: tuple[BudgetInput, ...]
    sensitivity: np.ndarray          # (n_constants, n_inputs): d p / d x
    contribution: np.ndarray         # (n_constants, n_inputs): |c| u
    u_combined: np.ndarray
    covariance: np.ndarray           # type A + type B, (n, n)
    k: float = COVERAGE_FACTOR
    notes: tuple[str, ...] = field(default=())

    @property
    def u_type_b(self) -> np.ndarray:
        return np.sqrt(np.sum(self.contribution ** 2, axis=1))

    @property
    def expanded(self) -> np.ndarray:
        return self.k * self.u_combined

    def to_dict(self) -> dict:
        """JSON-ready: ``inputs`` (name, value, u, unit, source), per constant the value,
        u_type_a, u_type_b, u_combined, U (expanded), U_rel and the budget table
        ``contributions`` {input: {sensitivity, u (same unit as the constant), share}}."""
        consts = {}
        for j, n in enumerate(self.names):
            uc2 = float(self.u_combined[j]) ** 2
            uc2 = uc2 if np.isfinite(uc2) else 0.0     # undetermined constant: no shares
            rows = {"type A (fit)": {"sensitivity": None, "u": float(self.u_type_a[j]),
                                     "share": float(self.u_type_a[j] ** 2 / uc2) if uc2 > 0 else 0.0}}
            for i, x in enumerate(self.inputs):
                c = float(self.contribution[j, i])
                rows[x.name] = {"sensitivity": float(self.sensitivity[j, i]), "u": c,
                                "share": c * c / uc2 if uc2 > 0 else 0.0}
            v = float(self.values[j])
            consts[n] = {"value": v, "u_type_a": float(self.u_type_a[j]), "u_type_b": float(self.u_type_b[j]),
                         "u_combined": float(self.u_combined[j]), "U": float(self.expanded[j]),
                         "U_rel": float(self.expanded[j] / abs(v)) if v else None,
                         "contributions": rows}
        sd = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = self.covariance / np.outer(sd, sd)
        return {"method": "GUM law of propagation: linearised sensitivities dp/dx = -J^+ dr/dx "
                          "through the fit (JCGM 100:2008)",
                "coverage_factor": self.k, "coverage": COVERAGE,
                "inputs": [{"name": x.name, "value": x.value, "u": x.u, "unit": x.unit, "source": x.source}
                           for x in self.inputs],
                "constants": consts,
                "correlation": {"names": list(self.names), "matrix": np.nan_to_num(corr).tolist()},
                "notes": list(self.notes)}


def sensitivity_coefficients(J: np.ndarray, dr_dx: np.ndarray) -> np.ndarray:
    """``dp/dx = -J^+ dr/dx``: ``J`` (n_data, n_params) and ``dr_dx`` (n_data, n_inputs),
    both whitened; returns (n_params, n_inputs). Least squares (``numpy.linalg.lstsq``)."""
    J = np.asarray(J, float)
    dr = np.asarray(dr_dx, float).reshape(J.shape[0], -1)
    return -np.linalg.lstsq(J, dr, rcond=None)[0]


def gum_budget(blocks: Sequence[DataBlock], est: Estimate, inputs: Sequence[BudgetInput],
               k: float = COVERAGE_FACTOR, notes: Sequence[str] = ()) -> Budget:
    """The budget of ``est`` (fitted on ``blocks``) for the type-B ``inputs``.

    The blocks' sigmas are scaled as the fit scaled them (``est.sigma_scale``, the Birge
    ratio per data kind) so that the weights are those of the estimate.
    """
    scale = est.sigma_scale or {}
    blocks = [replace(b, sigma=b.sigma * scale.get(b.kind, 1.0)) for b in blocks]
    sig = np.concatenate([b.sigma for b in blocks])
    jac = whitened_jacobian(blocks, est.params, est.names, space="linear")
    J = np.vstack([jac[b.name] for b in blocks])
    if inputs:
        dr = np.column_stack([np.asarray(x.d_residual, float) / sig for x in inputs])
        # theta = p / p* (space "linear"): column j of J is p*_j dr/dp_j
        S = sensitivity_coefficients(J, dr) * np.asarray(est.values, float)[:, None]
    else:
        S = np.zeros((len(est.names), 0))
    u = np.array([x.u for x in inputs], float)
    contrib = np.abs(S) * u[None, :]
    uA = np.asarray(est.std, float)
    uc = np.sqrt(uA ** 2 + np.sum(contrib ** 2, axis=1))
    cov = np.asarray(est.cov, float) + (S * u[None, :] ** 2) @ S.T
    return Budget(tuple(est.names), np.asarray(est.values, float), uA, tuple(inputs), S, contrib, uc, cov,
                  float(k), tuple(notes))
