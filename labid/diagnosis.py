"""Gap diagnosis workflow: features JSON (CONTRACT section 2) + nominal rig -> diagnosis.

``problem_from_features(doc, base_dir)`` turns the parsed features into an
``engine.gap_forward.GapProblem`` (UserError naming the key on bad input);
``run_diagnosis(doc, base_dir)`` runs ``engine.gap.diagnose``; ``plot_gap``
draws where the gap lies (whitened residual of every feature before/after,
and the chi^2 share of each group).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .errors import UserError

__all__ = ["problem_from_features", "run_diagnosis", "plot_gap", "load_features"]


def load_features(path: str | Path) -> tuple[dict, Path]:
    """Parse a features JSON file; (doc, directory for relative specimen paths)."""
    import json
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
    except FileNotFoundError:
        raise UserError("file not found; expected a features JSON file (CONTRACT section 2)", file=str(p)) from None
    except (OSError, UnicodeDecodeError) as e:
        raise UserError(f"cannot read: {e}", file=str(p)) from None
    except json.JSONDecodeError as e:
        raise UserError(f"not valid JSON (line {e.lineno}): {e.msg}", file=str(p)) from None
    if not isinstance(doc, dict):
        raise UserError("expected a JSON object at the top level", file=str(p))
    return doc, p.parent


def _arr(doc: Mapping, key: str, where: str, src: str, n: int | None = None, positive=False) -> np.ndarray:
    if key not in doc:
        raise UserError("missing; expected a list of numbers", file=src, key=f"{where}{key}")
    try:
        a = np.asarray(doc[key], float)
    except (TypeError, ValueError):
        raise UserError(f"value {doc[key]!r:.60}: expected a list of numbers", file=src, key=f"{where}{key}") from None
    if a.ndim == 0 and n is not None:
        a = np.full(n, float(a))
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise UserError("expected a non-empty list of finite numbers", file=src, key=f"{where}{key}")
    if n is not None and a.size != n:
        raise UserError(f"{a.size} values: expected {n}", file=src, key=f"{where}{key}")
    if positive and np.any(a <= 0):
        raise UserError("expected positive values", file=src, key=f"{where}{key}")
    return a


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


def _points(items: Any, key: str, src: str) -> tuple[tuple[float, float], ...]:
    if items is None:
        return ()
    if not isinstance(items, list):
        raise UserError("expected a list of {x, y} tables", file=src, key=key)
    out = []
    for i, it in enumerate(items):
        if not isinstance(it, Mapping) or "x" not in it or "y" not in it:
            raise UserError(f"item {i}: expected a table with x and y in m", file=src, key=key)
        out.append((_num(it, "x", f"{key}[{i}].", src), _num(it, "y", f"{key}[{i}].", src)))
    return tuple(out)


def problem_from_features(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>"):
    """GapProblem from parsed features (specimen path relative to ``base_dir`` or inline)."""
    from engine.gap_forward import GapProblem, ModalData, RigLayout, WaveData

    from .specimen import load_specimen, specimen_from_dict

    spec = doc.get("specimen")
    if isinstance(spec, Mapping):
        specimen = specimen_from_dict(spec, f"{src}:specimen")
    elif isinstance(spec, str):
        p = Path(spec)
        if not p.is_absolute() and (Path(base_dir) / p).exists():
            p = Path(base_dir) / p
        specimen = load_specimen(p if p.exists() else spec)
    else:
        raise UserError("missing; expected a specimen file path or an inline specimen table",
                        file=src, key="specimen")
    modal = None
    if doc.get("modal") is not None:
        m = doc["modal"]
        if not isinstance(m, Mapping):
            raise UserError("expected a table", file=src, key="modal")
        f = _arr(m, "frequencies_hz", "modal.", src, positive=True)
        s = _arr(m, "sigma_hz", "modal.", src, len(f), positive=True)
        pts = vals = None
        ms = m.get("mode_shapes")
        if ms is not None:
            try:
                pts = np.asarray(ms["points"], float)
                vals = np.asarray(ms["values"], float)
            except (KeyError, TypeError, ValueError):
                raise UserError("expected {points: [[x, y], ...], values: [[...], ...]}",
                                file=src, key="modal.mode_shapes") from None
            if pts.ndim != 2 or pts.shape[1] != 2 or vals.shape != (len(f), len(pts)):
                raise UserError(f"values of shape {vals.shape}: expected ({len(f)}, {len(pts)}) "
                                "(one row per measured mode, one column per point)",
                                file=src, key="modal.mode_shapes")
        modal = ModalData(f, s, pts, vals)
    waves = []
    wl = doc.get("waves") or []
    if not isinstance(wl, list):
        raise UserError("expected a list of wave sets", file=src, key="waves")
    for i, w in enumerate(wl):
        where = f"waves[{i}]."
        if not isinstance(w, Mapping):
            raise UserError("expected a table", file=src, key=f"waves[{i}]")
        f = _arr(w, "frequency_hz", where, src, positive=True)
        cg = _arr(w, "group_velocity_m_s", where, src, len(f), positive=True)
        sg = _arr(w, "sigma_m_s", where, src, len(f), positive=True)
        mode = str(w.get("mode", "A0"))
        if mode not in ("A0", "S0", "SH0"):
            raise UserError(f"value {mode!r}: expected A0, S0 or SH0", file=src, key=f"{where}mode")
        waves.append(WaveData(mode, _num(w, "direction_deg", where, src, 0.0), f, cg, sg))
    rig = doc.get("rig") or {}
    if not isinstance(rig, Mapping):
        raise UserError("expected a table", file=src, key="rig")
    wl_ = rig.get("wavelet") or {}
    layout = RigLayout(
        _points(rig.get("accelerometers"), "rig.accelerometers", src),
        _points(rig.get("supports"), "rig.supports", src),
        _num(rig, "wave_path_m", "rig.", src),
        _num(rig, "sensor_length_m", "rig.", src, 0.0),
        _num(rig, "temperature_c", "rig.", src),
        _num(wl_, "bandwidth", "rig.wavelet.", src, 2.0),
        _num(wl_, "center", "rig.wavelet.", src, 5.0))
    if modal is None and not waves:
        raise UserError("no modal frequencies and no waves: nothing to diagnose", file=src, key="modal")
    if waves and not (layout.wave_path_m and layout.wave_path_m > 0):
        raise UserError("missing or non-positive; expected the wave path in m", file=src, key="rig.wave_path_m")
    for k, (x, y) in [("rig.accelerometers", p) for p in layout.accelerometers] + \
                     [("rig.supports", p) for p in layout.supports]:
        if not (-1e-9 <= x <= specimen.length + 1e-9 and -1e-9 <= y <= specimen.width + 1e-9):
            raise UserError(f"point ({x}, {y}) lies outside the {specimen.length} x {specimen.width} m plate",
                            file=src, key=k)
    return GapProblem(specimen.laminate, specimen.length, specimen.width, layout, modal, tuple(waves))


def run_diagnosis(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>",
                  options=None) -> dict:
    """Diagnosis dict (CONTRACT section 3 keys first) of parsed features."""
    from engine.gap import diagnose
    from engine.laminate import PhysicsError

    problem = problem_from_features(doc, base_dir, src)
    try:
        return diagnose(problem, options)
    except PhysicsError as e:
        raise UserError(f"unphysical nominal constants: {e}", file=src, key="specimen") from None


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
    a1.bar(x - 0.2, r0, 0.4, color=[colors[s] for s in sets], label="before (constants only)")
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
    a2.set_xlabel("chi^2 per feature (1 = noise); red: significant")
    a2.tick_params(axis="y", labelsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
