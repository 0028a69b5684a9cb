"""Figures of the identification and diagnosis workflows (matplotlib, written to files).

* :func:`plot_multi_start` -- identified parameters against the start number
  (paper Fig. 3).
* :func:`plot_gap` -- where the sim-to-real gap lies.

matplotlib is imported inside each function: pyplot costs ~0.6 s CPU on top of numpy
(measured 0.74 s user against 0.15 s for numpy alone) and only these figures need it.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..base import atomic
from ..base.errors import UserError
from ..base.summary import display_unit

__all__ = ["plot_multi_start", "plot_gap"]


def plot_multi_start(results: Sequence[Mapping], names: Sequence[str], path: str | Path, *,
                     truth: Mapping[str, float] | None = None, title: str = "") -> Path:
    """Scatter of each identified parameter (and its start) against the start
    number, one panel per parameter (paper Fig. 3). PNG/PDF by extension."""
    import matplotlib  # noqa: PLC0415 - heavy, needed only for this figure
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    k = len(names)
    cols = min(3, k)
    rows = math.ceil(k / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.0 * rows), squeeze=False)
    idx = np.arange(1, len(results) + 1)
    for ax, n in zip(axes.ravel(), names):
        unit, scale = display_unit(n)
        st = np.array([r["start"].get(n, np.nan) for r in results]) * scale
        val = np.array([r.get("values", {}).get(n, np.nan) for r in results]) * scale
        ok = np.array([bool(r.get("converged")) for r in results])
        ax.plot(idx, st, "x", color="0.6", ms=4, label="start")
        ax.plot(idx[ok], val[ok], "o", color="C0", ms=4, label="identified")
        if (~ok).any():
            ax.plot(idx[~ok], val[~ok], "o", mfc="none", color="C3", ms=4, label="not converged")
        if truth and n in truth:
            ax.axhline(truth[n] * scale, color="k", lw=0.8, ls="--", label="true")
        ax.set_xlabel("start number")
        ax.set_ylabel(f"{n} [{unit}]" if unit else n)
    for ax in axes.ravel()[k:]:
        ax.set_visible(False)
    axes.ravel()[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    save_figure(fig, path)
    plt.close(fig)


def plot_gap(result: Mapping, path: str | Path) -> None:
    """Figure of where the gap lies: whitened residuals per feature and chi^2 share per group."""
    import matplotlib  # noqa: PLC0415 - heavy, needed only for this figure
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

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
    save_figure(fig, path)
    plt.close(fig)


def save_figure(fig, path: str | Path) -> None:
    """``fig.savefig`` atomically (``labid.base.atomic``); the format from the suffix (PNG by default)."""
    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    with atomic.replacing(path, key="--plot") as tmp:
        try:
            fig.savefig(tmp, dpi=110, format=fmt)
        except ValueError as e:                      # an unknown format
            raise UserError(f"cannot write a figure ({e})", file=str(path), key="--plot") from None
