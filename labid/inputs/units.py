"""Units of imported records and calibration sheets: a unit text -> (quantity, SI factor).

A channel's samples are stored as volts at the ADC input (``labid.store``); a record in a
physical unit is converted with the channel's sensitivity (V per SI unit):
``volts = value * factor * sensitivity``. A record in a voltage unit (V, mV, uV) is
taken as volts at the input whatever the channel's kind.

Recognised: acceleration ``m/s^2`` (also ``m/s2``, ``m/s**2``, ``m s^-2``, ``m/s²``),
``mm/s^2``, ``g`` (= 9.80665 m/s^2, standard gravity, exact), ``ft/s^2``, ``in/s^2``;
force ``N``, ``kN``, ``mN``, ``lbf`` (4.4482216152605 N, exact); voltage ``V``, ``mV``,
``uV`` (``µV``). A unit may carry a leading factor: ``2.5V`` or ``2.5 V`` means that one
unit of the file is 2.5 V (a WAV sample is a fraction of full scale: give the full scale).
Sensitivities: ``V/(m/s^2)``, ``mV/(m/s^2)``, ``mV/g``, ``V/g``, ``V/N``, ``mV/N``,
``pC``-type charge units are not accepted (labid records voltages).
"""
from __future__ import annotations

import math
import re
from typing import Sequence

G0 = 9.80665            # m/s^2, standard gravity (exact by definition)
LBF = 4.4482216152605   # N, pound-force (exact by definition)

#: physical quantity recorded by each channel kind (drivers.protocol.UNITS)
QUANTITY = {"accelerometer": "acceleration", "force": "force", "voltage": "voltage"}

_ACC = {"m/s^2": 1.0, "m/s2": 1.0, "m/s**2": 1.0, "m s^-2": 1.0, "m/s²": 1.0, "m*s^-2": 1.0,
        "mm/s^2": 1e-3, "mm/s2": 1e-3, "g": G0, "G": G0, "g0": G0, "gn": G0,
        "ft/s^2": 0.3048, "ft/s2": 0.3048, "in/s^2": 0.0254, "in/s2": 0.0254}
_FORCE = {"N": 1.0, "kN": 1e3, "mN": 1e-3, "lbf": LBF}
_VOLT = {"V": 1.0, "mV": 1e-3, "uV": 1e-6, "µV": 1e-6, "μV": 1e-6}
_TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "ns": 1e-9}

_LEADING = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*\*?\s*(.+?)\s*$")


def known_units() -> list[str]:
    """Every unit text recognised for a record (for messages)."""
    return ["m/s^2", "mm/s^2", "g", "ft/s^2", "in/s^2", "N", "kN", "mN", "lbf", "V", "mV", "uV"]


def parse_unit(text: str) -> tuple[str, float] | None:
    """(quantity, factor to SI) of a record unit ('acceleration', 'force', 'voltage');
    None if not recognised. A leading number multiplies the factor ('2.5V')."""
    if text is None:
        return None
    t = str(text).strip()
    scale = 1.0
    m = _LEADING.match(t)
    if m and not t[:1].isalpha():
        scale, t = float(m.group(1)), m.group(2)
    t = t.replace(" ", "") if t not in _ACC else t
    for quantity, table in (("acceleration", _ACC), ("force", _FORCE), ("voltage", _VOLT)):
        if t in table:
            return quantity, scale * table[t]
    return None


def time_factor(text: str) -> float | None:
    """Seconds per unit of a time text ('s', 'ms', 'us', 'ns'); None if not a time unit."""
    return _TIME.get(str(text).strip())


def unit_matches(kind: str, quantity: str) -> bool:
    """Whether a record of ``quantity`` can feed a channel of ``kind`` (volts feed any kind)."""
    return quantity == "voltage" or QUANTITY.get(kind) == quantity


def sensitivity_si(value: float, unit: str) -> tuple[str, float] | None:
    """A sensitivity in ``unit`` -> (quantity, V per SI unit); None if not recognised.

    ``unit`` is 'VOLTAGE/QUANTITY', e.g. 'mV/g' (10 mV/g = 1.0197e-3 V/(m/s^2)), 'V/N',
    'mV/N', 'V/(m/s^2)', 'V/V'."""
    u = str(unit).strip().replace(" ", "")
    if "/" not in u:
        return None
    num, den = u.split("/", 1)
    if den.startswith("(") and den.endswith(")"):
        den = den[1:-1]
    if num not in _VOLT:
        return None
    q = parse_unit(den)
    if q is None:
        return None
    quantity, f = q
    return quantity, float(value) * _VOLT[num] / f


def loss_factors(damping_ratio: Sequence[float]) -> list[float]:
    """The hysteretic loss factor eta = 2 zeta of each viscous damping ratio zeta (the same
    damping in its two conventions; NaN where zeta is missing)."""
    return [2.0 * float(z) if z is not None and math.isfinite(float(z)) else math.nan for z in damping_ratio]
