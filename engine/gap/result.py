"""The diagnosis result: frozen dataclasses and the JSON document of ``labid diagnose``.

:class:`GapResult` (``to_dict()``: CONTRACT section 3 keys first) holds the gap figures
(:class:`GapFigures`), the ranked candidates (:class:`RankedEffect`, with the refitted
constants and their std), the confusable groups (:class:`ConfusableGroup`: effects the data
cannot tell apart and what would separate them), the undetectable effects
(:class:`Undetectable`), the constants before/after (:class:`ConstantsChange`) and the
per-feature residuals (:class:`FeatureResiduals`). Units SI; gap figures are rms whitened
residuals (1 = noise level).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Mapping

import numpy as np

from .start import StartEstimate
from .where import GroupStat

__all__ = ["GapFigures", "RankedEffect", "Undetectable", "ConstantsChange", "FeatureResiduals",
           "ConfusableGroup", "GapResult"]


@dataclass(frozen=True)
class GapFigures:
    """The gap before and after the chosen effect (rms residual/sigma), chi^2 test figures."""

    before: float
    after: float
    held_out_before: float
    held_out_after: float
    chi2_before: float
    chi2_after: float
    dof: float
    n: int
    p_value_before: float
    p_value_after: float
    threshold_chi2: float
    false_alarm_rate: float
    significant: bool
    unit: str = "rms of residual/sigma (1 = noise level)"

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class RankedEffect:
    """One candidate in the ranking (``std``, ``held_out_after``, ``constants_after``,
    ``constants_std``, ``iterations`` only when refitted). ``flags``: constants the refit
    moved far while the data determine them weakly (issue 28: nu12 +136 % under a taper)."""

    name: str
    magnitude: float
    std: float | None
    unit: str
    gap_after: float
    score: float
    delta_chi2: float
    refitted: bool
    held_out_after: float | None
    detectable: bool
    absorbed_fraction: float
    bias_in_constants_per_unit: Mapping[str, float]
    constants_after: Mapping[str, float] | None
    iterations: int | None
    converged: bool | None = None
    constants_std: Mapping[str, float] | None = None
    flags: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        d = asdict(self)
        d["flags"] = list(self.flags)
        return d


@dataclass(frozen=True)
class Undetectable:
    """An effect the constants absorb, with the bias it puts into them per unit magnitude."""

    name: str
    absorbed_fraction: float
    unit: str
    bias_in_constants_per_unit: Mapping[str, float]

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class ConstantsChange:
    """Fitted constants without effect (and their std), and with the chosen effect (SI)."""

    before: Mapping[str, float]
    before_std: Mapping[str, float]
    after: Mapping[str, float]
    relative_change: Mapping[str, float]

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class FeatureResiduals:
    """Per feature: label, modality, set, whitened residual before/after, sigma; mode families."""

    labels: tuple[str, ...]
    modality: tuple[str, ...]
    set: tuple[str, ...]
    residual_before: np.ndarray
    residual_after: np.ndarray
    sigma: np.ndarray
    mode_families: tuple[str, ...] | None

    def to_dict(self) -> dict:
        return {"labels": list(self.labels), "modality": list(self.modality), "set": list(self.set),
                "residual_before": self.residual_before.tolist(),
                "residual_after": self.residual_after.tolist(), "sigma": self.sigma.tolist(),
                "mode_families": None if self.mode_families is None else list(self.mode_families)}


@dataclass(frozen=True)
class ConfusableGroup:
    """Library effects that explain the data about equally well (chi^2 within ``delta_chi2``
    of the best, each accepted), the known look-alikes outside the library, and what
    measurement would separate them."""

    effects: tuple[str, ...]
    delta_chi2: Mapping[str, float]
    separate_by: tuple[str, ...]
    outside_library: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {"effects": list(self.effects), "delta_chi2": dict(self.delta_chi2),
                "separate_by": list(self.separate_by), "outside_library": list(self.outside_library)}


@dataclass(frozen=True)
class GapResult:
    """The diagnosis (see module docstring); :meth:`to_dict` gives the JSON document."""

    gap: GapFigures
    where: tuple[str, ...]
    where_detail: tuple[GroupStat, ...]
    effects: tuple[RankedEffect, ...]
    verdict: str
    confusable: tuple[str, ...]
    undetectable: tuple[Undetectable, ...]
    errors: Mapping[str, str]
    groups: tuple[GroupStat, ...]
    constants: ConstantsChange
    features: FeatureResiduals
    converged: bool
    message: str
    start: StartEstimate | None = None
    pairing: dict | None = None
    model_sigma: np.ndarray | None = None
    notes: tuple[str, ...] = ()
    #: the peak pairing the chosen result uses: "identify" (identify's own), "order", "mac",
    #: or "re-paired under EFFECT" (engine.gap.repair)
    pairing_used: str = ""
    #: the verdict's confusable group(s) (verdict ``insufficient_data``: empty)
    confusable_groups: tuple[ConfusableGroup, ...] = ()
    #: verdict ``insufficient_data``: why, then what to add (one remedy per item)
    advice: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        st = self.start
        return {
            "gap": self.gap.to_dict(),
            "where": list(self.where),
            "where_detail": [g.to_dict() for g in self.where_detail],
            "effects": [e.to_dict() for e in self.effects],
            "verdict": self.verdict,
            "confusable": list(self.confusable),
            "undetectable": [u.to_dict() for u in self.undetectable],
            "errors": dict(self.errors),
            "groups": [g.to_dict() for g in self.groups],
            "constants": self.constants.to_dict(),
            "features": self.features.to_dict(),
            "identification": {
                "converged": self.converged, "message": self.message,
                "source": None if st is None else st.source,
                "parameters": None if st is None else list(st.names),
                "prior_rel_std": None if st is None else st.prior_rel_std,
                "pairing": None if st is None else st.pairing,
                "pairing_used": self.pairing_used},
            "pairing": self.pairing,
            "model_sigma_hz": None if self.model_sigma is None else self.model_sigma.tolist(),
            "diagnosis_notes": list(self.notes),
            "confusable_groups": [g.to_dict() for g in self.confusable_groups],
            "advice": list(self.advice),
        }
