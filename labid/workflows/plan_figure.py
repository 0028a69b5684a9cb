"""The figure of a test plan (``labid plan --plot``, the setup view's Plan box).

Left: the plate (mm) with the candidate grid, the supports, the nodal lines of the key
modes (w = 0 of the nominal plate's modes that carry most information on the fitted
constants), the recommended accelerometers and tap, the user's rig (hollow), and the wave
source and sensors when waves are recommended. Right: the predicted relative std of every
fitted constant, recommended plan against the user's rig, with the target.

matplotlib is imported inside :func:`plan_figure` (pyplot costs ~0.6 s CPU; the command
draws only with ``--plot``).
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..base import atomic

__all__ = ["plan_figure", "plan_png", "save_plan_figure", "NODAL_GRID"]

#: points per direction of the grid the nodal lines are drawn from
NODAL_GRID = 81
COLOURS = ("tab:purple", "tab:orange", "tab:cyan", "tab:olive", "tab:pink")


def plan_figure(result):
    """A matplotlib Figure of ``result`` (a ``labid.workflows.plan.PlanResult``)."""
    import matplotlib  # noqa: PLC0415 - heavy, needed only for this figure
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    doc, spec = result.doc, result.specimen
    L, W = spec.length * 1e3, spec.width * 1e3
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.0, 5.0), gridspec_kw={"width_ratios": [1.15, 1.0]})
    ax.add_patch(plt.Rectangle((0, 0), L, W, fill=False, lw=1.5, color="k"))
    if result.model is not None and result.modes is not None and result.key_modes:
        xs, ys = np.linspace(0, spec.length, NODAL_GRID), np.linspace(0, spec.width, NODAL_GRID)
        X, Y = np.meshgrid(xs, ys)
        w = result.model.shapes_at(result.modes, np.column_stack([X.ravel(), Y.ravel()]))
        for c, (k, km) in zip(COLOURS, zip(result.key_modes, doc["key_modes"])):
            ax.contour(X * 1e3, Y * 1e3, w[k].reshape(X.shape), levels=[0.0], colors=[c], linewidths=1.2)
            ax.plot([], [], color=c, lw=1.2, label=f"nodal lines, mode {k + 1} {km['family']} "
                                                   f"{km['frequency_hz']:.0f} Hz")
    for i, s in enumerate(doc["rigs"][:1]):
        a = np.array([[p["x"], p["y"]] for p in s["accelerometers"]]) * 1e3
        ax.plot(a[:, 0], a[:, 1], "^", mfc="none", mec="0.4", ms=9, label=f"{s['label']}: accelerometers")
        ax.plot(s["hammer"]["x"] * 1e3, s["hammer"]["y"] * 1e3, "*", mfc="none", mec="0.4", ms=13,
                label=f"{s['label']}: tap")
    rec = doc["recommended"]
    a = np.array([[p["x"], p["y"]] for p in rec["accelerometers"]]) * 1e3
    ax.plot(a[:, 0], a[:, 1], "^", color="tab:blue", ms=10, label="recommended accelerometers")
    for j, (x, y) in enumerate(a, 1):
        ax.annotate(f"acc{j}", (x, y), textcoords="offset points", xytext=(5, 5), fontsize=8, color="tab:blue")
    ax.plot(rec["hammer"]["x"] * 1e3, rec["hammer"]["y"] * 1e3, "*", color="tab:red", ms=15,
            label="recommended tap")
    sup = result.template.supports if result.template is not None else ()
    if sup:
        sp = np.array(sup) * 1e3
        ax.plot(sp[:, 0], sp[:, 1], "x", color="k", ms=8, label="supports")
    wv = doc["waves"]
    if wv.get("recommended"):
        sx, sy = wv["source"]["x"] * 1e3, wv["source"]["y"] * 1e3
        for leg in wv["legs"]:
            fx, fy = np.array(leg["far_xy"]) * 1e3
            nx, ny = np.array(leg["near_xy"]) * 1e3
            ax.plot([sx, fx], [sy, fy], "-", color="tab:green", lw=0.8)
            ax.plot([nx, fx], [ny, fy], "s", color="tab:green", ms=6)
        ax.plot(sx, sy, "D", color="tab:green", ms=8, label="wave source and sensors")
    ax.set_xlim(-0.04 * L, 1.04 * L)
    ax.set_ylim(-0.04 * W, 1.04 * W)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"{doc['specimen']}: recommended layout")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, frameon=False)
    # predicted stds
    names = list(rec["constants"])
    x = np.arange(len(names))
    r = [100 * rec["constants"][n]["std_rel"] for n in names]
    u = [100 * doc["rigs"][0]["constants"].get(n, {}).get("std_rel", np.nan) for n in names]
    bx.bar(x - 0.2, u, 0.4, color="0.7", label=doc["rigs"][0]["label"])
    bx.bar(x + 0.2, r, 0.4, color="tab:blue", label="recommended")
    bx.axhline(100 * doc["target_u"], color="tab:red", ls="--", lw=1, label=f"target {100 * doc['target_u']:g} %")
    bx.set_xticks(x, [n + ("" if rec["constants"][n]["wanted"] else "\n(not wanted)") for n in names])
    bx.set_yscale("log")
    bx.set_ylabel("predicted relative std (%)")
    bx.set_title("predicted std (rms over the prior)")
    bx.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plan_png(result, dpi: int = 100) -> bytes:
    """The figure as PNG bytes."""
    import matplotlib.pyplot as plt  # noqa: PLC0415 - imported by plan_figure already

    fig = plan_figure(result)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


def save_plan_figure(result, path: str | Path) -> None:
    """Write the figure as PNG (atomically; a full or read-only disk is a UserError naming the file)."""
    atomic.write_bytes(Path(path), plan_png(result), key="--plot")
