"""Blind gap cases from a generator that is not labid's model (issue 28).

``draw(seed, kind)`` draws from the seed alone a specimen (CFRP [0/+-45]2s, a wood-like
orthotropic plate, aluminium), the true constants (nominal +-5 %, nu12 +-3 %), the data a
lab would have (10-40 modal frequencies without shapes, 0.1-0.5 % noise; or group
velocities; or both; effect cases 0.05-0.2 % noise), one condition with a realistic magnitude,
and returns the features
(CONTRACT section 2; the nominal specimen inline), the options a lab would give
(:func:`fitted`) and the hidden truth. The constants the lab fits deviate from nominal
(+-5 %, nu12 +-3 %); the ones it holds are at their nominal values (a lab that holds a
constant it does not know has a real model gap: measured apart, bench/RESULTS.md).

Who makes the data:
* natural frequencies: :mod:`bench.independent.ritz_plate` (Rayleigh-Ritz Mindlin plate,
  no code shared with engine.plate; order 12 up to 20 modes, 16 beyond: within 1e-4 of the
  converged values for the CFRP and aluminium plates, 3e-4 for the wood-like one, i.e. a
  tenth to a third of the smallest noise; bench/bench_ritz.py, bench/RESULTS.md "Issue 28");
  the suspension modes that springs lift are dropped, as a lab does not list them;
* group velocities: :mod:`bench.independent.legendre_safe` (``wave_generator="legendre"``, the
  default since session 24: hierarchical Legendre p-elements, one per ply, the real roots k of
  the quadratic eigenproblem at each frequency; no code shared with engine.safe; the plies
  read here by :func:`legendre_plies`, the 3D constants a table leaves out by the specimen
  format's transverse isotropy). ``wave_generator="safe"``: engine.safe at its default order
  + 3 (session 23's rows; a different discretisation of the diagnoser's own model). Which one
  made a case is in its recipe and :attr:`Case.detail`. The time-of-flight effects are their
  definition: t = (d + delta) / c_g + dt, c_obs = d / t.

Conditions (``KINDS``): ``clean``; library effects (``LIBRARY``, the engine's names, sizes of
issue 28); out-of-library effects (``OUT_OF_LIBRARY``): a soft patch (impact damage), a
local thickness bump, a glue mass away from the sensors, an anticlastic curvature (shallow
shell; springs can mimic a mild one, so ``support_stiffness`` named *with* curvature as a
look-alike counts right). Generated features are cached in ``bench/out/`` by their recipe.
"""
from __future__ import annotations

import copy
import hashlib
import json
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from bench.independent.legendre_safe import LegendrePlate, layers_of
from bench.independent.ritz_plate import RitzPlate, plies_from_table
from engine.safe import default_discretisation, group_velocity
from labid.inputs.specimen import specimen_from_dict

CACHE = Path(__file__).resolve().parent / "out" / "gap_independent_cache"

LIBRARY = ("sensor_mass", "support_stiffness", "thickness_taper", "misalignment", "ply_angle_error",
           "density_gradient", "timing_offset", "path_length")
OUT_OF_LIBRARY = ("soft_patch", "thickness_bump", "glue_mass", "curvature")
KINDS = ("clean",) + LIBRARY + OUT_OF_LIBRARY
WAVE_EFFECTS = ("timing_offset", "path_length")
ANGLE_EFFECTS = ("misalignment", "ply_angle_error")

#: magnitudes (low, high, signed) in the engine's unit (issue 28's realistic sizes)
RANGES = {
    "sensor_mass": (0.001, 0.005, False),          # kg beyond the declared mass, at every accelerometer
    "support_stiffness": (100.0, 1000.0, False),   # N/m at every support
    "thickness_taper": (0.03, 0.08, False),        # relative change at each end
    "misalignment": (2.0, 5.0, False),             # deg, every ply
    "ply_angle_error": (3.0, 8.0, True),           # deg, the top ply
    "density_gradient": (0.04, 0.06, True),        # relative change at each end (+-5 %)
    "timing_offset": (0.5e-6, 3e-6, True),         # s
    "path_length": (0.003, 0.010, True),           # m
    "soft_patch": (0.3, 0.6, False),               # stiffness lost over a 60 mm square
    "thickness_bump": (0.10, 0.25, False),         # relative thickness added at a bump's centre
    "glue_mass": (0.003, 0.010, False),            # kg at a point >= 60 mm from every accelerometer
    "curvature": (0.02, 0.10, False),              # 1/m, anticlastic (kx = -ky)
}

SPRUCE = {"plate": {"length": 0.40, "width": 0.25},
          "materials": {"spruce": {"density": 430.0, "E1": 11.0e9, "E2": 0.75e9, "nu12": 0.37, "G12": 0.68e9,
                                   "G13": 0.62e9, "G23": 0.07e9, "E3": 0.5e9,
                                   "nu13": 0.4, "nu23": 0.4}},
          "layup": {"material": "spruce", "angles_deg": [0], "ply_thickness": 0.004}}
ALUMINIUM = {"plate": {"length": 0.30, "width": 0.24},
             "materials": {"Al": {"density": 2700.0, "E": 71.0e9, "G": 26.7e9}},
             "layup": {"material": "Al", "angles_deg": [0], "ply_thickness": 3.175e-3}}


def _cfrp() -> dict:
    t = tomllib.loads(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text())
    t.pop("report", None)
    return t


#: specimen: (table, wave sets (mode, direction deg, n), wave band Hz, path m)
SPECIMENS = {
    "cfrp": (_cfrp, (("A0", 0.0, 8), ("A0", 45.0, 8), ("A0", 90.0, 8), ("S0", 0.0, 6), ("S0", 90.0, 6)),
             (20e3, 200e3), 0.25),
    "wood": (lambda: copy.deepcopy(SPRUCE), (("A0", 0.0, 8), ("A0", 90.0, 8)), (5e3, 40e3), 0.20),
    "aluminium": (lambda: copy.deepcopy(ALUMINIUM), (("A0", 0.0, 8), ("S0", 0.0, 6)), (10e3, 100e3), 0.20),
}
ACCEL_MASS_KG = 0.002
SAFE_EXTRA_ORDER = 3
WAVE_GENERATORS = ("legendre", "safe")
#: Legendre element order per ply: c_g within 1e-7 of order + 2 over each specimen's band
#: (tests/unit/bench/test_legendre_safe.py), 5e3 times below the smallest noise (0.05 %)
LEGENDRE_ORDER = {"cfrp": 4, "wood": 10, "aluminium": 8}


@dataclass(frozen=True)
class Case:
    """A generated case: what the diagnoser sees (``features``, the options a lab would give:
    ``params``, ``prior``) and the hidden truth."""

    seed: int
    kind: str
    magnitude: float
    unit: str
    specimen: str
    n_modes: int
    noise: float
    data: str                 # "modal", "waves" or "combined"
    features: dict
    truth: dict
    params: tuple | None
    prior: float | None
    noiseless: list
    detail: dict


def _rig(length: float, width: float) -> tuple[tuple, tuple]:
    acc = ((0.02, 0.02), (length - 0.02, 0.02), (0.02, width - 0.02), (length - 0.02, width - 0.02))
    sup = ((0.09 * length, width), (0.91 * length, width))
    return acc, sup


def _data_choice(kind: str, rng) -> str:
    if kind in WAVE_EFFECTS:
        return "waves"                 # a pitch-catch set-up of its own (the path-length case)
    if kind in LIBRARY or kind in OUT_OF_LIBRARY:
        return "modal"
    return str(rng.choice(["modal", "modal", "combined", "waves"]))


def recipe(seed: int, kind: str, specimen: str | None = None, data: str | None = None,
           n_modes: int | None = None, noise: float | None = None, magnitude: float | None = None,
           wave_sets: tuple | None = None, band: tuple | None = None, fit: tuple | None = None,
           wave_generator: str = "legendre") -> dict:
    """Everything random of a case, drawn from ``seed`` (and the forced choices)."""
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r}: expected one of {KINDS}")
    if wave_generator not in WAVE_GENERATORS:
        raise ValueError(f"wave_generator {wave_generator!r}: expected one of {WAVE_GENERATORS}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 28]))
    spec = specimen or str(rng.choice(list(SPECIMENS)))
    if (kind in ANGLE_EFFECTS and spec == "aluminium") or (kind == "ply_angle_error" and spec == "wood"):
        spec = "cfrp"         # an angle needs an orthotropic plate; one ply of several a laminate
    table = SPECIMENS[spec][0]()
    mat = dict(table["materials"][table["layup"]["material"]])
    names = [k for k in ("E1", "E2", "nu12", "G12", "G13", "G23", "E", "G") if k in mat]   # E3, nu13, nu23 held
    dev = {k: (0.03 if k == "nu12" else 0.05) * float(rng.standard_normal()) for k in names}
    while "E" in mat and mat["E"] * (1 + dev["E"]) / (2 * mat["G"] * (1 + dev["G"])) - 1.0 >= 0.5:
        # E and G drawn apart can give nu >= 0.5 (no positive-definite stiffness; seeds 85, 183):
        # G's deviation drawn again (the seeds whose nu < 0.5 keep their draws)
        dev["G"] = 0.05 * float(rng.standard_normal())
    data = data or _data_choice(kind, rng)
    params, prior = fit if fit is not None else fitted(data, "E" in mat)
    # the constants the lab fits deviate from nominal; the ones it holds are as it holds them
    truth = {k: float(mat[k] * (1.0 + (dev[k] if k in params else 0.0))) for k in names}
    n = int(n_modes or rng.integers(10, 41))
    # clean cases: 0.1-0.5 % (the calibration); effect cases: 0.05-0.2 %, a good modal test
    # (at 0.35-0.5 % half of the realistic-size effects leave less than chi^2 30 in the data)
    noise = float(noise or (rng.uniform(1e-3, 5e-3) if kind == "clean" else rng.uniform(5e-4, 2e-3)))
    mag, extra = 0.0, {}
    if kind != "clean":
        lo, hi, signed = RANGES[kind]
        mag = float(rng.uniform(lo, hi)) * (float(rng.choice([-1.0, 1.0])) if signed else 1.0)
        mag = mag if magnitude is None else float(magnitude)
    L, W = float(table["plate"]["length"]), float(table["plate"]["width"])
    acc, _ = _rig(L, W)
    if kind == "soft_patch":
        extra["centre"] = rng.uniform([0.25 * L, 0.25 * W], [0.75 * L, 0.75 * W]).tolist()
    if kind == "thickness_bump":
        extra["centre"] = rng.uniform([0.25 * L, 0.25 * W], [0.75 * L, 0.75 * W]).tolist()
        extra["radius"] = float(rng.uniform(0.04, 0.06))
    if kind == "glue_mass":
        while True:
            p = rng.uniform([0.02, 0.02], [L - 0.02, W - 0.02])
            if min(np.hypot(p[0] - a, p[1] - b) for a, b in acc) > 0.06:
                break
        extra["at"] = p.tolist()
    if wave_sets is not None:
        extra["wave_sets"] = [list(w) for w in wave_sets]
    if band is not None:
        extra["band"] = list(band)
    noise_seed = int(rng.integers(2 ** 31))
    if data != "modal":
        extra["wave_generator"] = wave_generator      # (modal recipes, and their cache keys, unchanged)
    return {"seed": int(seed), "kind": kind, "specimen": spec, "truth": truth, "data": data, "n_modes": n,
            "noise": noise, "magnitude": mag, "extra": extra, "noise_seed": noise_seed, "params": list(params),
            "prior": prior}


def fitted(data: str, isotropic: bool) -> tuple[tuple[str, ...], float | None]:
    """(constants fitted, prior) as a lab would ask: isotropic E, G; orthotropic modal only: the
    in-plane E1, E2, G12; with waves all six with a 30 % prior (A0/S0 alone leave some to it)."""
    if isotropic:
        return ("E", "G"), None
    if data == "modal":
        return ("E1", "E2", "G12"), None
    return ("E1", "E2", "nu12", "G12", "G13", "G23"), 0.3


def ritz_for(r: dict, table: dict, order: int) -> RitzPlate:
    """The Ritz plate of a recipe (the true plate, with the condition built in)."""
    kind, mag, ex = r["kind"], r["magnitude"], r["extra"]
    plies, L, W = plies_from_table(table, r["truth"], angle_offset=mag if kind == "misalignment" else 0.0,
                                   top_offset=mag if kind == "ply_angle_error" else 0.0)
    acc, sup = _rig(L, W)
    m_acc = ACCEL_MASS_KG + (mag if kind == "sensor_mass" else 0.0)
    masses = [(x, y, m_acc) for x, y in acc]
    if kind == "glue_mass":
        masses.append((*ex["at"], mag))
    springs = [(x, y, mag) for x, y in sup] if kind == "support_stiffness" else []
    kw: dict = {}
    if kind == "thickness_taper":
        kw["thickness_field"] = lambda x, y: 1.0 + mag * (2.0 * x / L - 1.0)
    if kind == "density_gradient":
        kw["density_field"] = lambda x, y: 1.0 + mag * (2.0 * x / L - 1.0)
    if kind == "soft_patch":
        (x0, y0), a = ex["centre"], 0.03
        kw["stiffness_field"] = lambda x, y: 1.0 - mag * ((np.abs(x - x0) < a) & (np.abs(y - y0) < a))
        kw["breaks_x"], kw["breaks_y"] = (x0 - a, x0 + a), (y0 - a, y0 + a)
    if kind == "thickness_bump":
        (x0, y0), R = ex["centre"], ex["radius"]

        def bump(x, y):
            rr = np.hypot(x - x0, y - y0) / R
            return 1.0 + mag * np.where(rr < 1.0, np.cos(0.5 * np.pi * np.minimum(rr, 1.0)) ** 2, 0.0)
        kw["thickness_field"] = bump
        kw["breaks_x"], kw["breaks_y"] = (x0 - R, x0, x0 + R), (y0 - R, y0, y0 + R)
    if kind == "curvature":
        kw["curvature"] = (mag, -mag)
    return RitzPlate(plies, L, W, order=order, masses=masses, springs=springs, **kw)


def legendre_plies(table: dict, truth: dict, angle_offset: float = 0.0, top_offset: float = 0.0) -> list[tuple]:
    """(constants E1..G23 and density, angle deg, thickness m) per ply, bottom first, for
    :func:`bench.independent.legendre_safe.layers_of`: the table read by the Ritz plate's own
    reader; isotropic E, G give E1 = E2 = E3 = E, G12 = G13 = G23 = G, nu = E / 2G - 1; an
    orthotropic table without E3, nu13, nu23 is transversely isotropic (E3 = E2, nu13 = nu12,
    nu23 = E2 / 2 G23 - 1), as the specimen format documents."""
    plies, _, _ = plies_from_table(table, truth, angle_offset=angle_offset, top_offset=top_offset)
    rows = []
    for p in plies:
        c = {k: float(v) for k, v in p.constants.items()}
        if "E" in c:
            E = c["E"]
            G = c["G"] if "G" in c else E / (2.0 * (1.0 + c["nu"]))
            nu = E / (2.0 * G) - 1.0
            d = dict(E1=E, E2=E, E3=E, nu12=nu, nu13=nu, nu23=nu, G12=G, G13=G, G23=G)
        else:
            d = {k: c[k] for k in ("E1", "E2", "nu12", "G12", "G13", "G23")}
            d["E3"] = c.get("E3", c["E2"])
            d["nu13"] = c.get("nu13", c["nu12"])
            d["nu23"] = c.get("nu23", c["E2"] / (2.0 * c["G23"]) - 1.0)
        d["density"] = float(p.density)
        rows.append((d, float(p.angle_deg), float(p.thickness)))
    return rows


def legendre_group_velocity(plies: list[tuple], mode: str, direction_deg: float, f_hz, order: int) -> np.ndarray:
    """Group velocity (m/s) of A0 or S0 along ``direction_deg`` at ``f_hz`` from the independent
    Legendre model: at each frequency below the first cut-off it has exactly three propagating
    roots, S0 < SH0 < A0 by wavenumber (phase velocities c_S0 > c_SH0 > c_A0); more or fewer
    roots stop the bench rather than guess a label."""
    if mode not in ("A0", "S0"):
        raise ValueError(f"mode {mode!r}: the Legendre generator gives A0 and S0")
    plate = LegendrePlate(layers_of(plies, direction_deg), order)
    out = []
    for f in np.atleast_1d(np.asarray(f_hz, float)):
        roots = plate.roots(float(f))
        if len(roots) != 3:
            raise ValueError(f"{len(roots)} propagating roots at {f:g} Hz along {direction_deg:g} deg: "
                             "expected 3 (A0, SH0, S0 below the first cut-off)")
        out.append(roots[-1][1] if mode == "A0" else roots[0][1])
    return np.array(out)


def _waves(r: dict, table: dict) -> list[tuple[str, float, np.ndarray, np.ndarray]]:
    """(mode, direction, frequencies, true group velocities as the lab measures them) per set."""
    _, sets, band, path = SPECIMENS[r["specimen"]]
    sets = r["extra"].get("wave_sets", sets)
    band = r["extra"].get("band", band)
    kind, mag = r["kind"], r["magnitude"]
    gen = r["extra"].get("wave_generator", "safe")
    off = mag if kind == "misalignment" else 0.0
    top = mag if kind == "ply_angle_error" else 0.0
    if gen == "legendre":
        plies = legendre_plies(table, r["truth"], angle_offset=off, top_offset=top)

        def cg_of(mode, direction, f):
            return legendre_group_velocity(plies, mode, direction, f, LEGENDRE_ORDER[r["specimen"]])
    else:
        tab = copy.deepcopy(table)
        tab["materials"][tab["layup"]["material"]].update(r["truth"])
        ang = tab["layup"]["angles_deg"]
        tab["layup"]["angles_deg"] = [a + off + (top if i == len(ang) - 1 else 0.0) for i, a in enumerate(ang)]
        lam = specimen_from_dict(tab).laminate
        order = default_discretisation(lam, band[1])[0] + SAFE_EXTRA_ORDER

        def cg_of(mode, direction, f):
            return np.asarray(group_velocity(lam, f, mode=mode, direction_deg=direction, order=order), float)
    out = []
    for mode, direction, n in sets:
        f = np.geomspace(band[0], band[1], n) if n > 1 else np.array([float(np.sqrt(band[0] * band[1]))])
        cg = cg_of(mode, direction, f)
        t = (path + (mag if kind == "path_length" else 0.0)) / cg + (mag if kind == "timing_offset" else 0.0)
        out.append((mode, direction, f, path / t))
    return out


def _generate(r: dict) -> dict:
    table = SPECIMENS[r["specimen"]][0]()
    L, W = float(table["plate"]["length"]), float(table["plate"]["width"])
    acc, sup = _rig(L, W)
    out: dict = {"modal": None, "waves": []}
    if r["data"] in ("modal", "combined"):
        order = 12 if r["n_modes"] <= 20 else 16
        modes = ritz_for(r, table, order).solve(r["n_modes"])
        out["modal"] = modes.frequencies_hz.tolist()
        out["suspension_hz"] = modes.rigid_hz.tolist()
        out["ritz_order"] = order
    if r["data"] in ("waves", "combined"):
        out["waves"] = [(m, d, f.tolist(), c.tolist()) for m, d, f, c in _waves(r, table)]
    return out


def generated(r: dict) -> dict:
    """Noise-free features of a recipe (cached in ``CACHE`` by the recipe's hash)."""
    key = hashlib.sha1(json.dumps({k: v for k, v in r.items() if k not in ("noise_seed", "params", "prior")},
                                  sort_keys=True)
                       .encode()).hexdigest()[:16]
    path = CACHE / f"{key}.json"
    if path.exists():
        return json.loads(path.read_text())
    out = _generate(r)
    CACHE.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out))
    tmp.replace(path)
    return out


def draw(seed: int, kind: str, **force) -> Case:
    """The case of ``seed`` with condition ``kind`` (``force``: specimen, data, n_modes, noise,
    magnitude, wave_sets, band, fit = (constants fitted, prior), wave_generator)."""
    r = recipe(seed, kind, **force)
    g = generated(r)
    table = SPECIMENS[r["specimen"]][0]()
    L, W = float(table["plate"]["length"]), float(table["plate"]["width"])
    acc, sup = _rig(L, W)
    _, _, _, path = SPECIMENS[r["specimen"]]
    rng = np.random.default_rng(r["noise_seed"])
    doc: dict = {"specimen": copy.deepcopy(table)}
    clean = []
    if g["modal"] is not None:
        f = np.asarray(g["modal"])
        sig = r["noise"] * f
        doc["modal"] = {"frequencies_hz": (f + sig * rng.standard_normal(f.size)).tolist(), "sigma_hz": sig.tolist()}
        clean += f.tolist()
    doc["waves"] = []
    for mode, d, fr, cg in g["waves"]:
        cg = np.asarray(cg)
        sig = r["noise"] * cg
        doc["waves"].append({"mode": mode, "direction_deg": d, "frequency_hz": fr,
                             "group_velocity_m_s": (cg + sig * rng.standard_normal(cg.size)).tolist(),
                             "sigma_m_s": sig.tolist()})
        clean += cg.tolist()
    doc["rig"] = {"accelerometers": [{"x": x, "y": y, "mass_kg": ACCEL_MASS_KG} for x, y in acc],
                  "supports": [{"x": x, "y": y} for x, y in sup], "wave_path_m": path, "sensor_length_m": 0.0}
    params, prior = tuple(r["params"]), r["prior"]
    from engine.forward import EFFECTS
    unit = EFFECTS[kind].unit if kind in EFFECTS else {"glue_mass": "kg", "curvature": "1/m"}.get(kind, "1")
    return Case(int(seed), kind, r["magnitude"], unit, r["specimen"], r["n_modes"] if g["modal"] else 0,
                r["noise"], r["data"], doc, r["truth"], params, prior, clean,
                {"extra": r["extra"], "suspension_hz": g.get("suspension_hz"), "ritz_order": g.get("ritz_order"),
                 "wave_generator": None if r["data"] == "modal" else r["extra"]["wave_generator"]})
