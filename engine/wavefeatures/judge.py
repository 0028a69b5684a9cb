"""Where a pick's foreign-packet test is judged: at a time its own noise does not move.

``picks.arrivals_of`` drops a pick when a foreign packet could shift it by more than
``max_bias`` of the travel time (or reaches ``leak_db`` of its level), and otherwise adds the
bound to its sigma. The excitation's crosstalk (``crosstalk.bound_in``) decays after the drive,
so judged at the pick's own time the test keeps the picks that noise moved later and drops
those it moved earlier: where the test is marginal the kept picks are late, the velocities
slow. Measured on the sweep rig's 100 kHz burst (bench/bench_s0_edge.py, issue 24, session
29): S0 along 0 deg at 86-88 kHz (the burst's S0 band edge, 24-25 dB per 2-shot group, the
crosstalk test marginal) the kept picks were 0.36 +- 0.10 us later than the noise-free ones
(-0.8 % of the velocity at 40 cm), the reported 94-96 kHz points -0.43 +- 0.20 % against
+0.5 % noise-free. Judged at the target's predicted time (the stage-2 prediction, smooth over
the band: the same for every noise draw to first order) the decision no longer selects on the
pick's noise. Units: s, Hz, any amplitude unit.
"""
from __future__ import annotations

import numpy as np

__all__ = ["crosstalk_at"]


def crosstalk_at(xtalk_row: np.ndarray, level: float, t_judge: float, fs_hz: float, st: float
                 ) -> tuple[float, float]:
    """(relative level, shift bound in s) of the crosstalk bound ``xtalk_row`` (|W| on the
    record's sample grid, one analysis frequency) on a packet of peak ``level`` and amplitude
    time-std ``st``: its level and slope taken at ``t_judge`` (s from the row's first sample),
    the shift bound st^2 |dA/dt| / level + 0.7 st A / level (as for a foreign packet)."""
    k = min(max(int(round(t_judge * fs_hz)), 1), xtalk_row.size - 2)
    ax = float(xtalk_row[k - 1:k + 2].max())
    dax = float(np.abs(np.diff(xtalk_row[k - 1:k + 2])).max()) * fs_hz
    return ax / level, (st * st * dax + 0.7 * st * ax) / level
