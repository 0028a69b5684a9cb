"""Scrambled Sobol' points without importing ``scipy.stats``.

Why hand-written (measured, kept on purpose): the global stage draws a few dozen points
once per fit, and ``scipy.stats.qmc`` costs ~0.4 s CPU and ~30 MiB to import (scipy.stats
builds every distribution's docstring) -- a sixth of ``labid identify`` on the demo's
features (bench/RESULTS.md, issue 29 session 24). This generator returns what
``scipy.stats.qmc.Sobol(d, scramble=True, seed=seed).random(n)`` returns, bit for bit
(``tests/unit/engine/test_identify_sobol.py`` compares them): Joe & Kuo's direction
numbers (new-joe-kuo-6.21201, the file scipy ships; Bratley & Fox's recurrence), a
left linear matrix scramble and a digital shift drawn from the same random stream, and
the Gray-code order. If scipy's direction-number file cannot be found, scipy.stats.qmc
itself is used.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

__all__ = ["sobol"]

BITS = 30


def _direction_numbers(d: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(poly, vinit) of the first ``d`` dimensions from scipy's file, located without
    importing scipy.stats (find_spec imports the parent package, scipy, only)."""
    spec = importlib.util.find_spec("scipy.stats")
    if spec is None or not spec.submodule_search_locations:
        return None
    f = Path(list(spec.submodule_search_locations)[0]) / "_sobol_direction_numbers.npz"
    if not f.is_file():
        return None
    with np.load(f) as z:
        return z["poly"][:d].astype(np.int64), z["vinit"][:d].astype(np.int64)


def _directions(poly: np.ndarray, vinit: np.ndarray, d: int) -> np.ndarray:
    """(d, BITS) direction integers, column j scaled by 2^(BITS-1-j)."""
    v = np.zeros((d, BITS), np.int64)
    v[0] = 1
    for i in range(1, d):
        p = int(poly[i])
        m = p.bit_length() - 1
        v[i, :m] = vinit[i, :m]
        for j in range(m, BITS):
            x = int(v[i, j - m])
            for k in range(m):
                if (p >> (m - 1 - k)) & 1:
                    x ^= int(v[i, j - k - 1]) << (k + 1)
            v[i, j] = x
    return v << (BITS - 1 - np.arange(BITS))


def _scrambled(v: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """(directions after a random lower-triangular GF(2) matrix scramble, digital shift)."""
    d = v.shape[0]
    shift = rng.integers(0, 2, size=(d, BITS), dtype=np.uint32).astype(np.int64) @ (1 << np.arange(BITS))
    ltm = np.tril(rng.integers(0, 2, size=(d, BITS, BITS), dtype=np.uint32)).astype(np.int64)
    ltm[:, np.arange(BITS), np.arange(BITS)] = 1
    bits = (v[:, :, None] >> np.arange(BITS)) & 1             # (d, j, k): bit k of v[d, j]
    # row p of the scramble, read with bit k of the direction as column BITS-1-k
    t1 = np.einsum("dpk,djk->djp", ltm[:, :, ::-1], bits) & 1  # (d, j, p)
    out = t1 @ (1 << (BITS - 1 - np.arange(BITS)))
    return out, shift


def sobol(d: int, n: int, seed: int) -> np.ndarray:
    """(n, d) scrambled Sobol' points in [0, 1) (as qmc.Sobol(d, scramble=True, seed=seed).random(n))."""
    dn = _direction_numbers(d)
    if dn is None:  # pragma: no cover - scipy without its data file
        from scipy.stats import qmc  # noqa: PLC0415
        return qmc.Sobol(d, scramble=True, seed=seed).random(n)
    v, shift = _scrambled(_directions(*dn, d), np.random.default_rng(seed))
    out = np.empty((n, d))
    q = shift.copy()
    scale = 2.0 ** -BITS
    if n:
        out[0] = q * scale
    for i in range(n - 1):
        low0 = (~i & (i + 1)).bit_length() - 1                 # position of i's lowest zero bit
        q ^= v[:, low0]
        out[i + 1] = q * scale
    return out
