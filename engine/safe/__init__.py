"""SAFE (semi-analytical finite element) guided waves in a layered anisotropic plate.

Units: SI (m, s, Pa, kg/m^3, Hz, rad/m, m/s); angles in degrees.

Modules (each readable alone):

* :mod:`.model` -- spectral elements through the thickness, the matrices K0, K1~,
  K2, M of ``[K0 + k K1~ + k^2 K2] q = w^2 M q`` and their uncoupled DOF classes;
* :mod:`.branches` -- Rayleigh-Ritz reduction of a class and its branches as
  Chebyshev series in k; roots at given frequencies (the measured reason for this
  hand-written series is in its docstring);
* :mod:`.roots` -- the roots of the converged branch series at given frequencies;
* :mod:`.labels` -- names of the branches (A0, S0, SH0, A1, ...);
* :mod:`.curves` -- dispersion curves and group velocities (the public entry);
* :mod:`.forces` -- force histories (hammer, pencil-lead break, tone burst);
* :mod:`.transfer` -- per-mode transfer functions of a source to a surface sensor;
* :mod:`.transient` -- forced transient response at a sensor (paper Eqs. 23-26).

Public API (re-exported here): ``dispersion``, ``dispersion_from_model``,
``group_velocity``, ``group_velocity_jacobian`` (its derivatives in the ply constants), ``mode_solution``,
``ModeSolution``, ``Dispersion``, ``ModeCurve``, ``safe_model``, ``SafeModel``,
``default_discretisation``, ``ply_stiffness``, ``bond_matrix``, ``SafeError``,
``ForceHistory``, ``hammer_force``, ``pencil_lead_break``, ``tone_burst``,
``mode_transfer``, ``mode_velocities``, ``transient_response``, ``QUANTITIES``.

The workflow (run by the test suite as a doctest): a laminate, then the velocities of
one mode on a frequency grid. The exact Rayleigh-Lamb group velocities of a 1 mm
aluminium plate (E = 70 GPa, nu = 0.33, 2700 kg/m^3) at f h = 0.1 and 0.5 MHz mm are
A0 1783.696 and 2908.787 m/s, S0 5391.689 and 5335.510 m/s:

>>> import numpy as np
>>> from engine.laminate import Laminate, Material, Ply
>>> from engine.safe import group_velocity
>>> al = Laminate([Ply(Material.isotropic_from(70e9, 2700.0, nu=0.33), 0.0, 1e-3)])
>>> np.round(group_velocity(al, [100e3, 500e3], "A0"), 1)
array([1783.7, 2908.8])
>>> np.round(group_velocity(al, [100e3, 500e3], "S0"), 1)
array([5391.7, 5335.5])

Package-internal (public names shared by the modules of this package, and used by
its tests and benchmarks; not for other layers): ``model.DofClass``,
``model.class_bases``, ``model.coupling``, ``model.TWO_PI``, everything in
``branches``, ``roots``, ``labels`` and ``transfer``.
"""
import importlib

from .curves import (Dispersion, ModeCurve, ModeSolution, dispersion, dispersion_from_model, group_velocity,
                     group_velocity_jacobian, mode_solution)
from .model import SafeError, SafeModel, bond_matrix, default_discretisation, ply_stiffness, safe_model

#: names of the force and transient modules, imported at first use (PEP 562): the curves alone
#: (``labid dispersion``, the wave blocks of identify) do not pay their import (~4-9 ms CPU)
_LAZY = {**dict.fromkeys(("ForceHistory", "hammer_force", "pencil_lead_break", "tone_burst"), "forces"),
         **dict.fromkeys(("QUANTITIES", "mode_transfer", "mode_velocities", "transient_response"), "transient")}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))

__all__ = [
    "ModeCurve", "Dispersion", "SafeModel", "SafeError",
    "safe_model", "dispersion", "dispersion_from_model", "group_velocity", "group_velocity_jacobian",
    "ModeSolution", "mode_solution",
    "default_discretisation",
    "bond_matrix", "ply_stiffness",
    "ForceHistory", "hammer_force", "pencil_lead_break", "tone_burst",
    "mode_transfer", "mode_velocities", "transient_response", "QUANTITIES",
]
