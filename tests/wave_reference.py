"""The group velocity a wave test compares its picks with, from a model the picks did not use.

labid's picks are windowed by ``engine.safe`` (the nominal specimen's curves) and the simulated
rig synthesises with ``engine.safe`` too; comparing a pick with ``engine.safe`` again would judge
the method by the model that placed its window (issue 24). This reference is the independent
guided-wave model of bench/independent/legendre_safe.py (hierarchical Legendre elements per
ply, its own stiffness and rotation; within 1e-7 of the exact Rayleigh-Lamb table, tested in
tests/unit/bench/test_legendre_safe.py), element order 4 per ply.
"""
from __future__ import annotations

import numpy as np

from bench.independent.legendre_safe import branches, layers_of, plate_of

BRANCH = {"A0": 0, "SH0": 1, "S0": 2}   # the three branches below the first cut-off, by w at each k
_BRANCHES: dict = {}                    # (plate, fmax) -> Branches: a 12-ply CFRP costs ~1.3 s CPU


def independent_group_velocity(laminate, f_hz, mode: str, direction_deg: float = 0.0) -> np.ndarray:
    """Group velocity (m/s) of ``mode`` ('A0', 'SH0', 'S0') of ``laminate`` along
    ``direction_deg`` at the frequencies ``f_hz`` (Hz), from the independent model."""
    f = np.atleast_1d(np.asarray(f_hz, float))
    plate = plate_of(layers_of(laminate.plies, direction_deg), 4)     # cached by its layers
    key = (plate, round(float(f.max()) * 1.05, -2))
    if key not in _BRANCHES:
        _BRANCHES[key] = branches(plate, key[1], n_k=250)
    br = _BRANCHES[key]
    cg = br.at(BRANCH[mode], 2 * np.pi * f)[1]
    assert np.all(np.isfinite(cg)), "frequency outside the independent model's branch"
    return cg
