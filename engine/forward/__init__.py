"""Forward models: the measured features predicted from elastic constants (and effects).

Public seam:

* :mod:`.modal`: ``ModalForward`` (frequencies paired with the measured modes;
  ``solve`` returns a ``ModalSolution``: modes, pairing, warnings), ``SelectedModes``,
  ``mac``, ``pair_by_mac``, ``pair_by_frequency``, ``modal_block``;
* :mod:`.pairing`: ``assign`` (likelihood pairing of peaks with predicted modes, missing
  and spurious peaks allowed), ``visibility``, ``Assignment``;
* :mod:`.waves`: ``wave_block``, ``SafeWaves`` (memoised SAFE velocities);
* :mod:`.effects`: the single registry of unmodelled effects ``EFFECTS``
  (``EffectSpec``: unit, plausible range, typical magnitude, modalities, doc),
  their shared physics (``ALPHA_*``, ``F_REF``, ``temperature_params``,
  ``log_sinc_slope``) and ``EffectError``;
* :mod:`.model`: ``ForwardModel``, every feature of an ``engine.features.Features``
  for constants plus effects (the gap diagnosis and the blind-case generator).

``modal_block`` / ``wave_block`` give the ``engine.fit.DataBlock`` s of the
identification.
"""
from .effects import (ALPHA_FIBRE, ALPHA_ISOTROPIC, ALPHA_MATRIX, EFFECTS, F_REF, EffectError, EffectSpec,
                      log_sinc_slope, temperature_params)
from .modal import (ModalForward, ModalSolution, SelectedModes, mac, modal_block, pair_by_frequency,
                    pair_by_mac)
from .model import ForwardModel
from .pairing import Assignment, assign, visibility
from .waves import SafeWaves, wave_block

__all__ = ["ModalForward", "ModalSolution", "SelectedModes", "mac", "pair_by_mac", "pair_by_frequency",
           "modal_block", "wave_block", "Assignment", "assign", "visibility", "SafeWaves", "ForwardModel", "EFFECTS", "EffectSpec", "EffectError",
           "ALPHA_FIBRE", "ALPHA_MATRIX", "ALPHA_ISOTROPIC", "F_REF", "temperature_params", "log_sinc_slope"]
