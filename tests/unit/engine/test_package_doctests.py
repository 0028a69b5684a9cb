"""The package docstrings of engine.plate and engine.safe are runnable doctests of their
workflow (scikit-fem style), checked against NAFEMS FV12 and the exact Rayleigh-Lamb values
of reference/ORACLES.md."""
from __future__ import annotations

import doctest

import pytest

import engine.plate
import engine.safe


@pytest.mark.parametrize("package", [engine.plate, engine.safe], ids=lambda m: m.__name__)
def test_package_docstring_runs(package):
    res = doctest.testmod(package, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert res.attempted >= 4 and res.failed == 0
