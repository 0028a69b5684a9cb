"""The shapes of the results labid stores under ``/results`` (issue 27: a results group
holding garbage made the report, the export and the panel fail with AttributeError).

``check_result(name, value, src)`` compares a decoded result with the shape labid writes
for ``name`` (``analysis``, ``identification*``, ``diagnosis``, ``gui``): every key the
readers (report, export, panel) use must have the type written there. Unknown keys and
absent keys pass (readers take them with ``.get``); a wrong type is a ``UserError``
naming the file and the key: the run is damaged, and every reader refuses it in one line.

Spec language: ``N`` a number or null (NaN is stored as null), ``R`` a number (never
null: readers format it), ``S`` a string, ``B`` a boolean, ``A`` anything, ``D`` any object, ``L`` any list; ``{"key": spec}`` an object
with those keys, ``{"*": spec}`` an object whose every value is ``spec``; ``[spec]`` a
list (or array) of ``spec``; a tuple: any of its specs.
"""
from __future__ import annotations

import json
import numbers
from typing import Any

import numpy as np

from ..base.errors import UserError

N, R, S, B, A, D, L = "number", "real", "string", "boolean", "any", "object", "list"
_NUMS = [N]
_PAR = {"*": N}                                   # a value per parameter name

FEATURES = {
    "specimen": (S, D),
    "modal": {"frequencies_hz": [R], "sigma_hz": _NUMS, "damping_ratio": _NUMS, "confidence": _NUMS,
              "mode_index": _NUMS, "mode_shapes": {"points": [_NUMS], "values": [_NUMS]}},
    "waves": ([{"mode": S, "direction_deg": R, "frequency_hz": _NUMS, "group_velocity_m_s": _NUMS,
                "sigma_m_s": _NUMS, "dropped": {"*": N}}], D),
    "rig": {"temperature_c": N, "accelerometers": [{"x": N, "y": N, "mass_kg": N}],
            "supports": [{"x": N, "y": N}], "wave_path_m": N, "sensor_length_m": N},
    "damping": {"modes": [{"frequency_hz": R, "loss_factor": N, "damping_ratio": N, "label": (S, N)}],
                "families": {"*": {"modes": L, "median_loss_factor": N}}},
    "analysis": {"notes": [S], "run": S},
}
IDENTIFICATION = {
    "parameters": {"*": {"value": N, "std": N, "identified": B}},
    "converged": B, "identified": B, "method": S, "message": S, "iterations": N, "specimen": S,
    "data": (S, [S]), "warnings": [(S, D)], "flags": [(S, D)], "sigma_scale": _PAR,
    "held": {"*": ({"value": N, "std": N}, N)},
    "residual": _PAR, "start": _PAR, "nominal": _PAR,
    "fit": {"chi2": N, "dof": N, "n_points": N, "chi2_per_dof": N, "p_value": N, "consistent": B,
            "identified": B, "std_scale": N, "flags": D, "unexplained_peaks": N},
    "correlation": {"names": [S], "matrix": [_NUMS]},
    "identifiability": {"parameters": {"*": {"rel_std": N, "conditional_rel_std": N, "identified": B,
                                             "constrained_by": [S], "reason": S}},
                        "poorly_identified": [S], "data_sets": {"*": D}, "condition_number": N},
    "pairing": [{"peak": N, "measured_hz": N, "predicted_hz": N, "mode_index": N, "family": (S, N)}],
    "unpaired_modes": [{"mode_index": N, "family": (S, N), "predicted_hz": N, "visibility": N}],
    "blocks": {"*": {"kind": S, "predicted": _NUMS, "observed": _NUMS, "relative": _NUMS, "rms_rel": N}},
    "history": [{"iteration": N, "cost": N, "params": _PAR}],
    "multi_start": [{"converged": B, "values": _PAR, "start": _PAR}],
    "multi_start_minima": [{"values": _PAR, "chi2_per_point": N, "n_starts": N}],
    "posterior": {"names": [S], "std": _PAR, "n_samples": N, "acceptance": N},
    "uncertainty_budget": {"coverage_factor": N, "coverage": S, "method": S, "notes": [S],
                           "inputs": [{"name": S, "value": N, "u": N, "unit": S, "source": S}],
                           "constants": {"*": {"value": N, "u_type_a": N, "u_type_b": N, "u_combined": N,
                                               "U": N, "U_rel": N,
                                               "contributions": {"*": {"sensitivity": N, "u": N, "share": N}}}},
                           "correlation": {"names": [S], "matrix": [_NUMS]}},
}
DIAGNOSIS = {
    "gap": {"*": (N, B, S)}, "verdict": S, "where": [(S, D)], "notes": [S], "diagnosis_notes": [S],
    "effects": [{"name": S, "magnitude": N, "std": N, "unit": S, "gap_after": N, "score": N, "delta_chi2": N,
                 "refitted": B, "detectable": B, "absorbed_fraction": N, "held_out_after": N,
                 "bias_in_constants_per_unit": _PAR}],
    "undetectable": [{"name": S, "absorbed_fraction": N, "unit": S, "bias_in_constants_per_unit": _PAR}],
    "confusable": L, "groups": [{"group": S, "n": N, "chi2": N, "share": N, "rms": N, "p_value": N}],
    "constants": {"*": _PAR},
    "features": {"labels": [S], "modality": [S], "set": [(S, N)], "residual_before": _NUMS,
                 "residual_after": _NUMS, "sigma": _NUMS, "mode_families": [(S, N)]},
    "identification": {"converged": B, "message": S, "source": S, "parameters": [S]},
    "model_sigma_hz": _NUMS,
}
ANALYSIS = {
    "features": ({"json": S}, D), "notes": [S], "settings": D,
    "peaks": {"*": _NUMS},
    "spectrum": {"frequencies_hz": _NUMS, "indicator": _NUMS, "kind": S},
    "arrivals": {"frequencies_hz": _NUMS, "times_s": _NUMS, "sigma_s": _NUMS, "wavelet": S, "channel_curve": S},
    "waves": {"*": {"frequency_hz": _NUMS, "group_velocity_m_s": _NUMS, "sigma_m_s": _NUMS, "valid": _NUMS}},
}
GUI = {"state_json": S}


def spec_of(name: str):
    """The spec of the results group ``name`` (None: not one labid's readers interpret)."""
    if name.startswith("identification") or name == "identify":
        return IDENTIFICATION
    if name in ("diagnosis", "gap", "diagnose"):
        return DIAGNOSIS
    if name == "analysis":
        return ANALYSIS
    if name == "features":
        return FEATURES
    if name == "gui":
        return GUI
    return None


def _fits(value: Any, spec) -> str | None:
    """'' if ``value`` fits ``spec``; else the path below it that does not (with what was found)."""
    if isinstance(spec, tuple):
        found = [_fits(value, s) for s in spec]
        return None if None in found else found[0]
    if spec == A:
        return None
    if spec in (N, R):
        ok = (value is None and spec == N) or (isinstance(value, (numbers.Real, np.number)) and not isinstance(
            value, (bool, np.bool_))) or (isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf")
        return None if ok else f": {type(value).__name__}, expected a number"
    if spec == S:
        return None if isinstance(value, str) else f": {type(value).__name__}, expected text"
    if spec == B:
        return None if isinstance(value, (bool, np.bool_)) else f": {type(value).__name__}, expected true/false"
    if spec == D:
        return None if isinstance(value, dict) else f": {type(value).__name__}, expected an object"
    if spec == L:
        return None if isinstance(value, (list, np.ndarray)) else f": {type(value).__name__}, expected a list"
    if isinstance(spec, list):
        if value is None:       # null: a list not computed (labid's readers treat it as absent)
            return None
        if isinstance(value, np.ndarray):
            ok = spec[0] in (N, R, A) and value.dtype.kind in "iufb" or spec[0] == S and value.dtype.kind in "OSU"
            return None if ok else f": an array of {value.dtype}, expected a list"
        if not isinstance(value, list):
            return f": {type(value).__name__}, expected a list"
        for i, x in enumerate(value):
            bad = _fits(x, spec[0])
            if bad is not None:
                return f"[{i}]{bad}"
        return None
    if not isinstance(value, dict):
        return f": {type(value).__name__}, expected an object"
    for k, v in value.items():
        sub = spec.get(k, spec.get("*"))
        if sub is None:
            continue
        bad = _fits(v, sub)
        if bad is not None:
            return f".{k}{bad}"
    return None


def _lengths(feats: Any) -> str | None:
    """The per-peak (per-point) lists of a features document that are not as long as its
    frequencies, as ``_fits`` words it (labid writes them equal; the export indexes them)."""
    if not isinstance(feats, dict):
        return None
    groups = [("modal", feats.get("modal"), "frequencies_hz", ("sigma_hz", "damping_ratio", "confidence", "mode_index"))]
    waves = feats.get("waves")
    groups += [(f"waves[{i}]", w, "frequency_hz", ("group_velocity_m_s", "sigma_m_s"))
               for i, w in enumerate(waves if isinstance(waves, list) else [])]
    for where, g, ref, keys in groups:
        if not isinstance(g, dict):
            continue
        n = 0 if g.get(ref) is None else len(g[ref])
        for k in keys:
            v, needed = g.get(k), k == "group_velocity_m_s"           # the others may be left out
            m = 0 if v is None else len(v)
            if (v is not None or needed) and m not in ((n,) if needed else (0, n)):
                return f".{where}.{k}: {m} values for {n} frequencies, expected one per frequency"
    return None


def check_result(name: str, value: Any, src: str) -> None:
    """UserError naming ``src`` and the key when the result ``name`` does not have the
    shape labid writes (a damaged run file); nothing for other groups."""
    spec = spec_of(name)
    if spec is None:
        return
    bad = _fits(value, spec)
    if bad is None and name == "analysis":
        feats = value.get("features") if isinstance(value, dict) else None
        if isinstance(feats, dict) and isinstance(feats.get("json"), str):
            try:
                feats = json.loads(feats["json"])
            except ValueError:
                bad = ".features.json: not JSON"
            else:
                bad = _fits(feats, FEATURES) or _lengths(feats)
                bad = None if bad is None else ".features" + bad
    if bad is None and name == "gui" and isinstance(value, dict) and isinstance(value.get("state_json"), str):
        try:
            json.loads(value["state_json"])
        except ValueError:
            bad = ".state_json: not JSON"
    if bad is not None:
        key, _, what = bad.partition(": ")
        raise UserError(f"damaged run file: {what}; expected a result as labid writes it",
                        file=src, key=f"/results/{name}{key}")
