"""The measured-features file (JSON, CONTRACT section 2): read, validate, write, parse.

The bridge between processing (``labid analyze``) and identification /
diagnosis. Any of ``modal``, ``waves``, ``rig`` may be absent. ``specimen`` is
a path relative to the JSON file (or a built-in name) or the specimen table
inline. JSON has no NaN: a velocity that could not be measured is ``null``
(read back as NaN). Every mistake raises ``UserError`` naming the file, the
key (``waves[0].frequency_hz[3]``), the value and what was expected; so does an
unknown key (``TOP_KEYS``, ``MODAL_KEYS``, ``WAVE_KEYS``, ``RIG_KEYS``; ``analysis`` is
free-form). Values are bounded where they enter (``LIMITS``). ``modal.mode_index``
(optional): the predicted elastic-mode index (0-based, as identify's ``pairing``) of each
peak, or null; a labelled peak is paired with that mode only.
A ``specimen`` path must name a regular file of at most ``MAX_SPECIMEN_BYTES``.

:func:`parse_features` is the one conversion of a document into the engine's
in-memory form, ``engine.features.Features`` (with the specimen it names and
the notes on assumed sigmas); :func:`features_document` the way back.
Identification and diagnosis both start from it.
"""
from __future__ import annotations

import json
import math
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from engine.features import Features, ModalData, RigLayout, WaveData

from ..base import atomic
from ..base.errors import UserError
from .files import read_json_file
from .featurelimits import (LIMITS, MAX_SPECIMEN_BYTES, MODAL_KEYS, RIG_KEYS, SHAPES_KEYS, TOP_KEYS,
                            WAVE_KEYS, mode_index, position, within)
from .keys import check_keys
from .specimen import BUILTIN, Specimen, load_specimen, specimen_from_dict

__all__ = ["validate_features", "read_features", "write_features", "features_text",
           "specimen_of", "MODE_LABEL", "parse_features", "ParsedFeatures", "features_document",
           "DEFAULT_MODAL_SIGMA_REL", "DEFAULT_WAVE_SIGMA_REL"]

MODE_LABEL = re.compile(r"^(A|S|SH)\d+$")
#: sigmas assumed when a features file gives none (relative to the value)
DEFAULT_MODAL_SIGMA_REL = 1e-3
DEFAULT_WAVE_SIGMA_REL = 1e-2


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(v: Any, key: str, src: str, *, positive=False, nonneg=False, null_ok=False) -> float:
    if v is None and null_ok:
        return math.nan
    if not _is_num(v) or not math.isfinite(v):
        what = "a finite number" + (" or null" if null_ok else "")
        raise UserError(f"value {v!r}: expected {what}", file=src, key=key)
    if positive and not v > 0:
        raise UserError(f"value {v!r}: expected a positive number", file=src, key=key)
    if nonneg and v < 0:
        raise UserError(f"value {v!r}: expected a number >= 0", file=src, key=key)
    return float(v)


def _numbers(tab: Mapping, key: str, where: str, src: str, *, n: int | None = None, required=True,
             bound: str | None = None, **kw) -> list[float] | None:
    full = where + key
    if key not in tab:
        if required:
            raise UserError("missing key; expected a list of numbers", file=src, key=full)
        return None
    v = tab[key]
    if not isinstance(v, list):
        raise UserError(f"value {v!r}: expected a list of numbers", file=src, key=full)
    if n is not None and len(v) != n:
        raise UserError(f"{len(v)} values: expected {n}, one per frequency", file=src, key=full)
    if len(v) > LIMITS["n_values"]:
        raise UserError(f"{len(v)} values: expected at most {LIMITS['n_values']}", file=src, key=full)
    out = [_number(x, f"{full}[{i}]", src, **kw) for i, x in enumerate(v)]
    if bound is not None:
        for i, x in enumerate(out):
            within(x, bound, f"{full}[{i}]", src)
    return out


def _object(v: Any, key: str, src: str) -> Mapping:
    if not isinstance(v, Mapping):
        raise UserError(f"value {v!r}: expected an object", file=src, key=key)
    return v


def _modal(m: Any, src: str) -> dict:
    m = _object(m, "modal", src)
    check_keys(m, MODAL_KEYS, "modal.", src)
    out = dict(m)
    f = _numbers(m, "frequencies_hz", "modal.", src, positive=True, bound="frequency_hz")
    if len(f) > LIMITS["n_modes"]:
        raise UserError(f"{len(f)} frequencies: expected at most {LIMITS['n_modes']}", file=src,
                        key="modal.frequencies_hz")
    out["frequencies_hz"] = f
    s = _numbers(m, "sigma_hz", "modal.", src, n=len(f), required=False, positive=True, bound="sigma_hz")
    if s is not None:
        out["sigma_hz"] = s
    for key in ("damping_ratio", "confidence"):
        if m.get(key) is not None:
            out[key] = _numbers(m, key, "modal.", src, n=len(f), null_ok=True)
    if m.get("mode_index") is not None:
        out["mode_index"] = mode_index(m["mode_index"], len(f), src)
    if m.get("mode_shapes") is not None:
        ms = _object(m["mode_shapes"], "modal.mode_shapes", src)
        check_keys(ms, SHAPES_KEYS, "modal.mode_shapes.", src)
        pts = ms.get("points")
        if not isinstance(pts, list) or not pts:
            raise UserError(f"value {pts!r}: expected a non-empty list of [x, y] points in m",
                            file=src, key="modal.mode_shapes.points")
        points = []
        for j, p in enumerate(pts):
            key = f"modal.mode_shapes.points[{j}]"
            if not isinstance(p, list) or len(p) != 2:
                raise UserError(f"value {p!r}: expected [x, y] in m", file=src, key=key)
            points.append([_number(p[0], key + "[0]", src), _number(p[1], key + "[1]", src)])
        vals = ms.get("values")
        if not isinstance(vals, list) or len(vals) != len(f):
            raise UserError(f"expected a list of {len(f)} rows (one per frequency) of {len(points)} values",
                            file=src, key="modal.mode_shapes.values")
        rows = []
        for i, row in enumerate(vals):
            key = f"modal.mode_shapes.values[{i}]"
            if not isinstance(row, list) or len(row) != len(points):
                raise UserError(f"value {row!r}: expected {len(points)} values, one per point", file=src, key=key)
            rows.append([_number(x, f"{key}[{j}]", src) for j, x in enumerate(row)])
        out["mode_shapes"] = {**ms, "points": points, "values": rows}
    return out


def _waves(w: Any, src: str) -> list[dict]:
    if not isinstance(w, list):
        raise UserError(f"value {w!r}: expected a list of wave curves", file=src, key="waves")
    out = []
    for i, c in enumerate(w):
        where = f"waves[{i}]."
        c = _object(c, f"waves[{i}]", src)
        check_keys(c, WAVE_KEYS, where, src)
        mode = c.get("mode", "A0")
        if not isinstance(mode, str) or not MODE_LABEL.match(mode):
            raise UserError(f"value {mode!r}: expected a mode label such as 'A0', 'S0', 'SH0', 'A1'",
                            file=src, key=where + "mode")
        d = within(_number(c.get("direction_deg", 0.0), where + "direction_deg", src), "angle_deg",
                    where + "direction_deg", src)
        f = _numbers(c, "frequency_hz", where, src, positive=True, bound="frequency_hz")
        v = _numbers(c, "group_velocity_m_s", where, src, n=len(f), positive=True, null_ok=True,
                     bound="velocity_m_s")
        s = _numbers(c, "sigma_m_s", where, src, n=len(f), required=False, positive=True, null_ok=True,
                     bound="velocity_m_s")
        item = {**c, "mode": mode, "direction_deg": d, "frequency_hz": f, "group_velocity_m_s": v}
        if s is not None:
            item["sigma_m_s"] = s
        out.append(item)
    return out


def _rig(r: Any, src: str) -> dict:
    r = _object(r, "rig", src)
    check_keys(r, RIG_KEYS, "rig.", src)
    out = dict(r)
    if "temperature_c" in r:
        out["temperature_c"] = within(_number(r["temperature_c"], "rig.temperature_c", src),
                                       "temperature_c", "rig.temperature_c", src)
    for key, fields in (("accelerometers", ("x", "y", "mass_kg")), ("supports", ("x", "y"))):
        if key not in r:
            continue
        lst = r[key]
        if not isinstance(lst, list):
            raise UserError(f"value {lst!r}: expected a list of objects", file=src, key=f"rig.{key}")
        items = []
        for i, a in enumerate(lst):
            a = _object(a, f"rig.{key}[{i}]", src)
            check_keys(a, set(fields), f"rig.{key}[{i}].", src)
            item = dict(a)
            for fld in fields:
                if fld == "mass_kg" and fld not in a:
                    continue
                if fld not in a:
                    raise UserError("missing key; expected a number", file=src, key=f"rig.{key}[{i}].{fld}")
                k = f"rig.{key}[{i}].{fld}"
                item[fld] = (within(_number(a[fld], k, src, nonneg=True), "mass_kg", k, src)
                             if fld == "mass_kg" else position(a[fld], k, src))
            items.append(item)
        declared = [i for i, a in enumerate(items) if "mass_kg" in a]
        if key == "accelerometers" and 0 < len(declared) < len(items):
            # issue 27: a mass left out was read as 0 kg beside the others' grams; the fit could not
            # match the measured peaks and identify took ten times its usual cost
            i = next(i for i in range(len(items)) if i not in declared)
            raise UserError(f"missing key while accelerometers {declared} declare theirs; expected the mass in kg "
                            "of every accelerometer (0 for one that adds none): a sensor taken as massless "
                            "shifts the model's frequencies and makes the fit fail",
                            file=src, key=f"rig.accelerometers[{i}].mass_kg")
        out[key] = items
    if "wave_path_m" in r:
        out["wave_path_m"] = within(_number(r["wave_path_m"], "rig.wave_path_m", src, positive=True),
                                     "length_m", "rig.wave_path_m", src)
    if "sensor_length_m" in r:
        out["sensor_length_m"] = within(_number(r["sensor_length_m"], "rig.sensor_length_m", src, nonneg=True),
                                         "length_m", "rig.sensor_length_m", src)
    if r.get("wavelet") is not None:
        wl = _object(r["wavelet"], "rig.wavelet", src)
        check_keys(wl, {"bandwidth", "center"}, "rig.wavelet.", src)
        for k in wl:
            v = _number(wl[k], f"rig.wavelet.{k}", src, positive=True)
            if v > 1e3:
                raise UserError(f"value {v:g}: expected at most 1000", file=src, key=f"rig.wavelet.{k}")
    return out


def validate_features(doc: Any, src: str = "<features>") -> dict:
    """A checked copy of a features document (numbers as floats, null velocities as NaN).

    An unknown key is an error naming it (labid.inputs.featurelimits holds the keys).
    """
    doc = _object(doc, "(top level)", src)
    check_keys(doc, TOP_KEYS, "", src)
    out = dict(doc)
    if doc.get("analysis") is not None:
        _object(doc["analysis"], "analysis", src)
    if doc.get("damping") is not None:
        _object(doc["damping"], "damping", src)
    if "specimen" in doc and doc["specimen"] is not None:
        s = doc["specimen"]
        if isinstance(s, str):
            if not s or "\0" in s or len(s) > 4096:
                raise UserError("expected a specimen file path (no NUL byte, at most 4096 characters) "
                                "or table", file=src, key="specimen")
        elif isinstance(s, Mapping):
            specimen_from_dict(s, f"{src}#specimen")  # validates, raises UserError
        else:
            raise UserError(f"value {s!r}: expected a specimen file path or an inline table",
                            file=src, key="specimen")
    if doc.get("modal") is not None:
        out["modal"] = _modal(doc["modal"], src)
    if doc.get("waves") is not None:
        out["waves"] = _waves(doc["waves"], src)
    if doc.get("rig") is not None:
        out["rig"] = _rig(doc["rig"], src)
    return out


def read_features(path: str | Path) -> dict:
    """Read and validate a features JSON file."""
    p = Path(path)
    return validate_features(read_json_file(p, "a features JSON file"), str(p))


def specimen_of(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>") -> Specimen:
    """The specimen a features document refers to (path relative to ``base_dir``, built-in name, or table)."""
    s = doc.get("specimen")
    if s is None:
        raise UserError("missing key; expected a specimen file path or table", file=src, key="specimen")
    if isinstance(s, Mapping):
        return specimen_from_dict(s, f"{src}#specimen")
    p = Path(s)
    full = p if p.is_absolute() else Path(base_dir) / p
    if s in BUILTIN and not full.exists():
        return load_specimen(s)
    try:
        st = full.stat()
    except OSError as e:
        raise UserError(f"cannot read the specimen file ({e.strerror}); expected a specimen TOML file",
                        file=src, key="specimen") from None
    if not stat.S_ISREG(st.st_mode):
        raise UserError("not a regular file; expected a specimen TOML file", file=src, key="specimen")
    if st.st_size > MAX_SPECIMEN_BYTES:
        raise UserError(f"{st.st_size} bytes: expected a specimen TOML file of at most {MAX_SPECIMEN_BYTES}",
                        file=src, key="specimen")
    return load_specimen(full)


def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if hasattr(v, "tolist"):
        return _jsonable(v.tolist())
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, Path):
        return str(v)
    return v


def features_text(doc: Mapping, src: str = "<features>") -> str:
    """Validated JSON text of a features document (NaN written as null)."""
    clean = _jsonable(doc)
    validate_features(clean, src)
    return json.dumps(clean, indent=2, allow_nan=False) + "\n"


def write_features(path: str | Path, doc: Mapping, *, specimen_path: str | Path | None = None) -> dict:
    """Validate and write a features file; returns the document written.

    ``specimen_path`` (a file path relative to the current directory, or
    absolute) is stored relative to the JSON file's directory.
    """
    p = Path(path)
    out = dict(doc)
    if specimen_path is not None:
        sp = str(specimen_path)
        out["specimen"] = sp if sp in BUILTIN else os.path.relpath(Path(sp).resolve(), p.resolve().parent)
    text = features_text(out, str(p))
    atomic.write_text(p, text)                 # temp + rename: never half a file (issue 27)
    return json.loads(text)


# ---------------------------------------------------------------------------
# document <-> engine.features.Features
# ---------------------------------------------------------------------------
def _nan_to_null(v: Any) -> Any:
    """JSON view of a (possibly already validated) document: NaN -> None."""
    if isinstance(v, Mapping):
        return {k: _nan_to_null(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_nan_to_null(x) for x in v]
    if isinstance(v, np.ndarray):
        return _nan_to_null(v.tolist())
    if isinstance(v, float) and math.isnan(v):
        return None
    return v


def _opt_number(doc: Mapping, key: str, where: str, src: str, default=None) -> float | None:
    v = doc.get(key, default)
    if v is None:
        return None
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise UserError(f"value {v!r}: expected a number", file=src, key=f"{where}{key}") from None
    if not math.isfinite(v):
        raise UserError(f"value {v!r}: expected a finite number", file=src, key=f"{where}{key}")
    return v


def _sigma(values: np.ndarray, given: Any, default_rel: float, key: str, notes: list[str]) -> np.ndarray:
    if given is None:
        notes.append(f"{key} absent: assuming {default_rel:.1%} of the values")
        return default_rel * values
    return np.asarray(given, dtype=float)


def _rig_layout(rig: Mapping, src: str) -> RigLayout:
    wl_ = rig.get("wavelet") or {}
    if not isinstance(wl_, Mapping):
        raise UserError(f"value {wl_!r}: expected an object {{bandwidth, center}}", file=src,
                        key="rig.wavelet")
    acc = rig.get("accelerometers") or []
    return RigLayout(
        tuple((a["x"], a["y"]) for a in acc),
        tuple((a["x"], a["y"]) for a in rig.get("supports") or []),
        rig.get("wave_path_m"),
        float(rig.get("sensor_length_m") or 0.0),
        rig.get("temperature_c"),
        _opt_number(wl_, "bandwidth", "rig.wavelet.", src, 2.0),
        _opt_number(wl_, "center", "rig.wavelet.", src, 5.0),
        tuple(float(a.get("mass_kg") or 0.0) for a in acc))


@dataclass(frozen=True)
class ParsedFeatures:
    """A features document in the engine's form, the specimen it names, and notes
    (sigmas assumed where the document gives none)."""

    features: Features
    specimen: Specimen
    notes: tuple[str, ...] = ()


def parse_features(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>", *,
                   specimen: Specimen | None = None) -> ParsedFeatures:
    """Validate a features document and convert it into ``engine.features.Features``.

    ``specimen`` replaces the one the document names (path relative to
    ``base_dir``, built-in name or inline table). NaN in an in-memory document
    counts as null. Absent sigmas become DEFAULT_MODAL_SIGMA_REL /
    DEFAULT_WAVE_SIGMA_REL of the values (with a note); unmeasured velocities
    (null) stay NaN: the consumer decides what to drop.
    """
    doc = validate_features(_nan_to_null(doc), src)
    spec = specimen if specimen is not None else specimen_of(doc, base_dir, src)
    notes: list[str] = []
    modal = None
    m = doc.get("modal")
    if m is not None:
        f = np.asarray(m["frequencies_hz"], dtype=float)
        sig = _sigma(f, m.get("sigma_hz"), DEFAULT_MODAL_SIGMA_REL, "modal.sigma_hz", notes)
        pts = vals = None
        if m.get("mode_shapes") is not None:
            pts = np.asarray(m["mode_shapes"]["points"], float)
            vals = np.asarray(m["mode_shapes"]["values"], float)
        modal = ModalData(f, sig, pts, vals)
    waves = []
    for i, w in enumerate(doc.get("waves") or []):
        cg = np.asarray(w["group_velocity_m_s"], dtype=float)
        sig = _sigma(cg, w.get("sigma_m_s"), DEFAULT_WAVE_SIGMA_REL, f"waves[{i}].sigma_m_s", notes)
        waves.append(WaveData(w["mode"], float(w["direction_deg"]), np.asarray(w["frequency_hz"], dtype=float),
                              cg, sig))
    rig = _rig_layout(doc.get("rig") or {}, src)
    mi = (m or {}).get("mode_index")
    feats = Features(spec.laminate, spec.length, spec.width, rig, modal, tuple(waves),
                     specimen_name=spec.name, mode_index=tuple(mi) if mi is not None else None)
    return ParsedFeatures(feats, spec, tuple(notes))


def features_document(features: Features, specimen: Any) -> dict:
    """The features document (CONTRACT section 2) of ``features``; ``specimen`` is
    what goes under ``specimen`` (a path, a built-in name or a table). NaN stays
    NaN (written as null by :func:`write_features`)."""
    doc: dict[str, Any] = {"specimen": specimen}
    md = features.modal
    if md is not None:
        doc["modal"] = {"frequencies_hz": np.asarray(md.frequency_hz, float).tolist(),
                        "sigma_hz": np.broadcast_to(md.sigma_hz, np.shape(md.frequency_hz)).tolist()}
        if features.mode_index is not None:
            doc["modal"]["mode_index"] = list(features.mode_index)
        if md.shapes is not None:
            doc["modal"]["mode_shapes"] = {"points": np.asarray(md.points, float).tolist(),
                                           "values": np.asarray(md.shapes, float).tolist()}
    doc["waves"] = [{"mode": w.mode, "direction_deg": w.direction_deg,
                     "frequency_hz": np.asarray(w.frequency_hz, float).tolist(),
                     "group_velocity_m_s": np.asarray(w.group_velocity_m_s, float).tolist(),
                     "sigma_m_s": np.broadcast_to(w.sigma_m_s, np.shape(w.frequency_hz)).tolist()}
                    for w in features.waves]
    rig = features.rig
    r: dict[str, Any] = {}
    if rig.temperature_c is not None:
        r["temperature_c"] = rig.temperature_c
    masses = rig.accelerometer_masses
    r["accelerometers"] = [{"x": x, "y": y, **({"mass_kg": masses[i]} if masses else {})}
                           for i, (x, y) in enumerate(rig.accelerometers)]
    r["supports"] = [{"x": x, "y": y} for x, y in rig.supports]
    if rig.wave_path_m is not None:
        r["wave_path_m"] = rig.wave_path_m
    r["sensor_length_m"] = rig.sensor_length_m
    if (rig.wavelet_bandwidth, rig.wavelet_center) != (RigLayout.wavelet_bandwidth, RigLayout.wavelet_center):
        r["wavelet"] = {"bandwidth": rig.wavelet_bandwidth, "center": rig.wavelet_center}
    doc["rig"] = r
    return doc
