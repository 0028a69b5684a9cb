"""Test design: where to measure so that the wanted constants are identifiable (issue 25).

Modules: :mod:`.modal` (modes at prior draws sampled at candidate points; the
measurement model of a peak), :mod:`.fisher` (predicted covariance of the fitted
constants for a batch of layouts; the D/A criteria), :mod:`.search` (candidate grid and
coordinate-exchange search), :mod:`.waves` (guided waves: whether they pay, directions,
band, distances). No I/O; units SI.
"""
from .fisher import CRITERIA, DesignProblem, Evaluation, criterion, evaluate
from .modal import Measurement, ModalSet, half_sine_spectrum, modal_set, prior_draws
from .search import Layout, candidate_grid, optimise, snap

__all__ = ["Measurement", "ModalSet", "modal_set", "prior_draws", "half_sine_spectrum", "DesignProblem",
           "Evaluation", "evaluate", "criterion", "CRITERIA", "Layout", "candidate_grid", "optimise", "snap"]
