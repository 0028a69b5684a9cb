"""Gap diagnosis workflow: features JSON (CONTRACT section 2) + nominal rig -> diagnosis.

``gap_features(doc, base_dir)`` turns the parsed features
(``labid.inputs.features.parse_features``) into the ``engine.features.Features`` the
diagnosis uses (every mode, as ``labid identify``; measured velocities only;
UserError naming the key on bad input). ``start_estimate`` is the ONE call into
the identification: the estimate ``labid identify`` reports with the same
options (parameters, start, prior), handed to ``engine.gap.diagnose`` as an
``engine.gap.StartEstimate``. ``run_diagnosis(doc, base_dir)`` runs both and
returns the JSON document (its figure: ``labid.report.plots.plot_gap``).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from engine.features import Features, ModalData, WaveData
from engine.forward import EffectError
from engine.gap import GapError, GapOptions, StartEstimate, diagnose
from engine.laminate import PhysicsError

from .identification import estimation
from ..base import progress
from ..base.errors import UserError
from ..inputs.features import DEFAULT_MODAL_SIGMA_REL, DEFAULT_WAVE_SIGMA_REL, parse_features

__all__ = ["gap_features", "gap_features_and_notes", "run_diagnosis", "start_estimate", "MAX_MODES"]

#: modal frequencies used at most (None: every mode, as labid identify; the per-mode
#: discretisation error enters the whitening instead of a cut)
MAX_MODES = None


def gap_features(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                 max_modes: int = MAX_MODES) -> Features:
    """The diagnosis' Features of a features document (see ``gap_features_and_notes``)."""
    return gap_features_and_notes(doc, base_dir, src, max_modes)[0]


def _lowest_modes(md: ModalData, max_modes: int, notes: list[str]) -> ModalData:
    f = md.frequency_hz
    order = np.argsort(f)
    if max_modes is None or len(f) <= max_modes:
        return md
    if len(f) > max_modes:
        notes.append(f"modal: {len(f)} frequencies; the lowest {max_modes} are used (the default "
                     "plate mesh is converged for the lowest modes only)")
    keep = np.sort(order[:max_modes])
    return ModalData(f[keep], md.sigma_hz[keep], md.points, None if md.shapes is None else md.shapes[keep])


def _measured(w: WaveData) -> WaveData | None:
    """The measured points of a wave set (a sigma given as null: the default one)."""
    cg = w.group_velocity_m_s
    sg = np.where(np.isfinite(w.sigma_m_s), w.sigma_m_s, DEFAULT_WAVE_SIGMA_REL * cg)
    ok = np.isfinite(cg) & np.isfinite(sg)
    if ok.sum() == 0:
        return None
    return WaveData(w.mode, w.direction_deg, w.frequency_hz[ok], cg[ok], sg[ok])


def gap_features_and_notes(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                           max_modes: int = MAX_MODES) -> tuple[Features, list[str]]:
    """(Features, notes) from a features document (specimen path relative to
    ``base_dir``, a built-in name or inline). The lowest ``max_modes`` modes are
    kept; velocities that are null/NaN are dropped; absent sigmas default as in
    ``labid identify``."""
    parsed = parse_features(doc, base_dir, src)
    feats, specimen = parsed.features, parsed.specimen
    notes = list(parsed.notes)
    modal = None
    if feats.modal is not None:
        md = feats.modal
        sig = np.where(np.isfinite(md.sigma_hz), md.sigma_hz, DEFAULT_MODAL_SIGMA_REL * md.frequency_hz)
        modal = _lowest_modes(replace(md, sigma_hz=sig), max_modes, notes)
    waves = []
    for i, w in enumerate(feats.waves):
        m = _measured(w)
        if m is None:
            notes.append(f"waves[{i}]: no measured velocity, set ignored")
            continue
        waves.append(m)
    layout = feats.rig
    if modal is None and not waves:
        raise UserError("no modal frequencies and no wave velocities: nothing to diagnose", file=src,
                        key="modal")
    if waves and not layout.wave_path_m:
        raise UserError("missing; expected the wave path in m (needed with waves)", file=src,
                        key="rig.wave_path_m")
    for k, (x, y) in [("rig.accelerometers", p) for p in layout.accelerometers] + \
                     [("rig.supports", p) for p in layout.supports]:
        if not (-1e-9 <= x <= specimen.length + 1e-9 and -1e-9 <= y <= specimen.width + 1e-9):
            raise UserError(f"point ({x}, {y}) lies outside the {specimen.length} x {specimen.width} m plate",
                            file=src, key=k)
    return replace(feats, modal=modal, waves=tuple(waves)), notes


#: relative amplitude at the response points below which a mode is 'barely seen'
#: (engine.forward.pairing's V_SEEN: the penalty for skipping it falls below a full miss)
BARELY_SEEN = 0.25


def pairing_findings(ident: Mapping) -> list[str]:
    """``where`` entries from identify's pairing (JSON ``pairing`` / ``unpaired_modes``):
    a predicted in-band mode without a peak (and whether the response point barely sees
    it), a peak that matches no mode. Mode and peak numbers 1-based, as in the text."""
    out = []
    for u in ident.get("unpaired_modes") or []:
        vis = u.get("visibility")
        seen = (f", which the response point barely sees (relative amplitude {vis:.2f})"
                if vis is not None and vis < BARELY_SEEN else "")
        out.append(f"predicted mode {int(u['mode_index']) + 1} near {float(u['predicted_hz']):.1f} Hz "
                   f"has no measured peak{seen} (identify's pairing)")
    for r in ident.get("pairing") or []:
        if r.get("mode_index") is None and r.get("measured_hz") is not None:
            out.append(f"peak {int(r['peak']) + 1} ({float(r['measured_hz']):.1f} Hz) matches no mode: "
                       "suspension, harmonic or electrical? (identify's pairing)")
    return out


def start_estimate(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                   names: Sequence[str] | None = None, start: Mapping[str, float] | None = None,
                   prior: float | None = None, result: Mapping | None = None) -> StartEstimate:
    """The estimate ``labid identify FEATURES --params NAMES --start START --prior PRIOR``
    reports (``labid.workflows.identification.estimation.run``, method lm: same parameter selection, start,
    prior, pairing, Birge and consistency checks), as the diagnosis' start.

    ``result``: that estimate's JSON dict when the caller has it already (the demo
    identifies the same features with the same options just before): used as it is,
    not recomputed. This is the single seam between the diagnosis and the
    identification: re-point it when the identification's entry point changes.
    """
    problem = estimation.problem_from_features(doc, base_dir=base_dir, src=src)
    md = problem.features.modal if problem.features is not None else None
    if result is None:
        result = estimation.run(problem, names, start, method="lm", prior=prior).to_dict()
    names = tuple(result["parameters"])
    st = estimation.start_values(problem, names, start)
    pairing = "mac" if md is not None and md.shapes is not None else "order"
    # identify's own peak -> mode assignment, when it reports one (issue 12: JSON ``pairing``)
    report = result.get("pairing")
    mode_index = None
    # (whatever the shapes: identify pairs by MAC only with >= 6 shape points, else by likelihood)
    if isinstance(report, list) and report and all(
            isinstance(r, Mapping) and "mode_index" in r for r in report):
        mode_index = tuple(None if r["mode_index"] is None else int(r["mode_index"]) for r in report)
        pairing = "identify"
    par = result["parameters"]
    return StartEstimate(names=names, params={n: float(par[n]["value"]) for n in names},
                         findings=tuple(pairing_findings(result)),
                         std={n: float(par[n]["std"]) for n in names},
                         converged=bool(result["converged"]), message=str(result.get("message", "")),
                         iterations=int(result.get("iterations") or 0),
                         prior_rel_std=prior, prior_mean=st,
                         pairing=pairing, mode_index=mode_index,
                         source="labid identify (labid.workflows.identification.estimation.run, method lm)",
                         warnings=tuple(result.get("warnings") or ()),
                         consistent=bool((result.get("fit") or {}).get("consistent", True)))


def run_diagnosis(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                  options: GapOptions | None = None, names: Sequence[str] | None = None,
                  start: Mapping[str, float] | None = None, prior: float | None = None,
                  estimate: Mapping | None = None) -> dict:
    """Diagnosis document (``GapResult.to_dict()``, CONTRACT section 3 keys first, plus
    ``notes``) of parsed features, from identify's estimate (:func:`start_estimate`;
    ``estimate``: identify's result dict for these features and options, if at hand).
    Progress (the estimate, candidates screened and refitted) on stderr via ``labid.base.progress``."""
    problem, notes = gap_features_and_notes(doc, base_dir, src)
    if estimate is None:
        progress.note("diagnosis: identifying the constants (as labid identify)")
    st = start_estimate(doc, base_dir, src, names, start, prior, result=estimate)
    bar = progress.bar(None, "candidate effects", unit="step")

    def step(stage: str, done: int, total: int) -> None:
        if getattr(bar, "total", total) != total:
            bar.total = total
        bar.update(1)
        bar.set_postfix_str(stage)
    try:
        with bar:
            res = diagnose(problem, options, start=st, progress=step).to_dict()
        res["notes"] = notes + list(st.warnings)
        # pairing as a cause (issue 13): what identify's own pairing set aside leads `where`,
        # when the diagnosis' result rests on that pairing
        if res.get("identification", {}).get("pairing_used") == "identify":
            res["where"] = [w for w in st.findings if w not in res["where"]] + list(res["where"])
        return res
    except PhysicsError as e:
        raise UserError(f"unphysical nominal constants: {e}", file=src, key="specimen") from None
    except (GapError, EffectError) as e:
        raise UserError(f"cannot diagnose: {e}", file=src) from None
