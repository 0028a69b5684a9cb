"""The GUM uncertainty budget of an identification (issue 16): specimen ``[uncertainty]``.

The specimen file may hold a table of type-B standard uncertainties, SI units::

    [uncertainty]
    thickness = 2e-5          # m, plate (laminate) thickness
    length = 5e-4             # m
    width = 5e-4              # m
    density = 27.0            # kg/m^3  -- or --  mass = 0.005  (kg, the plate weighed)
    sensor_position = 1e-3    # m, each sensor (wave sensors along the path; accelerometers in x and y)
    source_position = 1e-3    # m, the wave source along the path
    path_length = 0.0         # m, the source-sensor distance itself (beyond the positions)

Absent keys take :data:`DEFAULTS` (docs/uncertainty.md). With ``mass`` the density is not
an input: it follows from the mass and the dimensions, rho = m / (L W h), so a thickness
error also moves the density (E ~ h^-3 instead of h^-2 for a thin plate).

:func:`budget_of_problem` differentiates the forward model of the fitted problem in each
input at the estimate -- the plate modes analytically (``engine.plate.geometry_sensitivities``),
the SAFE velocities by central differences (relative step :data:`REL_STEP`) -- and hands the
changes to :func:`engine.fit.budget.gum_budget` (dp/dx = -J^+ dr/dx).
Its console table: ``labid.base.summary.budget_text``. Units SI.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from engine.fit.budget import BudgetInput, gum_budget
from engine.fit import Estimate
from engine.plate import geometry_sensitivities

from ..base.errors import UserError
from .identification.estimation import Problem, problem_from_features
from ..inputs.keys import check_keys
from ..inputs.specimen import Specimen

__all__ = ["DEFAULTS", "KEYS", "REL_STEP", "uncertainty_table", "budget_inputs", "budget_of_problem"]

#: keys of ``[uncertainty]`` and their units
KEYS = {"thickness": "m", "length": "m", "width": "m", "density": "kg/m^3", "mass": "kg",
        "sensor_position": "m", "source_position": "m", "path_length": "m"}
#: defaults: (value, relative?) -- relative ones are a fraction of the nominal value
DEFAULTS = {"thickness": (0.01, True), "length": (5e-4, False), "width": (5e-4, False),
            "density": (0.01, True), "sensor_position": (1e-3, False), "source_position": (1e-3, False),
            "path_length": (0.0, False)}
#: relative step of the central differences of the wave velocities (thickness, density, mass)
REL_STEP = 1e-3


# --------------------------------------------------------------------------- the table
def uncertainty_table(spec: Specimen, src: str = "<features>") -> dict[str, tuple[float, str]]:
    """``{key: (standard uncertainty in SI, 'specimen' | 'default')}`` of the specimen
    ``spec`` (its ``[uncertainty]`` table, read with it: ``Specimen.uncertainty``)."""
    tab = spec.uncertainty
    where = spec.source if spec.source else src
    if not isinstance(tab, Mapping):
        raise UserError("expected a table [uncertainty] of standard uncertainties in SI units",
                        file=where, key="uncertainty")
    check_keys(tab, KEYS, "uncertainty.", where)
    for k, v in tab.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v >= 0):
            raise UserError(f"value {v!r}: expected a standard uncertainty >= 0 in {KEYS[k]}",
                            file=where, key=f"uncertainty.{k}")
    if "mass" in tab and "density" in tab:
        raise UserError("both density and mass given; expected one of them", file=where, key="uncertainty.mass")
    nominal = {"thickness": spec.laminate.thickness, "density": spec.laminate.mean_density}
    out: dict[str, tuple[float, str]] = {}
    for k, (v, rel) in DEFAULTS.items():
        if k == "density" and "mass" in tab:
            continue
        if k in tab:
            out[k] = (float(tab[k]), "specimen")
        else:
            out[k] = (v * nominal[k] if rel else v, "default")
    if "mass" in tab:
        out["mass"] = (float(tab["mass"]), "specimen")
    return out


# --------------------------------------------------------------------------- the inputs
def budget_inputs(problem: Problem, est: Estimate, doc: Mapping, table: Mapping[str, tuple[float, str]]
                  ) -> tuple[list[BudgetInput], list[str]]:
    """The type-B inputs of ``problem`` at ``est`` with their residual changes, and notes on
    the inputs left out. Modal rows: analytic eigenvalue sensitivities of the fitted modes
    (``engine.plate.geometry_sensitivities``: no new solve; they equal the central
    differences of re-solved models to ~1e-6, tests/unit/engine/test_plate_sensitivity.py).
    Wave rows: central differences of the SAFE predictions (thickness, density, mass)."""
    spec, feats, mat = problem.specimen, problem.features, problem.material
    notes: list[str] = []
    params0 = est.params
    rho0 = spec.laminate.materials[mat].density
    L0, W0, h0 = spec.length, spec.width, spec.laminate.thickness
    fitted_density = "density" in est.names
    by_mass = "mass" in table
    has_modal = problem.modal_forward is not None
    masses = list(feats.rig.masses()) if (feats is not None and has_modal) else []
    y_obs = np.concatenate([b.observed for b in problem.blocks])
    wave_doc = {k: v for k, v in doc.items() if k != "modal"} if doc.get("waves") else None
    n_wave = sum(b.observed.size for b in problem.blocks if b.kind == "waves")
    rho_moves = by_mass and not fitted_density        # the density follows m / (L W h)

    modal: dict[str, np.ndarray] = {}
    if has_modal:
        # d f / d(input) of the fitted modes (raw model frequencies, as a re-solve would give)
        sol = problem.modal_forward.solve(dict(params0))
        ok = sol.index >= 0
        j = np.maximum(sol.index, 0)
        geo = geometry_sensitivities(problem.modal_forward.model, sol.modes, masses, params=dict(params0),
                                     material=mat)
        to_hz = np.where(ok, 1.0 / (8.0 * np.pi ** 2 * sol.modes.frequencies_hz[j]), 0.0)
        modal = {k: v[j] * to_hz for k, v in geo.items()}
        if fitted_density:
            modal["density"] = np.zeros(j.size)

    def waves_at(L=L0, W=W0, h=h0, mass_rel=0.0, rho_rel=0.0) -> np.ndarray:
        lam = spec.laminate.scaled_thickness(h / h0) if h != h0 else spec.laminate
        par = dict(params0)
        if not fitted_density:
            rho = rho0 * (1.0 + rho_rel)
            if by_mass:
                rho = rho0 * (L0 * W0 * h0) / (L * W * h) * (1.0 + mass_rel)
            par["density"] = rho
        pb = problem_from_features(wave_doc, specimen=Specimen(spec.name, L, W, lam, spec.source), material=mat,
                                   src=problem.source)
        return np.concatenate([np.asarray(b.predict(par), float) for b in pb.blocks])

    def central(make, step: float, modal_d: np.ndarray | None) -> np.ndarray:
        """The residual change per unit input: modal part given, waves by central differences
        (their length, width and accelerometer differences are exactly 0 unless the density
        follows the weighed mass)."""
        parts = [modal_d] if has_modal else []
        if wave_doc is not None:
            kw = make(step)
            if set(kw) <= {"L", "W"} and not rho_moves:
                parts.append(np.zeros(n_wave))
            else:
                parts.append((waves_at(**make(step)) - waves_at(**make(-step))) / (2.0 * step))
        return np.concatenate(parts)

    def rho_term(scale_per_unit: float) -> np.ndarray:
        """Modal change through the density when it follows the weighed mass."""
        return modal["density"] * scale_per_unit if (has_modal and rho_moves) else 0.0

    inputs: list[BudgetInput] = []

    def add(name: str, value: float, unit: str, d: np.ndarray) -> None:
        u, source = table[name]
        inputs.append(BudgetInput(name, float(value), float(u), unit, np.asarray(d, float), source))

    add("thickness", h0, "m", central(lambda s: {"h": h0 + s}, REL_STEP * h0,
                                      modal.get("thickness", 0.0) / h0 + rho_term(-1.0 / h0) if has_modal else None))
    if has_modal:
        add("length", L0, "m", central(lambda s: {"L": L0 + s}, REL_STEP * L0,
                                       modal["length"] / L0 + rho_term(-1.0 / L0)))
        add("width", W0, "m", central(lambda s: {"W": W0 + s}, REL_STEP * W0,
                                      modal["width"] / W0 + rho_term(-1.0 / W0)))
    if fitted_density:
        notes.append("density is identified: its type-B input (density or mass) is not used")
    elif by_mass:
        m0 = spec.mass
        add("mass", m0, "kg", central(lambda s: {"mass_rel": s / m0}, REL_STEP * m0,
                                      modal["density"] / m0 if has_modal else None))
    else:
        add("density", rho0, "kg/m^3", central(lambda s: {"rho_rel": s / rho0}, REL_STEP * rho0,
                                               modal["density"] / rho0 if has_modal else None))
    if masses:
        for axis, name in ((0, "x"), (1, "y")):
            d = np.concatenate([modal[f"masses_{name}"]] + ([np.zeros(n_wave)] if wave_doc is not None else []))
            u, source = table["sensor_position"]
            inputs.append(BudgetInput(f"accelerometer_position_{name}", 0.0, u, "m", d, source))
    wave_rows = np.concatenate([np.full(b.observed.size, b.kind == "waves") for b in problem.blocks])
    if wave_rows.any():
        path = feats.rig.wave_path_m if feats is not None else None
        if not path:
            notes.append("waves without rig.wave_path_m: sensor, source and path-length inputs not propagated")
        else:
            # observed group velocity = d / t: d(model - observed)/dd = -observed / d
            d = np.where(wave_rows, -y_obs / path, 0.0)
            for name in ("sensor_position", "source_position", "path_length"):
                if table[name][0] > 0:
                    add(name, path if name == "path_length" else 0.0, "m", d)
    if not est.method.startswith("levenberg"):
        notes.append(f"method {est.method}: sensitivities from the least-squares normal equations at its estimate")
    return inputs, notes


# --------------------------------------------------------------------------- entry points
def budget_of_problem(problem: Problem, est: Estimate, doc: Mapping, base_dir: str | Path = ".") -> dict:
    """The ``uncertainty_budget`` JSON of ``est`` fitted on ``problem`` (from features ``doc``)."""
    table = uncertainty_table(problem.specimen, problem.source)
    inputs, notes = budget_inputs(problem, est, doc, table)
    return gum_budget(problem.blocks, est, inputs, notes=notes).to_dict()
