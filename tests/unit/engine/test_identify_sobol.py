"""engine.identify.sobol: the global stage's scrambled Sobol' points without scipy.stats."""
import warnings

import numpy as np
import pytest

from engine.identify.sobol import sobol


@pytest.mark.parametrize("d", [1, 2, 3, 6, 9])
def test_equals_scipy_qmc_bitwise(d):
    from scipy.stats import qmc
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # qmc warns on n not a power of 2
        for seed in (0, 1, 12345):
            for n in (1, 5, 64, 100):
                assert np.array_equal(sobol(d, n, seed), qmc.Sobol(d, scramble=True, seed=seed).random(n))


def test_balance_of_a_power_of_two():
    # a (0, m, d)-net property of Sobol' points: each of the 2^m equal intervals of any one
    # coordinate holds exactly one of 2^m points, whatever the scramble
    u = sobol(4, 64, 3)
    for j in range(4):
        assert np.array_equal(np.bincount((u[:, j] * 64).astype(int), minlength=64), np.ones(64))


def test_identify_global_stage_does_not_import_scipy_stats():
    import subprocess
    import sys
    code = ("import sys; from engine.identify.sobol import sobol; import engine.identify.surrogate, "
            "engine.fit.checks, engine.gap.diagnose; sobol(3, 8, 0); print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
