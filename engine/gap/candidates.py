"""Candidate effects: whitened signatures, what the constants absorb, detectability.

Every candidate effect (``engine.forward.EFFECTS``) gives a whitened
signature s (secant at its typical magnitude). Projected on the orthogonal
complement of the constants' whitened Jacobian (prior rows included),
s_perp is what the constants cannot absorb; |s_perp| * range below
``detect_sigma`` means *undetectable*, reported with the bias the absorbed
effect puts into the constants (per unit magnitude). The linear estimate of
the magnitude (clipped to the plausible range) and its chi^2 rank the
candidates for the joint refit (:mod:`engine.gap.refit`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..features import Features
from ..forward import EFFECTS
from .refit import Refit
from .residuals import GapFit

__all__ = ["Candidate", "reference", "applies", "screen"]


@dataclass(frozen=True)
class Candidate:
    """One candidate effect after screening (``error`` set: it could not be evaluated).

    ``absorbed`` are the coefficients of the signature on the constants'
    columns (log-constants per unit magnitude), ``signature`` the whitened
    signature per unit magnitude; ``magnitude_linear`` / ``chi2_linear`` the
    linearised fit of the effect alone; ``refit`` the joint refit, if done.
    """

    name: str
    error: str | None = None
    unit: str = ""
    signature_norm: float = 0.0
    unabsorbed_norm: float = 0.0
    absorbed_fraction: float = 1.0
    detectable: bool = False
    bias_per_unit: Mapping[str, float] = field(default_factory=dict)
    absorbed: np.ndarray | None = None
    signature: np.ndarray | None = None
    magnitude_linear: float = 0.0
    chi2_linear: float = float("inf")
    refit: Refit | None = None

    @property
    def chi2(self) -> float:
        """chi^2 after the joint refit, else the linearised one."""
        return self.refit.chi2 if self.refit is not None else self.chi2_linear

    @property
    def cost(self) -> float:
        """chi^2 plus the pairing penalty a re-paired refit added: what ranks the candidates
        (the chi^2 test uses :attr:`chi2` alone: a penalty is a prior on the pairing, not misfit)."""
        return self.chi2 + (self.refit.penalty if self.refit is not None else 0.0)


def reference(name: str, problem: Features) -> float:
    """Effect value meaning 'absent' (the nominal sensor length for the aperture)."""
    return float(problem.rig.sensor_length_m) if name == "sensor_aperture" else 0.0


def applies(name: str, problem: Features) -> bool:
    """Whether the features hold a modality the effect acts on."""
    return any((m == "modal" and problem.modal is not None) or (m == "waves" and problem.waves)
               for m in EFFECTS[name].modalities)


def screen(name: str, F: GapFit, p_hat: Mapping[str, float], r0: np.ndarray, Ja: np.ndarray,
           names: Sequence[str], detect_sigma: float) -> Candidate:
    """Signature, absorption, detectability and linear magnitude of effect ``name``
    at the fitted constants ``p_hat`` (r0: whitened residual there; Ja: the
    constants' whitened Jacobian with the prior rows below)."""
    spec = EFFECTS[name]
    n, k = len(r0), len(names)
    a_ref = reference(name, F.problem)
    h = spec.typical
    try:
        s = (F.residual(p_hat, {name: a_ref + h}) - r0) / h
    except (ValueError, KeyError) as exc:
        return Candidate(name, error=str(exc))
    sa = np.concatenate([s, np.zeros(k)])
    c = np.linalg.lstsq(Ja, sa, rcond=1e-12)[0]
    sp = sa - Ja @ c
    ns, np_ = float(np.linalg.norm(s)), float(np.linalg.norm(sp))
    reach = max(abs(spec.lo - a_ref), abs(spec.hi - a_ref))
    detectable = np_ * reach >= detect_sigma
    a_lin = float(-(sp[:n] @ r0) / np_ ** 2) if np_ > 0 else 0.0
    a_lin = float(np.clip(a_ref + a_lin, spec.lo, spec.hi) - a_ref)
    chi_lin = float(np.sum((r0 + a_lin * sp[:n]) ** 2))
    return Candidate(
        name=name, unit=spec.unit, signature_norm=ns, unabsorbed_norm=np_,
        absorbed_fraction=1.0 - (np_ / ns) ** 2 if ns > 0 else 1.0,
        detectable=bool(detectable),
        bias_per_unit={nm_: float(np.expm1(ci) if abs(ci) < 50 else ci) for nm_, ci in zip(names, c)},
        absorbed=c, signature=s, magnitude_linear=a_ref + a_lin, chi2_linear=chi_lin)
