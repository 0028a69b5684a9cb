"""Whitened residuals of the measured features against the forward model (with effects).

:class:`GapFit` whitens the features by their sigmas plus a small
model-discretisation allowance (``model_rel_sigma``: relative, modal and
waves) and gives the residual vector, its Jacobian in log-constants, and the
``engine.fit`` data blocks of the constants' fit.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ..features import Features
from ..fit import DataBlock
from ..forward import F_REF, ForwardModel, temperature_params

__all__ = ["GapError", "GapFit"]


class GapError(ValueError):
    """Bad diagnosis input (no data, unknown effect, inconsistent arrays)."""


class GapFit:
    """Whitened residual machinery around one forward model.

    ``model_rel_sigma`` = (modal, waves) relative model allowance added in
    quadrature to the measured sigmas; ``model_sigma`` (absolute, one per
    feature, e.g. the per-mode discretisation error) is added in quadrature
    too. ``names``: the constants fitted (default: every modulus and Poisson
    ratio of the material).
    """

    def __init__(self, problem: Features, fw: ForwardModel, model_rel_sigma: tuple[float, float],
                 names=None, model_sigma: np.ndarray | None = None):
        self.problem, self.fw = problem, fw
        self.model_rel_sigma = tuple(model_rel_sigma)
        #: per predicted mode, the discretisation correction (engine.gap.convergence.ModeCorrection;
        #: None: uncorrected), kept to re-pair under an effect (engine.gap.repair)
        self.mode_correction = None
        y = fw.observed
        sig = fw.sigma
        nm = fw.n_modal
        rel = np.concatenate([np.full(nm, model_rel_sigma[0]),
                              np.full(len(y) - nm, model_rel_sigma[1])])
        extra = np.zeros_like(y) if model_sigma is None else np.asarray(model_sigma, float)
        self.y, self.sigma_measured = y, sig
        self.sigma = np.sqrt(sig ** 2 + (rel * y) ** 2 + extra ** 2)
        self.names = tuple(names) if names else problem.param_names()
        mat = problem.material_obj.params()
        self.nominal = {n: mat[n] for n in self.names}
        #: peaks identify left unexplained (no residual, no Jacobian row), or None
        self.unexplained = getattr(fw, "unexplained", None)
        #: the same problem on the discretisation check's finer mesh, built when first needed
        #: (engine.gap.convergence.under_effect)
        self.fine_forward = None

    def residual(self, params, effects) -> np.ndarray:
        r = (self.fw.predict(params, effects) - self.y) / self.sigma
        if self.unexplained is not None:
            r[:len(self.unexplained)][self.unexplained] = 0.0
        if not np.all(np.isfinite(r)):
            raise GapError("model undefined (a wave mode absent) for these constants/effects")
        return r

    def jacobian(self, params: Mapping[str, float], effects: Mapping[str, float],
                 fd_step: float = 1e-5, waves: bool = True) -> np.ndarray:
        """Whitened d residual / d log p: analytic modal rows, forward differences for waves
        (``waves=False``: the modal rows only)."""
        fw, nm, names = self.fw, self.fw.n_modal, self.names
        parts = []
        if nm:
            pT = temperature_params(params, effects.get("temperature", 0.0))
            mf = fw.modal_forward_with(effects) if hasattr(fw, "modal_forward_with") else fw.modal_forward(
                effects.get("sensor_mass", 0.0), effects.get("support_stiffness", 0.0),
                effects.get("thickness", 0.0))
            f0, dfdp = mf.jacobian(pT, list(names))
            Jm = dfdp * np.array([pT[n] for n in names])[None, :]
            eta = effects.get("viscoelastic", 0.0)
            if eta:
                g = 1.0 / (1.0 - eta / np.pi)
                fo = F_REF * (f0 / F_REF) ** g
                Jm = Jm * (g * fo / f0)[:, None]
            Jm = Jm / self.sigma[:nm, None]
            if self.unexplained is not None:
                Jm[self.unexplained] = 0.0
            parts.append(Jm)
        if len(self.y) > nm and waves:
            base = np.concatenate(fw.predict_waves(params, effects))
            cols = []
            for n_ in names:
                col = np.zeros_like(base)
                for h in (fd_step, -fd_step):      # backward where the forward step leaves the admissible region
                    p2 = dict(params)
                    p2[n_] = params[n_] * math.exp(h)
                    try:
                        col = (np.concatenate(fw.predict_waves(p2, effects)) - base) / h
                        break
                    except ValueError:
                        continue
                cols.append(col)
            Jw = np.column_stack(cols) / self.sigma[nm:, None]
            parts.append(np.where(np.isfinite(Jw), Jw, 0.0))
        return np.vstack(parts) if parts else np.zeros((0, len(names)))

    def blocks(self, raw: bool = False) -> list[DataBlock]:
        """Modal and wave blocks of the nominal model (no effect), whitened sigmas
        (``raw``: the measured sigmas alone, as ``labid identify`` weighs them)."""
        fw, nm = self.fw, self.fw.n_modal
        sigma = self.sigma_measured if raw else self.sigma
        out = []
        if nm:
            def jac(p, names):     # with the discretisation correction, as predict_modal has it
                f, J = fw.modal_forward().jacobian(dict(p), list(names))
                corr = getattr(fw, "peak_correction", None)
                return (f, J) if corr is None else (f * corr, J * corr[:, None])
            out.append(DataBlock("modal", self.y[:nm], sigma[:nm],
                                 lambda p: fw.predict_modal(p, {}), jac, kind="modal"))
        if len(self.y) > nm:
            def wpredict(p):
                y = np.concatenate(fw.predict_waves(p, {}))
                if not np.all(np.isfinite(y)):
                    raise GapError("group velocity undefined (mode absent) for these constants")
                return y

            def wjac(p, names):
                y = wpredict(p)
                cols = []
                for n_ in names:
                    p2 = dict(p)
                    p2[n_] = p[n_] * math.exp(1e-5)
                    try:
                        c_ = (np.concatenate(fw.predict_waves(p2, {})) - y) / (1e-5 * p[n_])
                    except ValueError:
                        c_ = np.zeros_like(y)
                    cols.append(np.where(np.isfinite(c_), c_, 0.0))
                return y, np.column_stack(cols)
            out.append(DataBlock("waves", self.y[nm:], sigma[nm:], wpredict, wjac, kind="waves"))
        return out
