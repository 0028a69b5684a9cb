"""Chi-square tail probabilities without ``scipy.stats``.

``scipy.stats`` costs ~0.4 s CPU and ~30 MiB to import (it builds every distribution's
docstring); ``labid identify`` and ``labid diagnose`` need only the chi^2 survival function
and its inverse, which ``scipy.stats.chi2`` takes from ``scipy.special`` (``chdtrc``,
``chdtri``), already imported with ``scipy.optimize``. These two functions return what
``scipy.stats.chi2.sf`` / ``.isf`` return, bit for bit, including their edge cases
(``tests/unit/engine/test_chisq.py``; bench/RESULTS.md, issue 29 session 24).
"""
from __future__ import annotations

import numpy as np
from scipy import special

__all__ = ["chi2_sf", "chi2_isf"]


def _out(v):
    return float(v) if np.ndim(v) == 0 else v


def chi2_sf(x, dof):
    """P(X > x) for X ~ chi^2(dof) (dimensionless); 1 for x < 0, nan for dof <= 0."""
    x, dof = np.asarray(x, float), np.asarray(dof, float)
    with np.errstate(invalid="ignore"):
        v = np.where(dof > 0, special.chdtrc(dof, np.maximum(x, 0.0)), np.nan)
    return _out(v)


def chi2_isf(q, dof):
    """x with P(X > x) = q for X ~ chi^2(dof); nan outside 0 <= q <= 1 or for dof <= 0."""
    q, dof = np.asarray(q, float), np.asarray(dof, float)
    with np.errstate(invalid="ignore"):
        v = np.where((dof > 0) & (q >= 0) & (q <= 1), special.chdtri(dof, q), np.nan)
    return _out(v)
