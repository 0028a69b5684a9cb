"""Gap diagnosis workflow: features JSON (CONTRACT section 2) + nominal rig -> diagnosis.

``problem_from_features(doc, base_dir)`` turns the parsed features into an
``engine.features.Features`` (UserError naming the key on bad input);
``run_diagnosis(doc, base_dir)`` runs ``engine.gap.diagnose``; ``plot_gap``
draws where the gap lies (whitened residual of every feature before/after,
and the chi^2 share of each group).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import numpy as np

from .errors import UserError

__all__ = ["problem_from_features", "run_diagnosis", "plot_gap", "load_features"]


def _num(doc: Mapping, key: str, where: str, src: str, default=None) -> float | None:
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



def load_features(path: str | Path) -> tuple[dict, Path]:
    """Read and validate a features JSON file (``labid.features``); (doc, its directory)."""
    from .features import read_features
    return read_features(path), Path(path).parent


def _sigmas(doc: Mapping, key: str, values: np.ndarray, default_rel: float, notes: list[str],
            where: str) -> np.ndarray:
    s = doc.get(key)
    if s is None:
        notes.append(f"{where}{key} absent: assuming {default_rel:.1%} of the values")
        return default_rel * values
    s = np.broadcast_to(np.asarray(s, float), values.shape).copy()
    bad = ~np.isfinite(s)
    s[bad] = default_rel * values[bad]
    return s


#: modal frequencies used at most (lowest first)
MAX_MODES = 12


def problem_from_features(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                          max_modes: int = MAX_MODES):
    """Features from a features document (see ``problem_and_notes``)."""
    return problem_and_notes(doc, base_dir, src, max_modes)[0]


def problem_and_notes(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                      max_modes: int = MAX_MODES):
    """(Features, notes) from a features document (validated by ``labid.features``; specimen
    path relative to ``base_dir``, a built-in name or inline). Velocities that are
    null/NaN are dropped; absent sigmas default as in ``labid identify``."""
    from engine.features import Features, ModalData, RigLayout, WaveData

    from .features import specimen_of, validate_features
    from .identification import DEFAULT_MODAL_SIGMA_REL, DEFAULT_WAVE_SIGMA_REL

    doc = validate_features(doc, src)
    specimen = specimen_of(doc, base_dir, src)
    notes: list[str] = []
    modal = None
    if doc.get("modal") is not None:
        m = doc["modal"]
        f = np.asarray(m["frequencies_hz"], float)
        sig = _sigmas(m, "sigma_hz", f, DEFAULT_MODAL_SIGMA_REL, notes, "modal.")
        pts = vals = None
        if m.get("mode_shapes") is not None:
            pts = np.asarray(m["mode_shapes"]["points"], float)
            vals = np.asarray(m["mode_shapes"]["values"], float)
        order = np.argsort(f)
        if len(f) > max_modes:
            notes.append(f"modal: {len(f)} frequencies; the lowest {max_modes} are used (the default "
                         "plate mesh is converged for the lowest modes only)")
        keep = np.sort(order[:max_modes])
        modal = ModalData(f[keep], sig[keep], pts, None if vals is None else vals[keep])
    waves = []
    for i, w in enumerate(doc.get("waves") or []):
        f = np.asarray(w["frequency_hz"], float)
        cg = np.asarray(w["group_velocity_m_s"], float)
        sg = _sigmas(w, "sigma_m_s", cg, DEFAULT_WAVE_SIGMA_REL, notes, f"waves[{i}].")
        ok = np.isfinite(cg) & np.isfinite(sg)
        if ok.sum() == 0:
            notes.append(f"waves[{i}]: no measured velocity, set ignored")
            continue
        waves.append(WaveData(w["mode"], float(w["direction_deg"]), f[ok], cg[ok], sg[ok]))
    rig = doc.get("rig") or {}
    wl_ = rig.get("wavelet") or {}
    layout = RigLayout(
        tuple((a["x"], a["y"]) for a in rig.get("accelerometers") or []),
        tuple((a["x"], a["y"]) for a in rig.get("supports") or []),
        rig.get("wave_path_m"),
        float(rig.get("sensor_length_m") or 0.0),
        rig.get("temperature_c"),
        _num(wl_, "bandwidth", "rig.wavelet.", src, 2.0),
        _num(wl_, "center", "rig.wavelet.", src, 5.0),
        tuple(float(a.get("mass_kg") or 0.0) for a in rig.get("accelerometers") or []))
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
    return (Features(specimen.laminate, specimen.length, specimen.width, layout, modal, tuple(waves)),
            notes)


def run_diagnosis(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                  options=None) -> dict:
    """Diagnosis dict (CONTRACT section 3 keys first) of parsed features."""
    from engine.forward import EffectError
    from engine.gap import GapError, diagnose
    from engine.laminate import PhysicsError

    problem, notes = problem_and_notes(doc, base_dir, src)
    try:
        res = diagnose(problem, options).to_dict()
        res["notes"] = notes
        return res
    except PhysicsError as e:
        raise UserError(f"unphysical nominal constants: {e}", file=src, key="specimen") from None
    except (GapError, EffectError) as e:
        raise UserError(f"cannot diagnose: {e}", file=src) from None


def plot_gap(result: Mapping, path: str | Path) -> None:
    """Figure of where the gap lies: whitened residuals per feature and chi^2 share per group."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ft = result["features"]
    r0 = np.asarray(ft["residual_before"])
    r1 = np.asarray(ft["residual_after"])
    sets = ft["set"]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(11, 7.5), gridspec_kw={"height_ratios": [3, 2]})
    x = np.arange(len(r0))
    colors = {s: f"C{i}" for i, s in enumerate(dict.fromkeys(sets))}
    a1.bar(x - 0.2, r0, 0.4, color=[colors[s] for s in sets], label="before (coloured by set)")
    a1.bar(x + 0.2, r1, 0.4, color="0.6", label=f"after ({result['verdict']})")
    a1.axhspan(-2, 2, color="0.9", zorder=-1)
    a1.set_ylabel("(model - measured) / sigma")
    a1.set_xticks(x)
    a1.set_xticklabels(ft["labels"], rotation=90, fontsize=6)
    for s, c in colors.items():
        a1.plot([], [], "s", color=c, label=s)
    a1.legend(fontsize=7, ncol=4)
    g = result["gap"]
    a1.set_title(f"gap {g['before']:.2f} -> {g['after']:.2f} (held out {g['held_out_before']:.2f} -> "
                 f"{g['held_out_after']:.2f}); verdict: {result['verdict']}", fontsize=9)
    groups = [d for d in result["groups"] if d["n"] > 0][:20]
    a2.barh([d["group"] for d in groups][::-1], [d["chi2"] / max(d["n"], 1) for d in groups][::-1],
            color=["C3" if d["significant"] else "C0" for d in groups][::-1])
    a2.axvline(1.0, color="k", lw=0.8)
    a2.set_xscale("log")
    a2.set_xlabel("chi^2 per feature (1 = noise); red: significant")
    a2.tick_params(axis="y", labelsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
