"""Pick <-> identify: the wave picks redone with the identified constants until they stop changing.

What a careful analyst does by hand (issue 24). The first wave analysis predicts the packets
(windows, echoes, foreign packets' levels) from the specimen file's constants, rescaled by
what the records show (``engine.wavefeatures.survey``); when those constants are far off, the
predicted shapes and the echoes of other directions are still off. So:

1. identify the constants from the features (modal and waves, ``labid.workflows.identification``);
2. analyse the wave shots again with the identified constants as the nominal model;
3. compare the new picks with the previous ones: points added or lost, and the largest
   velocity change in units of the point's sigma;
4. stop when no point is added or lost and none moves by more than ``tol_sigma`` of its
   sigma, or after ``max_iter`` rounds, or when the identification cannot determine the
   constants (insufficient data, or no constant with a relative std below ``MAX_REL_STD``):
   the picks then stay the last ones. Only determined constants replace the nominal ones.

Each round is recorded in the features' ``analysis.iterations`` (CONTRACT section 2, an
optional key): the constants used, the points per curve, what changed. The features keep
the specimen file's constants as their specimen (identify starts from them again).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from typing import Any, Callable, Sequence

from ..inputs.rig import rig_from_text
from ..inputs.specimen import Specimen, specimen_from_dict
from ..store import RunStore
from .analysis import Analysis, AnalysisSettings, wave_features
from .identification.estimation import problem_from_features, run as identify

__all__ = ["iterate_store", "pick_changes", "MAX_ITER", "TOL_SIGMA", "MAX_REL_STD"]

MAX_ITER = 4
TOL_SIGMA = 0.3
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


def _with_constants(specimen: Specimen, params: dict, material: str | None) -> Specimen:
    return replace(specimen, laminate=specimen.laminate.with_params(params, material))


def iterate_store(store: RunStore, an: Analysis, settings: AnalysisSettings = AnalysisSettings(), *,
                  names: Sequence[str] | None = None, max_iter: int = MAX_ITER, tol_sigma: float = TOL_SIGMA,
                  progress: Callable[[str], Any] | None = None) -> Analysis:
    """The loop of the module docstring on the analysis ``an`` of the open run ``store``;
    returns the analysis with the last picks and ``analysis.iterations`` in its features."""
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
    converged = False
    for k in range(1, max_iter + 1):
        problem = problem_from_features(cur.features, src=str(store.path))
        est = identify(problem, names)
        fit = est.fit or {}
        # only constants the data determine (relative std below MAX_REL_STD) move the nominal:
        # an undetermined one would move the predictions at random
        rel = est.rel_std
        params = {n: float(v) for n, v in est.params.items() if math.isfinite(v) and rel[n] < MAX_REL_STD}
        entry: dict[str, Any] = {"iteration": k, "constants": params,
                                 "identified": bool(fit.get("identified", False))}
        if fit.get("verdict") == "insufficient_data" or not params:
            entry["stopped"] = ("insufficient data" if fit.get("verdict") == "insufficient_data" else
                                "no constant determined by the data") + ": the picks stay those of the previous round"
            rounds.append(entry)
            break
        spec_k = _with_constants(specimen, params, problem.material)
        notes: list[str] = []
        wfeat, curves, arrivals, _extra, winfo = wave_features(records, rig, spec_k, settings, notes)
        ch = pick_changes(cur.features.get("waves", []), wfeat)
        entry.update(ch, n_points={f"{w['mode']}_{w['direction_deg']:g}": len(w["frequency_hz"]) for w in wfeat})
        rounds.append(entry)
        if progress:
            progress(f"pick <-> identify round {k}: {ch['added']} points added, {ch['lost']} lost, "
                     f"largest change {ch['max_shift_sigma']:.2g} sigma")
        if not wfeat:
            entry["stopped"] = "the re-analysis with the identified constants found no curve: previous picks kept"
            break
        feats = dict(cur.features)
        feats["waves"] = wfeat
        feats["analysis"] = {**cur.features.get("analysis", {}), "dropped": winfo.get("dropped", {})}
        cur = Analysis(feats, cur.spectrum, cur.peaks, curves, arrivals,
                       an.notes + [f"after identification (round {k}): {n}" for n in notes], cur.wave_band_hz,
                       winfo.get("dropped", {}), cur.no_velocity)
        if ch["added"] == 0 and ch["lost"] == 0 and ch["max_shift_sigma"] <= tol_sigma:
            converged = True
            break
    line = (f"pick <-> identify: the picks stopped changing after {len(rounds)} round(s)" if converged else
            f"pick <-> identify: {len(rounds)} round(s), " +
            (rounds[-1].get("stopped") if rounds and rounds[-1].get("stopped") else
             f"still changing after {max_iter} rounds (the last picks are kept)"))
    cur.notes.append(line)
    ana = cur.features.setdefault("analysis", {})
    ana["iterations"] = rounds
    ana["notes"] = list(cur.notes)
    return cur
