"""engine.fit.chisq: the chi^2 tail without scipy.stats, equal to scipy.stats.chi2 bit for bit."""
import itertools
import math

import numpy as np
from scipy import stats

from engine.fit.chisq import chi2_isf, chi2_sf

XS = [-np.inf, -1.0, 0.0, 1e-300, 0.5, 3.0, 13.28, 18.5, 1e3, np.inf, np.nan]
DOFS = [-1, 0, 0.5, 1, 4, 7.3, 36, 100, np.nan]
QS = [-0.1, 0.0, 1e-12, 1e-3, 0.01, 0.05, 0.5, 1.0, 1.5, np.nan]


def _same(a, b):
    return (math.isnan(a) and math.isnan(b)) or a == b


def test_sf_equals_scipy_stats_bitwise():
    for x, d in itertools.product(XS, DOFS):
        assert _same(chi2_sf(x, d), float(stats.chi2.sf(x, d))), (x, d)


def test_isf_equals_scipy_stats_bitwise():
    for q, d in itertools.product(QS, DOFS):
        assert _same(chi2_isf(q, d), float(stats.chi2.isf(q, d))), (q, d)


def test_published_critical_values():
    # chi^2 table (NIST/SEMATECH e-Handbook, 1.3.6.7.4): upper 5 % points for 1 and 4 dof,
    # upper 1 % for 4 dof
    assert abs(chi2_isf(0.05, 1) - 3.841) < 1e-3
    assert abs(chi2_isf(0.05, 4) - 9.488) < 1e-3
    assert abs(chi2_isf(0.01, 4) - 13.277) < 1e-3
    assert abs(chi2_sf(9.488, 4) - 0.05) < 1e-4


def test_arrays_keep_their_shape():
    v = chi2_sf(np.array([[1.0, 2.0], [3.0, -1.0]]), 2)
    assert v.shape == (2, 2) and v[1, 1] == 1.0
    assert np.allclose(v, np.exp(-np.array([[1.0, 2.0], [3.0, 0.0]]) / 2))  # chi^2(2) sf = e^{-x/2}
