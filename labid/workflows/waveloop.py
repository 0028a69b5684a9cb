"""Pick <-> identify: the wave picks redone with the identified constants until they stop changing.

What a careful analyst does by hand (issue 24). The first wave analysis predicts the packets
(windows, echoes, foreign packets' levels) from the specimen file's constants, rescaled by
what the records show (``engine.wavefeatures.survey``); when those constants are far off, the
predicted shapes and the echoes of other directions are still off. So:

1. identify the constants from the features (modal and waves, ``labid.workflows.identification``);
2. analyse the wave shots again with the identified constants as the nominal model;
3. stop when the picks are a fixed point, judged on the curves and the constants, not on
   the points' identity (a curve's few points land on other frequencies each round when the
   band follows the nominal, session 29: "added 4, lost 3" every round on an unmoved curve):

   - the constants: the identification from the current picks moved every determined
     constant by at most ``TOL_STD`` of its std from the constants those picks were made
     with (the file's in round 1). The picks then reproduce their own model: stop, no
     re-pick (``constants_shift_std`` in the round's entry);
   - the curves (``curve_changes``): after the re-pick, every new point within the previous
     curve's frequency span against the previous curve interpolated (a cubic spline)
     at its frequency, and every previous point within the new span against the new curve,
     |change| / sqrt(sigma_new^2 + sigma_old^2); stop when the largest is at most
     ``TOL_CURVE``, no curve (mode, direction) appeared or vanished, and each curve's span
     ends moved by at most ``SPAN_TOL`` of its mean point spacing (points added or lost
     only where the span changed count);

   or after ``max_iter`` rounds, or when the identification cannot determine the constants
   (insufficient data, or no constant with a relative std below ``MAX_REL_STD``): the picks
   then stay the last ones. Only determined constants replace the nominal ones.
   ``pick_changes`` (points matched by frequency within 0.5 %: added, lost, largest shift
   in sigmas) is still recorded in each round, no longer a stopping rule.

Each round is recorded in the features' ``analysis.iterations`` (CONTRACT section 2, an
optional key): the constants used, the points per curve, what changed. The features keep
the specimen file's constants as their specimen (identify starts from them again).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from typing import Any, Callable, Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from engine.laminate import PhysicsError
from engine.safe import ply_stiffness

from ..inputs.rig import rig_from_text
from ..inputs.specimen import Specimen, specimen_from_dict
from ..store import RunStore
from .analysis import Analysis, AnalysisSettings, wave_features
from .identification.estimation import problem_from_features, run as identify

__all__ = ["iterate_store", "pick_changes", "curve_changes", "curves_converged", "MAX_ITER", "TOL_SIGMA", "TOL_STD", "TOL_CURVE",
           "SPAN_TOL", "MAX_REL_STD"]

MAX_ITER = 4
TOL_SIGMA = 0.3          # pick_changes' old point-identity tolerance (recorded, no longer a rule)
# constants: largest |change| / std of a fixed point. Between rounds the constants come from
# other points (other frequencies) of the same records, so they differ by a fraction of their
# std even when the model no longer moves (session 29, seed 0: 0.53-0.55 std in rounds 2-4)
TOL_STD = 1.0
TOL_CURVE = 1.0          # curves: largest |change| / sqrt(s_new^2 + s_old^2) of a fixed point
# curves: each end of the span may move by this fraction of the previous curve's mean point
# spacing (the points' frequencies follow the nominal: seed 0's ends moved 0.1-0.3 spacing a
# round; a point beyond an end by more than half a spacing is a point the curve gained or lost)
SPAN_TOL = 0.5
MAX_REL_STD = 0.2


def pick_changes(old: Sequence[dict], new: Sequence[dict], rel_tol: float = 0.005) -> dict:
    """How the wave curves ``new`` differ from ``old`` (features' ``waves`` lists): points
    added and lost (a point is the same within ``rel_tol`` in frequency, same mode and
    direction), and the largest |velocity change| / sigma of the points in both."""
    def pts(ws):
        return {(w["mode"], round(float(w["direction_deg"]), 3)): list(zip(w["frequency_hz"], w["group_velocity_m_s"],
                                                                         w["sigma_m_s"])) for w in ws}
    a, b = pts(old), pts(new)
    added = lost = 0
    shift = 0.0
    for key in set(a) | set(b):
        pa, pb = a.get(key, []), b.get(key, [])
        used = set()
        for f, v, s in pb:
            j = next((j for j, (g, _, _) in enumerate(pa) if j not in used and abs(g - f) <= rel_tol * f), None)
            if j is None:
                added += 1
                continue
            used.add(j)
            sig = max(min(s, pa[j][2]), 1e-12)
            shift = max(shift, abs(v - pa[j][1]) / sig)
        lost += len(pa) - len(used)
    return {"added": added, "lost": lost, "max_shift_sigma": float(shift)}


def _curves(ws) -> dict:
    out = {}
    for w in ws:
        f = np.asarray(w["frequency_hz"], float)
        o = np.argsort(f)
        out[(w["mode"], round(float(w["direction_deg"]), 3))] = (
            f[o], np.asarray(w["group_velocity_m_s"], float)[o], np.asarray(w["sigma_m_s"], float)[o])
    return out


def _interp(x, xp, yp):
    """The curve through (xp, yp) at x: a not-a-knot cubic spline from 3 points (exact on a
    cubic: a few A0 points around the group velocity's maximum, where linear interpolation is
    off by about one sigma, session 29 seed 0, 36 kHz apart near 130 kHz), linear below."""
    x = np.clip(x, xp[0], xp[-1])
    if xp.size >= 3 and np.all(np.diff(xp) > 0):
        return CubicSpline(xp, yp)(x)
    return np.interp(x, xp, yp)


def _against(f, v, s, ref, rel_tol) -> tuple[float, int, int]:
    """Points (f, v, s) inside the span of the curve ``ref`` against it interpolated at their
    frequency: largest |dv| / sqrt(s^2 + s_ref^2), points compared, points outside."""
    fr, vr, sr = ref
    inside = (f >= fr[0] * (1 - rel_tol)) & (f <= fr[-1] * (1 + rel_tol))
    if not inside.any():
        return 0.0, 0, int(f.size)
    fi = f[inside]
    z = np.abs(v[inside] - _interp(fi, fr, vr)) / np.maximum(np.hypot(s[inside], np.interp(fi, fr, sr)), 1e-12)
    return float(z.max()), int(inside.sum()), int(f.size - inside.sum())


def curve_changes(old: Sequence[dict], new: Sequence[dict], rel_tol: float = 0.005) -> dict:
    """How the wave curves ``new`` differ from ``old`` as curves (rule in the module docstring):
    ``curve_shift_sigma`` (largest |dv| / sqrt(s_new^2 + s_old^2) over the points of either
    curve inside the other's span, the other interpolated by ``_interp``),
    ``compared`` points, ``span_added`` / ``span_lost`` (points outside the other curve's
    span), ``span_change`` (largest move of a span end / the old curve's mean point spacing,
    a tenth of its frequency for a one-point curve), ``curves_added`` / ``curves_lost``."""
    a, b = _curves(old), _curves(new)
    out = {"curve_shift_sigma": 0.0, "compared": 0, "span_added": 0, "span_lost": 0, "span_change": 0.0,
           "curves_added": len(set(b) - set(a)), "curves_lost": len(set(a) - set(b))}
    for key in set(a) & set(b):
        (fa, va, sa), (fb, vb, sb) = a[key], b[key]
        if not fa.size or not fb.size:
            out["curves_added" if fb.size else "curves_lost"] += int(bool(fa.size or fb.size))
            continue
        z1, n1, add = _against(fb, vb, sb, a[key], rel_tol)
        z2, n2, lost = _against(fa, va, sa, b[key], rel_tol)
        spacing = (fa[-1] - fa[0]) / (fa.size - 1) if fa.size > 1 and fa[-1] > fa[0] else 0.1 * fa[0]
        moved = max(abs(fb[0] - fa[0]), abs(fb[-1] - fa[-1]))
        out.update(curve_shift_sigma=max(out["curve_shift_sigma"], z1, z2), compared=out["compared"] + n1 + n2,
                   span_added=out["span_added"] + add, span_lost=out["span_lost"] + lost,
                   span_change=max(out["span_change"], 0.0 if moved <= rel_tol * fa[0] else float(moved / spacing)))
    return out


def curves_converged(ch: dict, tol_curve: float | None = None, span_tol: float | None = None) -> bool:
    """The curves' stopping rule on ``curve_changes``' output (module docstring)."""
    tol_curve = TOL_CURVE if tol_curve is None else tol_curve
    span_tol = SPAN_TOL if span_tol is None else span_tol
    return (ch["curves_added"] == ch["curves_lost"] == 0 and ch["compared"] > 0
            and ch["curve_shift_sigma"] <= tol_curve and ch["span_change"] <= span_tol)


def _not_physical(specimen: Specimen) -> str:
    """'' when every ply's 3D stiffness is positive definite, else what is wrong."""
    try:
        for ply, C in zip(specimen.laminate.plies, ply_stiffness(specimen.laminate, 0.0)):
            if not np.all(np.isfinite(C)) or np.linalg.eigvalsh(0.5 * (C + C.T)).min() <= 0:
                return f"ply '{ply.material.name}': stiffness not positive definite"
    except (ValueError, PhysicsError) as e:
        return str(e)
    return ""


def _with_constants(specimen: Specimen, params: dict, material: str | None) -> Specimen:
    return replace(specimen, laminate=specimen.laminate.with_params(params, material))


def _file_constants(specimen: Specimen, material: str | None) -> dict:
    mats = specimen.laminate.materials
    m = mats.get(material) if material else (next(iter(mats.values())) if len(mats) == 1 else None)
    return m.params() if m is not None else {}


def iterate_store(store: RunStore, an: Analysis, settings: AnalysisSettings = AnalysisSettings(), *,
                  names: Sequence[str] | None = None, max_iter: int = MAX_ITER, tol_std: float | None = None,
                  tol_curve: float | None = None, progress: Callable[[str], Any] | None = None) -> Analysis:
    """The loop of the module docstring on the analysis ``an`` of the open run ``store``;
    returns the analysis with the last picks and ``analysis.iterations`` in its features.
    ``tol_std`` / ``tol_curve``: the stopping tolerances (default ``TOL_STD``, ``TOL_CURVE``;
    a negative one disables that rule)."""
    tol_std = TOL_STD if tol_std is None else tol_std
    tol_curve = TOL_CURVE if tol_curve is None else tol_curve
    doc = an.features
    if not doc.get("waves"):
        doc.setdefault("analysis", {})["iterations"] = []
        an.notes.append("pick <-> identify: no wave curves to iterate on")
        return an
    specimen = specimen_from_dict(tomllib.loads(store.specimen_toml()), f"{store.path}#config/specimen_toml")
    rig = rig_from_text(store.rig_toml(), f"{store.path}#config/rig_toml")
    records = store.shots("wave")
    rounds: list[dict] = []
    cur = an
    converged = ""
    used: dict | None = None         # the constants the current picks were made with
    prev_determined: set[str] = set()
    for k in range(1, max_iter + 1):
        problem = problem_from_features(cur.features, src=str(store.path))
        est = identify(problem, names)
        fit = est.fit or {}
        if used is None:
            used = _file_constants(specimen, problem.material)
        # only constants the data determine (relative std below MAX_REL_STD) move the nominal:
        # an undetermined one would move the predictions at random
        rel = est.rel_std
        std = dict(zip(est.names, (float(x) for x in est.std)))
        params = {n: float(v) for n, v in est.params.items() if math.isfinite(v) and rel[n] < MAX_REL_STD}
        entry: dict[str, Any] = {"iteration": k, "constants": params,
                                 "std": {n: std[n] for n in params},
                                 "identified": bool(fit.get("identified", False))}
        if fit.get("verdict") == "insufficient_data" or not params:
            entry["stopped"] = ("insufficient data" if fit.get("verdict") == "insufficient_data" else
                                "no constant determined by the data") + ": the picks stay those of the previous round"
            rounds.append(entry)
            break
        moved = [abs(v - used[n]) / std[n] for n, v in params.items() if n in used and std[n] > 0]
        entry["constants_shift_std"] = float(max(moved)) if moved else math.inf
        if entry["constants_shift_std"] <= tol_std:
            # the picks reproduce the constants they were made with: a fixed point, no re-pick
            rounds.append(entry)
            converged = (f"the identified constants moved by at most {entry['constants_shift_std']:.2g} of their "
                         f"std from those the picks were made with")
            break
        # constants determined in an earlier round but not in this one keep their last value
        # (back to the file's value, 40 % off, they moved the band: seed 0's round 4, G13)
        carried = {n: v for n, v in used.items() if n in prev_determined and n not in params}
        spec_k = _with_constants(specimen, {**carried, **params}, problem.material)
        bad = _not_physical(spec_k)
        if bad and carried:
            # the carried constants with this round's may make no physical ply (seed 2: G23 2.27 GPa
            # with the file's E2 9 GPa is nu23 0.99, physical only with the file's E1): this
            # round's constants alone, as before session 29
            spec_k = _with_constants(specimen, params, problem.material)
            bad = _not_physical(spec_k)
            entry["carried_dropped"] = sorted(carried)
        if bad:
            entry["stopped"] = f"the identified constants give a non-physical ply ({bad}): the picks stay those " \
                               "of the previous round"
            rounds.append(entry)
            break
        notes: list[str] = []
        wfeat, curves, arrivals, _extra, winfo = wave_features(records, rig, spec_k, settings, notes)
        old = cur.features.get("waves", [])
        ch = pick_changes(old, wfeat)
        cc = curve_changes(old, wfeat)
        entry.update(ch, **cc, n_points={f"{w['mode']}_{w['direction_deg']:g}": len(w["frequency_hz"]) for w in wfeat})
        rounds.append(entry)
        if progress:
            progress(f"pick <-> identify round {k}: constants moved {entry['constants_shift_std']:.2g} std; curves "
                     f"moved {cc['curve_shift_sigma']:.2g} sigma, span ends {cc['span_change']:.2g} spacing")
        if not wfeat:
            entry["stopped"] = "the re-analysis with the identified constants found no curve: previous picks kept"
            break
        feats = dict(cur.features)
        feats["waves"] = wfeat
        feats["analysis"] = {**cur.features.get("analysis", {}), "dropped": winfo.get("dropped", {})}
        cur = Analysis(feats, cur.spectrum, cur.peaks, curves, arrivals,
                       an.notes + [f"after identification (round {k}): {n}" for n in notes], cur.wave_band_hz,
                       winfo.get("dropped", {}), cur.no_velocity)
        used = _file_constants(spec_k, problem.material)       # what the new picks were made with
        prev_determined = set(params) | (set() if "carried_dropped" in entry else prev_determined)
        if tol_curve >= 0 and curves_converged(cc, tol_curve):
            converged = (f"the curves moved by at most {cc['curve_shift_sigma']:.2g} sigma and their spans by "
                         f"{cc['span_change']:.2g} point spacing")
            break
    line = (f"pick <-> identify: converged after {len(rounds)} round(s): {converged}" if converged else
            f"pick <-> identify: {len(rounds)} round(s), " +
            (rounds[-1].get("stopped") if rounds and rounds[-1].get("stopped") else
             f"still changing after {max_iter} rounds (the last picks are kept)"))
    cur.notes.append(line)
    ana = cur.features.setdefault("analysis", {})
    ana["iterations"] = rounds
    ana["notes"] = list(cur.notes)
    return cur
