"""The figures of the test report (``labid.report.certificate``): matplotlib PNGs as base64 text,
drawn through ``labid.report.plots.pyplot`` (the one matplotlib set-up).

``fig_spectrum``, ``fig_scalogram``, ``fig_dispersion``, ``fig_gap`` each return the
base64 PNG of one figure, or None when the run lacks its data; ``img`` wraps one in an
``<img>`` tag; ``scalar`` reads a number from a stored result (a float, or a dict with
``total``/``rms``/``value``/``chi2``). Data come from the run through ``labid.services``;
picks, velocities and constants are never recomputed here.
"""
from __future__ import annotations

import base64
import html
import io
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from .. import services
from ..base.errors import UserError
from ..services import IDENT_GROUPS, RunData, lookup
from ..inputs.specimen import specimen_from_dict
from .plots import gap_figure, pyplot, save_figure


def waves_list(w: Any) -> list[dict]:
    if isinstance(w, dict):
        return [w]
    return [x for x in (w or []) if isinstance(x, dict)]


# ------------------------------------------------------------------ figures
def fig_png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    pyplot().close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def img(b64: str, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{b64}">'


def figure(b64: str, number: int, caption: str) -> str:
    """A numbered figure with its caption (``Figure n. caption``)."""
    return (f'<figure>{img(b64, f"Figure {number}")}<figcaption><b>Figure {number}.</b> '
            f'{html.escape(caption)}</figcaption></figure>')


def fig_spectrum(rd: RunData, feats: dict) -> str | None:
    spec = lookup(rd.results, ("analysis/spectrum", "analysis/modal/spectrum", "modal/spectrum"))
    if isinstance(spec, dict) and "frequencies_hz" in spec:
        f = np.asarray(spec["frequencies_hz"])
        y = np.asarray(spec.get("indicator", spec.get("magnitude")))
        y = y if y.ndim == 1 else (y ** 2).sum(axis=0)
        label = "stored spectrum"
    else:
        got = services.average_spectrum(rd.hammer)
        if got is None:
            return None
        f, y, kind = got
        label = f"summed normalised {'|H1|²' if kind == 'frf' else 'auto-spectra'} of {len(rd.hammer)} hits"
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.semilogy(f[1:], y[1:], lw=0.8, color="#1f77b4", label=label)
    picks = np.asarray((feats.get("modal") or {}).get("frequencies_hz", []), float)
    top = float(np.nanmax(y[1:])) if len(y) > 1 else 1.0
    for i, fp in enumerate(picks):
        ax.axvline(fp, color="#d62728", lw=0.8, ls="--", label="picked resonances" if i == 0 else None)
    model = model_frequencies_of(rd)
    for i, fm in enumerate(model):
        ax.plot([fm], [top * 1.5], "v", color="#2ca02c", label="identified model" if i == 0 else None)
    if len(picks):
        ax.set_xlim(0, min(f[-1], 1.25 * picks.max()))
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("indicator")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return fig_png(fig)


def model_frequencies_of(rd: RunData) -> np.ndarray:
    return services.model_frequencies(lookup(rd.results, IDENT_GROUPS))


def fig_scalogram(rd: RunData, feats: dict) -> str | None:
    if not rd.wave:
        return None
    rec = rd.wave[0]
    chans = [c.name for c in rec.channels]
    name = chans[-1]
    ridge = lookup(rd.results, ("analysis/arrivals", "analysis/waves/arrivals"))
    an = rd.results.get("analysis")
    sc = services.scalogram(rec, name, an if isinstance(an, dict) else None, n_freqs=80)
    t, freqs, Wm = sc.times_s, sc.frequencies_hz, sc.magnitude
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    mesh = ax.pcolormesh(t * 1e6, freqs / 1e3, Wm, shading="auto", cmap="viridis")
    unit = {"accelerometer": "m/s²", "force": "N"}.get(rec.channel(name).kind, "V")
    fig.colorbar(mesh, ax=ax, pad=0.01, label=f"|CWT| ({unit})")
    if isinstance(ridge, dict) and "times_s" in ridge:
        ax.plot(np.asarray(ridge["times_s"]) * 1e6, np.asarray(ridge["frequencies_hz"]) / 1e3, "w.-",
                ms=3, lw=0.8, label="picked arrival ridge")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("time after trigger (µs)")
    ax.set_ylabel("frequency (kHz)")
    ax.set_title(f"|CWT| of {rec.meta.get('shot', 'wave shot')}, channel {name} ({sc.wavelet})", fontsize=9)
    return fig_png(fig)


def fig_dispersion(rd: RunData, feats: dict) -> str | None:
    ws = waves_list(feats.get("waves"))
    if not ws:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    for w in ws:
        f = np.asarray(w.get("frequency_hz", []), float)
        v = np.asarray(w.get("group_velocity_m_s", []), float)
        s = np.asarray(w.get("sigma_m_s", np.zeros_like(v)), float)
        ax.errorbar(f / 1e3, v, yerr=s, fmt="o", ms=3, capsize=2,
                    label=f"measured {w.get('mode', '')} {w.get('direction_deg', 0):g}°")
    params = services.parameters_of(lookup(rd.results, IDENT_GROUPS))
    lam = laminate_of(rd)
    if lam is not None:
        for w in ws:
            f = np.asarray(w.get("frequency_hz", []), float)
            if f.size < 2:
                continue
            grid = np.linspace(f.min(), f.max(), 60)
            mode, d = str(w.get("mode", "A0")), float(w.get("direction_deg", 0.0))
            for label, p, style in (("nominal", None, "--"), ("identified", params, "-")):
                if label == "identified" and not params:
                    continue
                try:
                    v = services.model_group_velocity(lam, grid, mode, d, p)
                except (ValueError, KeyError, TypeError):
                    continue
                ax.plot(grid / 1e3, v, style, color="#2ca02c" if p else "0.4",
                        label=f"SAFE {mode}, {label} constants")
    ax.set_xlabel("frequency (kHz)")
    ax.set_ylabel("group velocity (m/s)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig_png(fig)


def laminate_of(rd: RunData):
    """The laminate of the run's specimen, or None."""
    try:
        return specimen_from_dict(tomllib.loads(rd.specimen_toml), "run file").laminate
    except Exception:  # noqa: BLE001 - the figure just lacks the model curve
        return None


def fig_gap(gap: dict, path: str | Path | None = None) -> str | None:
    """The diagnosis' figure (``labid.report.plots.gap_figure``, as ``labid diagnose --plot``);
    ``path``: also written there (``plot_gap``'s file), from the same drawing (the demo: the
    figure is laid out once, ~0.6 s less)."""
    fig = gap_figure(gap)
    if fig is None:
        if path is not None:
            raise UserError("the diagnosis holds no residuals, groups or effects to draw", file=str(path),
                            key="--plot")
        return None
    if path is not None:
        save_figure(fig, path)
    return fig_png(fig)


def scalar(v: Any) -> float | None:
    if isinstance(v, (int, float, np.floating, np.integer)):
        return float(v)
    if isinstance(v, dict):
        for k in ("total", "rms", "value", "chi2"):
            if k in v:
                return scalar(v[k])
    return None
