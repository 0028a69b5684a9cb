"""Keys and bounds of the measured-features file (``labid.inputs.features``): the keys each
section may hold (an unknown key is an error naming it) and the bounds of values
where they enter."""
from __future__ import annotations

import math
from typing import Any

from ..base.errors import UserError

TOP_KEYS = {"specimen", "modal", "waves", "rig", "analysis", "damping"}   # damping: written by labid analyze (labid.workflows.damping), free-form
MODAL_KEYS = {"frequencies_hz", "sigma_hz", "damping_ratio", "confidence", "mode_shapes", "mode_index"}
SHAPES_KEYS = {"points", "values"}
WAVE_KEYS = {"mode", "direction_deg", "frequency_hz", "group_velocity_m_s", "sigma_m_s", "dropped"}
RIG_KEYS = {"temperature_c", "accelerometers", "supports", "wave_path_m", "sensor_length_m", "wavelet"}
#: (low, high) bounds where values enter (SI): frequencies 1 mHz-10 MHz, velocities up to
#: 100 km/s, rig paths and positions within 1 km, temperatures -273.15..1000 C,
#: angles within one turn either way, at most 2,000 values per list and 200 modal
#: frequencies (what the plate model is asked to solve, as ``labid modes --n``)
LIMITS = {"frequency_hz": (1e-3, 1e7), "sigma_hz": (0.0, 1e7), "velocity_m_s": (0.0, 1e5), "length_m": (0.0, 1e3),
          "temperature_c": (-273.15, 1000.0), "angle_deg": (-360.0, 360.0), "mass_kg": (0.0, 1e3),
          "n_values": 2000, "n_modes": 200}
MAX_SPECIMEN_BYTES = 1 << 20


def within(v: float, kind: str, key: str, src: str) -> float:
    lo, hi = LIMITS[kind]
    if not (math.isnan(v) or lo <= v <= hi):
        raise UserError(f"value {v:g}: outside [{lo:g}, {hi:g}] ({kind})", file=src, key=key)
    return v


def mode_index(v: Any, n: int, src: str) -> list[int | None]:
    """``modal.mode_index``: one predicted elastic-mode index (int >= 0; 0 = the first elastic
    mode, as in identify's ``pairing``) or null per peak."""
    key = "modal.mode_index"
    if not isinstance(v, list) or len(v) != n:
        raise UserError(f"value {v!r:.80}: expected a list of {n} mode indices (int >= 0) or null, "
                        "one per frequency", file=src, key=key)
    out: list[int | None] = []
    for i, x in enumerate(v):
        if x is None:
            out.append(None)
            continue
        if isinstance(x, float) and x.is_integer():
            x = int(x)
        if isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= 100_000:
            raise UserError(f"value {x!r}: expected an elastic-mode index (int >= 0, 0-based) or null",
                            file=src, key=f"{key}[{i}]")
        out.append(x)
    return out


def position(v: Any, key: str, src: str) -> float:
    """A coordinate on the plate, m (within +/- 1 km)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise UserError(f"value {v!r}: expected a finite number", file=src, key=key)
    x = float(v)
    if abs(x) > LIMITS["length_m"][1]:
        raise UserError(f"value {x:g}: outside [-1000, 1000] m", file=src, key=key)
    return x
