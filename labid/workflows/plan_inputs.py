"""What ``labid plan`` reads: its options (bounded where they enter), the measurement model
a rig implies, the layouts rig files hold, and the specimen's type-B inputs as columns of
d ln f / d input (the ``--budget``). Units SI; relative quantities as fractions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from engine.design import Measurement
from engine.forward import pair_by_mac
from engine.plate import Mesh, PlateModel

from ..base.errors import UserError
from ..inputs.rig import Rig
from ..inputs.specimen import Specimen

__all__ = ["PlanOptions", "LIMITS", "parse_options", "parse_fraction", "parse_prior", "parse_want", "material_of",
           "constant_names", "measurement_of", "rig_layout", "budget_columns", "DEFAULT_PRIOR"]

#: relative std of a datasheet value (one standard deviation) when --prior does not say
DEFAULT_PRIOR = 0.10
#: bounds of the options, where they enter: (low, high)
LIMITS = {"grid": (3, 41), "draws": (1, 32), "sensors": (1, 16), "max_modes": (5, 150),
          "target_u": (1e-5, 1.0), "prior": (0.0, 1.0), "sigma_f": (1e-6, 0.1), "margin_m": (0.0, 10.0),
          "mass_u": (0.0, 1.0), "wave_timing_s": (1e-10, 1e-4), "seed": (0, 2**31 - 1)}


@dataclass(frozen=True)
class PlanOptions:
    """``labid plan``'s choices (docs/plan.md). ``want``: constants to identify (None: every
    constant of the material); ``prior``: relative std per constant; ``budget``: 'none',
    'specimen' (its [uncertainty] table, defaults as ``labid identify``) or a TOML path with
    an [uncertainty] table; ``waves``: 'auto' (only when they pay), 'yes', 'no'; ``fit``:
    'auto' (the wanted constants and those the data determine, as ``labid identify``) or
    'wanted' (only the wanted ones; the others held at nominal)."""

    want: tuple[str, ...] | None = None
    target_u: float = 0.02
    prior: Mapping[str, float] | None = None
    budget: str = "none"
    grid: int = 15
    margin_m: float = 0.02
    keepout_m: float = 0.02
    min_gap_m: float = 0.02
    sensors: int | None = None
    draws: int = 6
    criterion: str = "MV"
    sigma_f: float = 1e-3
    mass_u: float = 0.1
    max_modes: int = 60
    waves: str = "auto"
    fit: str = "auto"
    wave_timing_s: float = 1e-7
    wave_floor: float = 5e-4
    seed: int = 0


def _bounded(v: float, key: str, option: str, unit: str = "") -> float:
    lo, hi = LIMITS[key]
    if not (math.isfinite(v) and lo <= v <= hi):
        raise UserError(f"value {v:g}{unit}: expected {lo:g} to {hi:g}{unit}", key=option)
    return v


def parse_fraction(text: str | float, option: str, key: str) -> float:
    """'2%' -> 0.02, '0.02' -> 0.02, bounded by ``LIMITS[key]`` (UserError naming ``option``)."""
    if isinstance(text, (int, float)):
        return _bounded(float(text), key, option)
    s = str(text).strip()
    try:
        v = float(s[:-1]) / 100.0 if s.endswith("%") else float(s)
    except ValueError:
        raise UserError(f"value {text!r}: expected a fraction such as 0.02 or a percentage such as 2%",
                        key=option) from None
    return _bounded(v, key, option)


def material_of(spec: Specimen) -> tuple[str, object]:
    """(name, Material) of a single-material specimen."""
    mats = spec.laminate.materials
    if len(mats) != 1:
        raise UserError(f"laminate has materials {sorted(mats)}; expected a single material to plan for",
                        file=spec.source, key="materials")
    name = next(iter(mats))
    return name, mats[name]


def constant_names(material) -> tuple[str, ...]:
    return ("E", "G") if material.isotropic else ("E1", "E2", "nu12", "G12", "G13", "G23")


def parse_want(text: str | None, material) -> tuple[str, ...]:
    """'E1,E2,G12' -> ('E1', 'E2', 'G12') in the material's order; None: all of them."""
    names = constant_names(material)
    if not text:
        return names
    want = [t.strip() for t in text.split(",") if t.strip()]
    bad = [w for w in want if w not in names]
    if bad or not want:
        raise UserError(f"value {text!r}: expected constants among {', '.join(names)}", key="--want")
    return tuple(n for n in names if n in want)


def parse_prior(text: str | None, material) -> dict[str, float]:
    """'10%' (every constant) or 'E1=5%,G13=30%' (the others DEFAULT_PRIOR) -> {name: rel std}."""
    names = constant_names(material)
    out = {n: DEFAULT_PRIOR for n in names}
    if not text:
        return out
    s = text.strip()
    if "=" not in s:
        v = parse_fraction(s, "--prior", "prior")
        return {n: v for n in names}
    for item in s.split(","):
        if not item.strip():
            continue
        name, _, val = item.partition("=")
        name = name.strip()
        if name not in names:
            raise UserError(f"item {item.strip()!r}: expected NAME=FRACTION with NAME among {', '.join(names)}",
                            key="--prior")
        out[name] = parse_fraction(val, "--prior", "prior")
    return out


def measurement_of(rig: Rig, options: PlanOptions) -> Measurement:
    """The measurement model of a rig's hammer test (docs/plan.md)."""
    dev = rig.device("hammer")
    if dev is None or rig.hammer is None:
        raise UserError("no device with role = \"hammer\" (or no [hammer]): a modal test needs one",
                        file=rig.source, key="devices")
    aa = dev.antialias
    # what labid analyze searches by default (0.4 x rate), within the anti-alias cutoff
    f_max = min(0.4, aa.cutoff_ratio if aa.kind != "none" else 0.5) * dev.timing.rate_hz
    masses = [c.mass_kg for c in rig.accelerometers]
    return Measurement(sigma_rel=options.sigma_f, damping=rig.sim.modal_damping,
                       resolution_hz=dev.timing.rate_hz / dev.timing.samples, contact_s=rig.hammer.contact_s,
                       f_max_hz=f_max, mass_kg=float(np.mean(masses)) if masses else 0.0,
                       mass_u_rel=options.mass_u)


def rig_layout(rig: Rig, spec: Specimen) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """(accelerometer points (ns, 2), hammer point (2,), masses (ns,), notes) of a rig. A rig
    whose points do not all lie on this plate (e.g. the built-in rig on another plate) is
    scaled onto it, with a note."""
    acc = rig.accelerometers
    if not acc:
        raise UserError("no accelerometer channel: a modal test needs at least one", file=rig.source,
                        key="devices")
    pts = np.array([[c.x, c.y] for c in acc], float)
    tap = np.array([rig.hammer.x, rig.hammer.y], float)
    masses = np.array([c.mass_kg for c in acc], float)
    notes = []
    allp = np.vstack([pts, tap])
    if np.any(allp[:, 0] > spec.length) or np.any(allp[:, 1] > spec.width):
        sx = min(1.0, spec.length / max(allp[:, 0].max(), 1e-9) * 0.95)
        sy = min(1.0, spec.width / max(allp[:, 1].max(), 1e-9) * 0.95)
        pts, tap = pts * [sx, sy], tap * [sx, sy]
        notes.append(f"{rig.source}: positions beyond the {spec.length:g} x {spec.width:g} m plate scaled by "
                     f"{sx:.3g} in x and {sy:.3g} in y onto it")
    return pts, tap, masses, notes


def _stretched(mesh: Mesh, length: float, width: float) -> Mesh:
    return Mesh(mesh.nx, mesh.ny, length, width, tuple(mesh.xe * (length / mesh.length)),
                tuple(mesh.ye * (width / mesh.width)))


def budget_columns(model: PlateModel, spec: Specimen, draws: Sequence[Mapping[str, float]], material: str,
                   table: Mapping[str, tuple[float, str]], n_modes: int, step: float = 1e-3,
                   progress=None) -> dict[str, tuple[np.ndarray, float]]:
    """The specimen's type-B inputs of a modal fit as ``{name: ((D, M) d ln f / d x, u)}``:
    thickness (all plies scaled) and length by forward differences of the plate model at every
    draw (modes paired by MAC), width from the scaling law (f ~ 1/s when L, W and h all scale
    by s), density -1/2 exactly (or, with the plate weighed, through rho = m / (L W h))."""
    h, L, W = spec.laminate.thickness, spec.length, spec.width
    rho = spec.laminate.mean_density
    D = len(draws)
    dh, dL = np.zeros((D, n_modes)), np.zeros((D, n_modes))
    thick = model.with_laminate(spec.laminate.scaled_thickness(math.exp(step)))
    longer = PlateModel.build(spec.laminate, L * math.exp(step), W, _stretched(model.mesh, L * math.exp(step), W))
    for d, p in enumerate(draws):
        if progress is not None:
            progress(f"budget sensitivities at draw {d + 1}/{D}")
        m0 = model.solve(n_modes, params=dict(p), material=material)
        for tgt, out in ((thick, dh), (longer, dL)):
            m1 = tgt.solve(n_modes + 4, params=dict(p), material=material)
            idx, _ = pair_by_mac(m0.shapes.T, m1.shapes.T)
            out[d] = (np.log(m1.frequencies_hz[idx]) - np.log(m0.frequencies_hz)) / step
    dW = -1.0 - dh - dL
    cols: dict[str, tuple[np.ndarray, float]] = {}
    mass = "mass" in table
    # per unit of the input itself: d ln f / d x = (d ln f / d ln x) / x
    if mass:   # rho = m / (L W h): ln f also moves by +1/2 d ln(L W h)
        dh, dL, dW = dh + 0.5, dL + 0.5, dW + 0.5
        m_plate = rho * L * W * h
        cols["mass"] = (np.full((D, n_modes), -0.5 / m_plate), table["mass"][0])
    else:
        cols["density"] = (np.full((D, n_modes), -0.5 / rho), table["density"][0])
    cols["thickness"] = (dh / h, table["thickness"][0])
    cols["length"] = (dL / L, table["length"][0])
    cols["width"] = (dW / W, table["width"][0])
    return {k: v for k, v in cols.items() if v[1] > 0}


def _int(v, key: str, option: str) -> int:
    lo, hi = LIMITS[key]
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= int(v) <= hi:
        raise UserError(f"value {v!r}: expected an integer from {lo} to {hi}", key=option)
    return int(v)


def _choice(v: str, choices: tuple[str, ...], option: str) -> str:
    if v not in choices:
        raise UserError(f"value {v!r}: expected one of {', '.join(choices)}", key=option)
    return v


def parse_options(material, *, want: str | None = None, target_u="2%", prior: str | None = None,
                  budget: str = "none", grid: int = 15, margin="0.02", sensors: int | None = None,
                  draws: int = 6, criterion: str = "MV", sigma_f="0.1%", mass_u="10%", max_modes: int = 60,
                  waves: str = "auto", fit: str = "auto", seed: int = 0) -> PlanOptions:
    """:class:`PlanOptions` from the command's raw values (strings such as '2%' or numbers),
    each bounded where it enters (``LIMITS``; a UserError names the option)."""
    try:
        m = float(margin)
    except (TypeError, ValueError):
        raise UserError(f"value {margin!r}: expected an edge margin in m", key="--margin") from None
    budget = str(budget)
    if budget not in ("none", "specimen") and not budget.endswith(".toml"):
        raise UserError(f"value {budget!r}: expected none, specimen or a TOML file with an [uncertainty] table",
                        key="--budget")
    return PlanOptions(
        want=parse_want(want, material), target_u=parse_fraction(target_u, "--target-u", "target_u"),
        prior=parse_prior(prior, material), budget=budget, grid=_int(grid, "grid", "--grid"),
        margin_m=_bounded(m, "margin_m", "--margin", " m"),
        sensors=None if sensors is None else _int(sensors, "sensors", "--sensors"),
        draws=_int(draws, "draws", "--draws"), criterion=_choice(criterion, ("MV", "D", "A"), "--criterion"),
        sigma_f=parse_fraction(sigma_f, "--sigma-f", "sigma_f"), mass_u=parse_fraction(mass_u, "--mass-u", "mass_u"),
        max_modes=_int(max_modes, "max_modes", "--max-modes"), waves=_choice(waves, ("auto", "yes", "no"), "--waves"),
        fit=_choice(fit, ("auto", "wanted"), "--fit"),
        seed=_int(seed, "seed", "--seed"))
