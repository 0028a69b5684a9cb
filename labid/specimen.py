"""Specimen files (TOML, CONTRACT section 1): read, validate, build a Laminate.

Every error names the file, the key and what was expected (UserError).
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

from engine.laminate import Laminate, Material, PhysicsError, Ply

from .errors import UserError

BUILTIN = {"cfrp": "cfrp_12ply.toml", "aluminium": "aluminium_3175.toml"}


@dataclass(frozen=True)
class Specimen:
    """A rectangular plate: name, in-plane size (m) and laminate."""

    name: str
    length: float
    width: float
    laminate: Laminate
    source: str = "<inline>"

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
    if positive and not v > 0:
        raise UserError(f"value {v!r}: expected a positive number", file=src, key=f"{where}{key}")
    return v


def _material(name: str, tab: Mapping[str, Any], src: str) -> Material:
    where = f"materials.{name}."
    if not isinstance(tab, Mapping):
        raise UserError("expected a table", file=src, key=f"materials.{name}")
    rho = _num(tab, "density", where, src)
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
        if name not in mats:
            raise UserError(f"material {name!r} is not defined; expected one of {sorted(mats)}",
                            file=src, key=key)
        return mats[name]

    if "plies" in doc:
        plies = doc["plies"]
        if not isinstance(plies, list) or not plies:
            raise UserError("expected a non-empty array of [[plies]] tables", file=src, key="plies")
        out = []
        for i, p in enumerate(plies):
            where = f"plies[{i}]."
            mat = get_mat(p.get("material"), where + "material")
            ang = _num(p, "angle_deg", where, src, positive=False)
            out.append(Ply(mat, ang, _num(p, "thickness", where, src)))
        return tuple(out)
    if "layup" not in doc:
        raise UserError("missing table; expected [layup] or [[plies]]", file=src, key="layup")
    lay = doc["layup"]
    mat = get_mat(lay.get("material"), "layup.material")
    angles = lay.get("angles_deg")
    if not isinstance(angles, list) or not angles or not all(
            isinstance(a, (int, float)) and not isinstance(a, bool) for a in angles):
        raise UserError(f"value {angles!r}: expected a non-empty list of angles in degrees",
                        file=src, key="layup.angles_deg")
    t = _num(lay, "ply_thickness", "layup.", src)
    return tuple(Ply(mat, float(a), t) for a in angles)


def specimen_from_dict(doc: Mapping[str, Any], src: str = "<inline>") -> Specimen:
    """Build and validate a Specimen from a parsed TOML/JSON table."""
    plate = doc.get("plate")
    if not isinstance(plate, Mapping):
        raise UserError("missing table; expected [plate] with length and width in m", file=src, key="plate")
    length = _num(plate, "length", "plate.", src)
    width = _num(plate, "width", "plate.", src)
    mtabs = doc.get("materials")
    if not isinstance(mtabs, Mapping) or not mtabs:
        raise UserError("missing table; expected at least one [materials.NAME]", file=src, key="materials")
    mats = {name: _material(name, tab, src) for name, tab in mtabs.items()}
    plies = _plies(doc, mats, src)
    return Specimen(str(doc.get("name", Path(src).stem)), length, width, Laminate(plies), src)


def load_specimen(path: str | Path) -> Specimen:
    """Read a specimen TOML file, or a built-in one by name ('cfrp', 'aluminium')."""
    p = str(path)
    if p in BUILTIN:
        text = resources.files("labid.data").joinpath(BUILTIN[p]).read_text()
        src = f"builtin:{p}"
    else:
        try:
            text = Path(p).read_text()
        except FileNotFoundError:
            raise UserError("file not found; expected a specimen TOML file", file=p) from None
        except OSError as e:
            raise UserError(f"cannot read: {e.strerror}", file=p) from None
        src = p
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise UserError(f"not valid TOML ({e})", file=src) from None
    return specimen_from_dict(doc, src)
