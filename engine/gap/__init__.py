"""Sim-to-real gap diagnosis of measured features (``engine.features.Features``).

Public seam:

* :mod:`.diagnose`: ``diagnose(features, options, forward) -> GapResult``
  (frozen; ``to_dict()`` is the JSON of ``labid diagnose``), ``GapOptions``,
  ``gap_test`` and the result parts ``GapFigures``, ``RankedEffect``,
  ``Undetectable``, ``ConstantsChange``, ``FeatureResiduals``;
* :mod:`.where`: ``feature_labels``, ``GroupStat`` (and the grouping/fold helpers);
* :mod:`.candidates`: ``Candidate``, ``screen`` (signatures, detectability);
* :mod:`.refit`: ``refit``, ``Refit`` (joint refit of constants and one effect);
* :mod:`.residuals`: ``GapFit`` (whitened residuals/Jacobian), ``GapError``.

The effect registry is ``engine.forward.EFFECTS``.
"""
from .candidates import Candidate, screen
from .diagnose import (ConstantsChange, FeatureResiduals, GapFigures, GapOptions, GapResult, RankedEffect,
                       Undetectable, diagnose, gap_test)
from .refit import Refit, RefitError, refit
from .residuals import GapError, GapFit
from .where import GroupStat, feature_labels

__all__ = ["diagnose", "GapOptions", "GapResult", "GapFigures", "RankedEffect", "Undetectable",
           "ConstantsChange", "FeatureResiduals", "gap_test", "feature_labels", "GroupStat", "Candidate",
           "screen", "Refit", "RefitError", "refit", "GapFit", "GapError"]
