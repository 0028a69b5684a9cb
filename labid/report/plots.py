"""The figures' one matplotlib set-up and the figures written to files.

* :func:`pyplot` -- matplotlib's pyplot on the Agg backend, imported when the first figure is
  drawn: pyplot costs ~0.6 s CPU on top of numpy (measured 0.74 s user against 0.15 s for
  numpy alone), and the panel and most commands never draw one. Every figure of labid
  (these and the report's, ``labid.report.figures``) is drawn through it.
* :func:`plot_multi_start` -- identified parameters against the start number (paper Fig. 3).
* :func:`gap_figure` -- the one figure of a gap diagnosis: where the gap lies (whitened
  residuals per feature, chi^2 per group) and how far modelling each candidate effect
  closes it; :func:`plot_gap` writes it (``labid diagnose --plot``, the demo), the report
  embeds it.
* :func:`save_figure` (atomic, the format from the suffix), :func:`check_format` (a
  figure path's format, checked before any computing).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..base import atomic
from ..base.errors import UserError
from ..base.summary import display_unit

__all__ = ["pyplot", "plot_multi_start", "gap_figure", "plot_gap", "save_figure", "check_format"]


def pyplot():
    """matplotlib.pyplot on the Agg backend (the module docstring says why it is imported late)."""
    import matplotlib  # noqa: PLC0415 - heavy, needed only when a figure is drawn
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt  # noqa: PLC0415
    return plt


def check_format(path: str | Path, key: str = "--plot") -> None:
    """UserError naming ``key`` unless matplotlib writes the format of ``path``'s suffix
    (PNG when it has none)."""
    from matplotlib.backend_bases import FigureCanvasBase  # noqa: PLC0415 - only with a figure path

    fmt = Path(path).suffix[1:].lower() or "png"
    known = FigureCanvasBase.get_supported_filetypes()
    if fmt not in known:
        raise UserError(f"figure format {fmt!r} unknown; expected one of {sorted(known)}", file=str(path), key=key)


def plot_multi_start(results: Sequence[Mapping], names: Sequence[str], path: str | Path, *,
                     truth: Mapping[str, float] | None = None, title: str = "") -> Path:
    """Scatter of each identified parameter (and its start) against the start
    number, one panel per parameter (paper Fig. 3). PNG/PDF by extension."""
    plt = pyplot()
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
    return path


def gap_figure(result: Mapping):
    """The figure of a diagnosis ``result`` (``labid diagnose`` JSON): whitened residuals per
    feature before and after (coloured by set), chi^2 per feature of each group (red:
    significant), and the gap after modelling each candidate effect against the gap before;
    a panel whose data the result lacks is left out. None when it has none of them."""
    ft = result.get("features") or {}
    groups = [d for d in result.get("groups") or [] if isinstance(d, Mapping) and d.get("n", 0) > 0][:20]
    effects = [e for e in result.get("effects") or [] if isinstance(e, Mapping)]
    has_res = bool(ft.get("residual_before"))
    panels = [k for k, ok in (("residuals", has_res), ("groups", bool(groups)), ("effects", bool(effects))) if ok]
    if not panels:
        return None
    plt = pyplot()
    heights = {"residuals": 3.0, "groups": 2.0, "effects": 0.6 + 0.25 * len(effects)}
    fig, axes = plt.subplots(len(panels), 1, figsize=(11, 1.2 + 1.5 * sum(heights[k] for k in panels)),
                             gridspec_kw={"height_ratios": [heights[k] for k in panels]}, squeeze=False)
    ax = dict(zip(panels, axes[:, 0]))
    g = result.get("gap") or {}
    title = (f"gap {g.get('before', math.nan):.2f} -> {g.get('after', math.nan):.2f} (held out "
             f"{g.get('held_out_before', math.nan):.2f} -> {g.get('held_out_after', math.nan):.2f}); "
             f"verdict: {result.get('verdict')}")
    if "residuals" in ax:
        a1 = ax["residuals"]
        r0 = np.asarray(ft["residual_before"], float)
        r1 = np.asarray(ft.get("residual_after", np.full(r0.size, np.nan)), float)
        sets = list(ft.get("set") or ["features"] * r0.size)
        x = np.arange(len(r0))
        colors = {s: f"C{i}" for i, s in enumerate(dict.fromkeys(sets))}
        a1.bar(x - 0.2, r0, 0.4, color=[colors[s] for s in sets], label="before (coloured by set)")
        a1.bar(x + 0.2, r1, 0.4, color="0.6", label=f"after ({result.get('verdict')})")
        a1.axhspan(-2, 2, color="0.9", zorder=-1)
        a1.set_ylabel("(model - measured) / sigma")
        a1.set_xticks(x)
        a1.set_xticklabels(ft.get("labels") or [str(i + 1) for i in x], rotation=90, fontsize=6)
        for s, c in colors.items():
            a1.plot([], [], "s", color=c, label=s)
        a1.legend(fontsize=7, ncol=4)
    axes[0, 0].set_title(title, fontsize=9)
    if "groups" in ax:
        a2 = ax["groups"]
        a2.barh([str(d["group"]) for d in groups][::-1], [d["chi2"] / max(d["n"], 1) for d in groups][::-1],
                color=["C3" if d.get("significant") else "C0" for d in groups][::-1])
        a2.axvline(1.0, color="k", lw=0.8)
        a2.set_xscale("log")
        a2.set_xlabel("chi^2 per feature (1 = noise); red: significant")
        a2.tick_params(axis="y", labelsize=6)
    if "effects" in ax:
        a3 = ax["effects"]
        names = [str(e.get("name")) for e in effects]
        after = [float(e.get("gap_after", np.nan)) for e in effects]
        a3.barh(names[::-1], after[::-1], color="#9ecae1")
        before = g.get("before")
        if isinstance(before, (int, float)):
            a3.axvline(float(before), color="#d62728", ls="--")
        a3.set_xlabel(f"gap after modelling each effect ({g.get('unit') or 'rms of residual/σ'}); "
                      "dashed red: the gap before")      # no legend: it would hide a bar
    fig.tight_layout()
    return fig


def plot_gap(result: Mapping, path: str | Path) -> None:
    """Write :func:`gap_figure` of a diagnosis to ``path`` (PNG/PDF/SVG by the suffix)."""
    fig = gap_figure(result)
    if fig is None:
        raise UserError("the diagnosis holds no residuals, groups or effects to draw", file=str(path), key="--plot")
    save_figure(fig, path)
    pyplot().close(fig)


def save_figure(fig, path: str | Path) -> None:
    """``fig.savefig`` atomically (``labid.base.atomic``); the format from the suffix (PNG by default)."""
    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    with atomic.replacing(path, key="--plot") as tmp:
        try:
            fig.savefig(tmp, dpi=110, format=fmt)
        except ValueError as e:                      # an unknown format
            raise UserError(f"cannot write a figure ({e})", file=str(path), key="--plot") from None
