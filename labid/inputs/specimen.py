"""Specimen files (TOML, CONTRACT section 1): read, validate, build a Laminate.

Every error names the file, the key and what was expected (UserError). Unknown keys
are errors naming the key (a typo would otherwise fall back to a default unseen).
Values are bounded where they enter (``LIMITS``: what a plate, a material and the
discretisation can hold); a modulus below 1e6 Pa is named as GPa typed as Pa.
Optional tables: ``[uncertainty]`` (standard uncertainties, SI; parsed by
``labid.uncertainty``) and ``[report]`` (strings/numbers for the report header).
"""
from __future__ import annotations

import math
import pkgutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from engine.laminate import Laminate, Material, PhysicsError, Ply

from ..base.errors import UserError
from .files import parse_toml, read_text_file
from .keys import check_keys

BUILTIN = {"cfrp": "cfrp_12ply.toml", "aluminium": "aluminium_3175.toml"}

#: (low, high) bounds of values where they enter (SI units). Moduli: 1 MPa (foams) to
#: 2 TPa (above diamond); density: 1 kg/m^3 (aerogels) to 25,000 (above osmium);
#: plate sides 1 mm to 100 m; plies 1 um to 1 m, at most 2,000 of them (the SAFE
#: discretisation holds a few nodes per ply); angles within one turn either way.
LIMITS = {"modulus": (1e6, 2e12), "density": (1.0, 25_000.0), "side": (1e-3, 100.0),
          "ply_thickness": (1e-6, 1.0), "angle_deg": (-360.0, 360.0), "plies": 2000,
          "poisson": (-1.0, 1.0)}
MODULI = ("E", "E1", "E2", "E3", "G", "G12", "G13", "G23")
TOP_KEYS = {"name", "plate", "materials", "layup", "plies", "uncertainty", "report"}
PLATE_KEYS = {"length", "width"}
MATERIAL_KEYS = {"density", "E", "G", "nu", "E1", "E2", "E3", "nu12", "nu13", "nu23", "G12", "G13", "G23"}
LAYUP_KEYS = {"material", "angles_deg", "ply_thickness"}
PLY_KEYS = {"material", "angle_deg", "thickness"}
#: ``[uncertainty]``: standard uncertainties in SI units (m, kg/m^3, kg)
UNCERTAINTY_KEYS = {"thickness", "length", "width", "density", "mass", "sensor_position",
                    "source_position", "path_length"}
#: ``[report]``: the report header (strings or numbers)
REPORT_KEYS = {"lab", "client", "operator", "specimen_id", "method", "temperature_c",
               "suspension", "revision", "report_number", "received", "condition", "deviations", "limits"}


def unit_slip(name: str, value: float, key: str, src: str | None = None) -> None:
    """UserError when modulus ``name`` (Pa) is out of ``LIMITS['modulus']``; a value below
    1e6 Pa is named as GPa typed as Pa."""
    lo, hi = LIMITS["modulus"]
    if 0 < value < lo:
        raise UserError(f"value {value:g} Pa for {name}: below {lo:g} Pa, looks like GPa typed as Pa; "
                        f"expected Pa ({value:g} GPa = {value * 1e9:.4g})", file=src, key=key)
    if value > hi:
        raise UserError(f"value {value:g} Pa for {name}: above {hi:g} Pa; expected a modulus in Pa",
                        file=src, key=key)


def _bounded(v: float, kind: str, key: str, src: str, what: str) -> float:
    lo, hi = LIMITS[kind]
    if not lo <= v <= hi:
        raise UserError(f"value {v:g}: outside [{lo:g}, {hi:g}]; expected {what}", file=src, key=key)
    return v


@dataclass(frozen=True)
class Specimen:
    """A rectangular plate: name, in-plane size (m) and laminate; ``uncertainty``: its
    ``[uncertainty]`` table as written (standard uncertainties, SI; checked)."""

    name: str
    length: float
    width: float
    laminate: Laminate
    source: str = "<inline>"
    uncertainty: Mapping[str, float] = field(default_factory=dict, compare=False, hash=False)

    @property
    def mass(self) -> float:
        """Plate mass, kg."""
        return self.length * self.width * self.laminate.thickness * self.laminate.mean_density


def _num(tab: Mapping[str, Any], key: str, where: str, src: str, *, positive=True,
         default: Any = ...) -> float:
    if key not in tab:
        if default is not ...:
            return default
        raise UserError("missing key; expected a number", file=src, key=f"{where}{key}")
    v = tab[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise UserError(f"value {v!r}: expected a number", file=src, key=f"{where}{key}")
    v = float(v)
    if not math.isfinite(v):
        raise UserError(f"value {v!r}: expected a finite number", file=src, key=f"{where}{key}")
    if positive and v > 0 and key in MODULI:
        unit_slip(key, v, f"{where}{key}", src)
    if positive and not v > 0:
        raise UserError(f"value {v!r}: expected a positive number", file=src, key=f"{where}{key}")
    return v


def _material(name: str, tab: Mapping[str, Any], src: str) -> Material:
    where = f"materials.{name}."
    if not isinstance(tab, Mapping):
        raise UserError("expected a table", file=src, key=f"materials.{name}")
    check_keys(tab, MATERIAL_KEYS, where, src)
    rho = _bounded(_num(tab, "density", where, src), "density", where + "density", src, "a density in kg/m^3")
    try:
        if "E" in tab and "E1" not in tab:
            E = _num(tab, "E", where, src)
            has_g, has_nu = "G" in tab, "nu" in tab
            if has_g == has_nu:
                raise UserError("expected exactly one of 'G' or 'nu' for an isotropic material",
                                file=src, key=f"{where}G")
            if has_g:
                mat = Material.isotropic_from(E, rho, G=_num(tab, "G", where, src), name=name)
            else:
                mat = Material.isotropic_from(E, rho, nu=_num(tab, "nu", where, src, positive=False), name=name)
        else:
            kw = {k: _num(tab, k, where, src) for k in ("E1", "E2", "G12", "G13", "G23")}
            kw["nu12"] = _num(tab, "nu12", where, src, positive=False)
            opt = {k: _num(tab, k, where, src, positive=(k == "E3"), default=None)
                   for k in ("E3", "nu13", "nu23")}
            mat = Material(density=rho, name=name, **kw, **opt)
        mat.check()
    except PhysicsError as e:
        raise UserError(str(e), file=src, key=f"materials.{name}") from None
    return mat


def _plies(doc: Mapping[str, Any], mats: dict[str, Material], src: str) -> tuple[Ply, ...]:
    def get_mat(name: Any, key: str) -> Material:
        if not isinstance(name, str) or name not in mats:
            raise UserError(f"material {name!r} is not defined; expected one of {sorted(mats)}",
                            file=src, key=key)
        return mats[name]

    if "plies" in doc:
        plies = doc["plies"]
        if not isinstance(plies, list) or not plies or not all(isinstance(p, Mapping) for p in plies):
            raise UserError("expected a non-empty array of [[plies]] tables", file=src, key="plies")
        if len(plies) > LIMITS["plies"]:
            raise UserError(f"{len(plies)} plies: expected at most {LIMITS['plies']}", file=src, key="plies")
        out = []
        for i, p in enumerate(plies):
            where = f"plies[{i}]."
            check_keys(p, PLY_KEYS, where, src)
            mat = get_mat(p.get("material"), where + "material")
            ang = _bounded(_num(p, "angle_deg", where, src, positive=False), "angle_deg",
                           where + "angle_deg", src, "an angle in degrees")
            t = _bounded(_num(p, "thickness", where, src), "ply_thickness", where + "thickness", src,
                         "a ply thickness in m")
            out.append(Ply(mat, ang, t))
        return tuple(out)
    if "layup" not in doc:
        raise UserError("missing table; expected [layup] or [[plies]]", file=src, key="layup")
    lay = doc["layup"]
    if not isinstance(lay, Mapping):
        raise UserError(f"value {lay!r}: expected a [layup] table", file=src, key="layup")
    check_keys(lay, LAYUP_KEYS, "layup.", src)
    mat = get_mat(lay.get("material"), "layup.material")
    angles = lay.get("angles_deg")
    if not isinstance(angles, list) or not angles or not all(
            isinstance(a, (int, float)) and not isinstance(a, bool) for a in angles):
        raise UserError(f"value {angles!r}: expected a non-empty list of angles in degrees",
                        file=src, key="layup.angles_deg")
    if len(angles) > LIMITS["plies"]:
        raise UserError(f"{len(angles)} plies: expected at most {LIMITS['plies']}", file=src,
                        key="layup.angles_deg")
    for i, a in enumerate(angles):
        _bounded(float(a), "angle_deg", f"layup.angles_deg[{i}]", src, "an angle in degrees")
    t = _bounded(_num(lay, "ply_thickness", "layup.", src), "ply_thickness", "layup.ply_thickness", src,
                 "a ply thickness in m")
    return tuple(Ply(mat, float(a), t) for a in angles)


def _optional_tables(doc: Mapping[str, Any], src: str) -> None:
    """Light checks of ``[uncertainty]`` and ``[report]`` (parsed by their own modules)."""
    unc = doc.get("uncertainty")
    if unc is not None:
        if not isinstance(unc, Mapping):
            raise UserError(f"value {unc!r}: expected a table of standard uncertainties (SI)",
                            file=src, key="uncertainty")
        check_keys(unc, UNCERTAINTY_KEYS, "uncertainty.", src)
        for k in unc:
            v = _num(unc, k, "uncertainty.", src, positive=False)
            if v < 0:
                raise UserError(f"value {v:g}: expected a standard uncertainty >= 0 (SI units)",
                                file=src, key=f"uncertainty.{k}")
        if "mass" in unc and "density" in unc:
            raise UserError(f"value {unc['mass']!r} with uncertainty.density {unc['density']!r} also given: "
                            "expected one of density (kg/m^3) or mass (kg, the plate weighed)",
                            file=src, key="uncertainty.mass")
    rep = doc.get("report")
    if rep is not None:
        if not isinstance(rep, Mapping):
            raise UserError(f"value {rep!r}: expected a table of report fields", file=src, key="report")
        check_keys(rep, REPORT_KEYS, "report.", src)
        for k, v in rep.items():
            if k == "limits":           # {constant: [low, high]} in SI, the statement of conformity
                check_limits(v, src)
                continue
            if isinstance(v, bool) or not isinstance(v, (str, int, float)):
                raise UserError(f"value {v!r}: expected a string or a number", file=src, key=f"report.{k}")
            if isinstance(v, str) and len(v) > 500:
                raise UserError(f"{len(v)} characters: expected at most 500", file=src, key=f"report.{k}")


def check_limits(lim: Any, src: str) -> None:
    """``[report.limits]``: ``NAME = [low, high]`` in SI units (a side may be ``nan``: open)."""
    if not isinstance(lim, Mapping):
        raise UserError(f"value {lim!r}: expected a table NAME = [low, high] (SI units)", file=src,
                        key="report.limits")
    for n, v in lim.items():
        ok = (isinstance(v, list) and len(v) == 2
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v))
        if not ok or (v[0] == v[0] and v[1] == v[1] and v[0] > v[1]):
            raise UserError(f"value {v!r}: expected [low, high] in SI units, low <= high (nan: no limit)",
                            file=src, key=f"report.limits.{n}")


def specimen_from_dict(doc: Mapping[str, Any], src: str = "<inline>") -> Specimen:
    """Build and validate a Specimen from a parsed TOML/JSON table."""
    if not isinstance(doc, Mapping):
        raise UserError(f"value {doc!r:.80}: expected a specimen table", file=src)
    check_keys(doc, TOP_KEYS, "", src)
    plate = doc.get("plate")
    if not isinstance(plate, Mapping):
        raise UserError("missing table; expected [plate] with length and width in m", file=src, key="plate")
    check_keys(plate, PLATE_KEYS, "plate.", src)
    length = _bounded(_num(plate, "length", "plate.", src), "side", "plate.length", src, "a length in m")
    width = _bounded(_num(plate, "width", "plate.", src), "side", "plate.width", src, "a width in m")
    mtabs = doc.get("materials")
    if not isinstance(mtabs, Mapping) or not mtabs:
        raise UserError("missing table; expected at least one [materials.NAME]", file=src, key="materials")
    mats = {name: _material(name, tab, src) for name, tab in mtabs.items()}
    plies = _plies(doc, mats, src)
    _optional_tables(doc, src)
    name = doc.get("name", Path(src).stem)
    if not isinstance(name, str):
        raise UserError(f"value {name!r}: expected a string", file=src, key="name")
    try:
        lam = Laminate(plies)
    except PhysicsError as e:
        raise UserError(str(e), file=src, key="layup") from None
    if not lam.thickness < min(length, width):
        raise UserError(f"thickness {lam.thickness:g} m: expected a plate thinner than its sides "
                        f"({min(length, width):g} m)", file=src, key="layup")
    return Specimen(name, length, width, lam, src, dict(doc.get("uncertainty") or {}))


def _builtin_text(name: str) -> str:
    """The TOML text of a built-in specimen (package data: from a zip too). ``pkgutil``, not
    ``importlib.resources``: that import (tempfile, zipfile) was ~8 ms of ``labid dispersion``'s
    ~0.35 s CPU (issue 29, session 26)."""
    return pkgutil.get_data("labid.data", BUILTIN[name]).decode("utf-8")


def load_specimen(path: str | Path) -> Specimen:
    """Read a specimen TOML file, or a built-in one by name ('cfrp', 'aluminium')."""
    p = str(path)
    if p in BUILTIN:
        text = _builtin_text(p)
        src = f"builtin:{p}"
    else:
        text = read_text_file(p, "a specimen TOML file")
        src = p
    return specimen_from_dict(parse_toml(text, src, "a specimen file"), src)


def specimen_text(spec: Specimen) -> str:
    """The TOML text a specimen was read from ('' for an inline one): what a run file keeps."""
    src = spec.source
    if src.startswith("builtin:"):
        return _builtin_text(src[8:])
    p = Path(src)
    return p.read_text() if p.is_file() else ""
