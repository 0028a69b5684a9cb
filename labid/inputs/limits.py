"""Bounds of what the models can hold, checked where inputs enter (issue 15): one line
naming the option and the limit instead of an allocation of petabytes or an hour of
eigenvalue solves. Physical bounds of file values live with their parsers
(``labid.inputs.specimen.LIMITS``, ``labid.inputs.features.LIMITS``)."""
from __future__ import annotations

import math

from engine.laminate import Laminate
from engine.safe import default_discretisation

from ..base.errors import UserError

#: highest frequency of a SAFE dispersion computation, Hz
MAX_FMAX_HZ = 1e8
#: lowest, Hz (below it every guided wave is a rigid-body motion of the plate)
MIN_FMAX_HZ = 1.0
#: through-thickness nodes of a SAFE model (3 DOF each; ~1,000 DOF solve in seconds)
MAX_SAFE_NODES = 300


def safe_nodes(laminate: Laminate, fmax_hz: float) -> int:
    """Through-thickness nodes of the SAFE model that resolves ``fmax_hz`` (``default_discretisation``)."""
    order, per_ply = default_discretisation(laminate, fmax_hz)
    return len(laminate.plies) * per_ply * order + 1


def check_fmax(laminate: Laminate, fmax_hz: float, key: str = "--fmax", src: str | None = None) -> float:
    """UserError unless ``fmax_hz`` is finite, within [MIN_FMAX_HZ, MAX_FMAX_HZ] and held by
    a SAFE model of at most MAX_SAFE_NODES nodes through the thickness."""
    if not (isinstance(fmax_hz, (int, float)) and math.isfinite(fmax_hz)
            and MIN_FMAX_HZ <= fmax_hz <= MAX_FMAX_HZ):
        raise UserError(f"value {fmax_hz!r}: expected a frequency in [{MIN_FMAX_HZ:g}, {MAX_FMAX_HZ:g}] Hz",
                        file=src, key=key)
    n = safe_nodes(laminate, fmax_hz)
    if n > MAX_SAFE_NODES:
        raise UserError(f"value {fmax_hz:g} Hz: the through-thickness model would need {n} nodes "
                        f"(limit {MAX_SAFE_NODES}); expected a lower frequency for this "
                        f"{laminate.thickness * 1e3:g} mm plate", file=src, key=key)
    return float(fmax_hz)
