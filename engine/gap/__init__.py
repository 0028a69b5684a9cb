"""Sim-to-real gap diagnosis of measured features (``engine.features.Features``).

Public seam:

* :mod:`.diagnose`: ``diagnose(features, options, forward) -> GapResult``
  (frozen; ``to_dict()`` is the JSON of ``labid diagnose``), ``GapOptions``,
  ``gap_test``; the result parts (:mod:`.result`) ``GapFigures``, ``RankedEffect``,
  ``Undetectable``, ``ConstantsChange``, ``FeatureResiduals``, ``ConfusableGroup``;
* :mod:`.verdict`: ``insufficient``, ``decide``, ``group``, ``ranking`` (the verdict rules);
* :mod:`.where`: ``feature_labels``, ``GroupStat`` (and the grouping/fold helpers);
* :mod:`.candidates`: ``Candidate``, ``screen`` (signatures, detectability);
* :mod:`.refit`: ``refit``, ``Refit`` (joint refit of constants and one effect);
* :mod:`.residuals`: ``GapFit`` (whitened residuals/Jacobian), ``GapError``;
* :mod:`.start`: ``StartEstimate`` (identify's estimate, the diagnosis' start), ``own_estimate``;
* :mod:`.forward`: ``GapForward`` (``ForwardModel`` + real-plate effects, fixed pairing);
* :mod:`.pairing`: ``pairing_check``, ``propose_pairing`` (pairing as a cause);
* :mod:`.convergence`: ``peak_corrections`` (the identification's per-mode mesh correction and error).

The effect registry is ``engine.forward.EFFECTS``.
"""
from .candidates import Candidate, screen
from .diagnose import (ConfusableGroup, ConstantsChange, FeatureResiduals, GapFigures, GapOptions, GapResult,
                       RankedEffect, Undetectable, diagnose, gap_test)
from .refit import Refit, RefitError, refit
from .residuals import GapError, GapFit
from .where import GroupStat, feature_labels
from .start import StartEstimate, own_estimate
from .forward import GapForward
from .pairing import PairingCheck, pairing_check, propose_pairing
from .convergence import peak_corrections

__all__ = ["diagnose", "GapOptions", "GapResult", "GapFigures", "RankedEffect", "Undetectable", "ConfusableGroup",
           "ConstantsChange", "FeatureResiduals", "gap_test", "feature_labels", "GroupStat", "Candidate",
           "screen", "Refit", "RefitError", "refit", "GapFit", "GapError", "StartEstimate", "own_estimate",
           "GapForward", "PairingCheck", "pairing_check", "propose_pairing", "peak_corrections"]
