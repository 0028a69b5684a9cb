"""Estimation of elastic constants from measured data, with uncertainty.

Generic over forward models: every data set is a :class:`DataBlock`
(observations, sigmas, ``predict(params)``, optional Jacobian); parameters are
dicts ``{name: value}`` in SI units.

Public seam:

* data and problem (:mod:`.problem`): ``DataBlock``, ``Prior``,
  ``IdentificationError``, ``Problem`` (whitened residual and Jacobian over
  blocks), ``Coords`` (theta <-> p), ``check_start``, ``prior_arrays``,
  ``whitened_jacobian``, ``linearised_block``;
* estimators (:mod:`.estimators`): ``estimate`` (Levenberg-Marquardt, the
  project's own: :mod:`.lm`), ``bayesian_update`` (Lai & Ip, Eq. 20),
  ``nelder_mead_fit`` (Eq. 29);
* uncertainty (:mod:`.uncertainty`): ``Estimate``, ``laplace``,
  ``identifiability``;
* checks of a combined fit (:mod:`.checks`): ``birge_refit``, ``consistency``,
  ``goodness`` (chi2, dof, p-value, consistent), ``scale_uncertainty``;
* full posterior (:mod:`.mcmc`, needs emcee): ``Posterior``, ``sample_posterior``.

Package-internal: ``finish_estimate`` (uncertainty) and ``levenberg_marquardt``
(lm) are shared by the estimators.
"""
from .checks import P_CONSISTENT, birge_refit, consistency, goodness, scale_uncertainty
from .estimators import bayesian_update, estimate, nelder_mead_fit
from .mcmc import Posterior, sample_posterior
from .problem import (Coords, DataBlock, IdentificationError, Params, Prior, Problem, check_start,
                      linearised_block, prior_arrays, whitened_jacobian)
from .uncertainty import Estimate, identifiability, laplace

__all__ = ["DataBlock", "Prior", "IdentificationError", "Params", "Problem", "Coords", "check_start",
           "prior_arrays", "whitened_jacobian", "linearised_block", "estimate", "bayesian_update",
           "nelder_mead_fit", "Estimate", "laplace", "identifiability", "birge_refit", "consistency", "goodness", "scale_uncertainty", "P_CONSISTENT",
           "Posterior", "sample_posterior"]
