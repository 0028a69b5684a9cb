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
    signature per unit magnitude (first order); ``magnitude_linear`` / ``chi2_linear``
    the screened fit of the effect alone (linear, or quadratic when screened with a
    second evaluation); ``refit`` the joint refit, if done.
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


def _points(spec, a_ref: float) -> tuple[float, float]:
    """Two magnitudes (offsets from the reference) inside the range to fit a quadratic signature:
    +typical and -typical for a signed range, else +typical and +2 typical (or +typical/2)."""
    h = spec.typical
    lo, hi = spec.lo - a_ref, spec.hi - a_ref
    a1 = h if h <= hi else -h
    if lo <= -h and a1 > 0:
        return a1, -h
    return a1, (2.0 * a1 if lo <= 2.0 * a1 <= hi else 0.5 * a1)


def _best_magnitude(u: np.ndarray, v: np.ndarray, w: np.ndarray, lo: float, hi: float) -> tuple[float, float]:
    """argmin and min over a in [lo, hi] of |u + a v + a^2 w|^2 (a quartic: stationary points and ends)."""
    c = [4.0 * (w @ w), 6.0 * (v @ w), 2.0 * (v @ v + 2.0 * u @ w), 2.0 * (u @ v)]
    cand = [lo, hi] + [float(z.real) for z in np.roots(c) if abs(z.imag) < 1e-9 * (1.0 + abs(z)) and lo < z.real < hi]

    def chi(a):
        r = u + a * v + a * a * w
        return float(r @ r)
    best = min(cand, key=chi)
    return best, chi(best)


def screen(name: str, F: GapFit, p_hat: Mapping[str, float], r0: np.ndarray, Ja: np.ndarray,
           names: Sequence[str], detect_sigma: float, quadratic: bool = False) -> Candidate:
    """Signature, absorption, detectability and screened magnitude of effect ``name`` at the
    fitted constants ``p_hat`` (r0: whitened residual there; Ja: the constants' whitened
    Jacobian with the prior rows below).

    Linear screen (one evaluation at the typical magnitude): the secant signature. With
    ``quadratic`` (when there is a gap to attribute) a second evaluation fits
    d(a) = a s1 + a^2 s2: second-order effects (a density gradient, a taper, a misalignment of
    a mirror-symmetric layup: even in a, zero slope at 0) are screened by their true shape
    instead of a secant that misjudges them (issue 28); magnitude and chi^2 are the minimum
    over the plausible range of |r0 + a s1' + a^2 s2'|^2 (primes: the part the constants
    cannot absorb), detectability the largest |a s1' + a^2 s2'| over the range."""
    spec = EFFECTS[name]
    n, k = len(r0), len(names)
    a_ref = reference(name, F.problem)
    a1, a2 = _points(spec, a_ref)
    lo, hi = spec.lo - a_ref, spec.hi - a_ref
    try:
        d1 = F.residual(p_hat, {name: a_ref + a1}) - r0
        d2 = F.residual(p_hat, {name: a_ref + a2}) - r0 if quadratic else None
    except (ValueError, KeyError) as exc:
        return Candidate(name, error=str(exc))
    if d2 is None:
        s1, s2 = d1 / a1, np.zeros(n)
    else:            # d(a) = a s1 + a^2 s2 through both points
        det = a1 * a2 * a2 - a2 * a1 * a1
        s1 = (d1 * a2 * a2 - d2 * a1 * a1) / det
        s2 = (a1 * d2 - a2 * d1) / det
    zeros = np.zeros(k)
    c = np.linalg.lstsq(Ja, np.concatenate([s1, zeros]), rcond=1e-12)[0]
    P = lambda s: (np.concatenate([s, zeros]) - Ja @ np.linalg.lstsq(Ja, np.concatenate([s, zeros]),  # noqa: E731
                                                                      rcond=1e-12)[0])[:n]
    s1p, s2p = P(s1), P(s2)
    sec = d1 / a1                                     # the secant: what the constants absorb per unit
    ns, np_ = float(np.linalg.norm(sec)), float(np.linalg.norm(P(sec)))
    grid = np.linspace(lo, hi, 65)
    reach = float(max(np.linalg.norm(a * s1p + a * a * s2p) for a in grid)) if d2 is not None \
        else np_ * max(abs(lo), abs(hi))
    a_best, chi_best = _best_magnitude(r0, s1p, s2p, lo, hi)
    return Candidate(
        name=name, unit=spec.unit, signature_norm=ns, unabsorbed_norm=np_,
        absorbed_fraction=1.0 - (np_ / ns) ** 2 if ns > 0 else 1.0,
        detectable=bool(reach >= detect_sigma),
        bias_per_unit={nm_: float(np.expm1(ci) if abs(ci) < 50 else ci) for nm_, ci in zip(names, c)},
        absorbed=c, signature=s1, magnitude_linear=a_ref + a_best, chi2_linear=chi_best)
