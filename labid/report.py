"""The test report: one self-contained HTML file per run (figures as base64 PNG).

``write_report(RUN.h5, out=None) -> path`` (``labid report``). Sections:
specimen and setup, spectra with picks, scalogram, dispersion fit, identified
constants with uncertainty, gap diagnosis. A section whose data the run does
not hold is replaced by a one-line note saying what is missing.

Everything shown is read from the run file: the configuration texts, the raw
shots and the ``/results`` groups written by the workflow (analysis,
identification, diagnosis, gui). Figures are drawn with matplotlib (Agg).
The run is read and display-only transforms of raw data (an averaged
amplitude spectrum, a scalogram, the SAFE curves) are computed through
``labid.services``, when the analysis did not store its own curves; picks,
velocities, constants and the diagnosis always come from the workflow's
results, never recomputed.
"""
from __future__ import annotations

import base64
import html
import io
import math
import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from . import atomic, services
from .errors import UserError
from .rig import rig_from_text
from .services import GAP_GROUPS, IDENT_GROUPS, RunData, features_of, lookup
from .specimen import specimen_from_dict


def _waves_list(w: Any) -> list[dict]:
    if isinstance(w, dict):
        return [w]
    return [x for x in (w or []) if isinstance(x, dict)]


# ------------------------------------------------------------------ figures
def _fig_png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    _plt().close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _img(b64: str, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{b64}">'


def _plt():
    """pyplot on the Agg backend, imported when the first figure is drawn: the panel imports
    this module at start and does not pay matplotlib's 0.3 s until a report is written."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    return plt


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
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.semilogy(f[1:], y[1:], lw=0.8, color="#1f77b4", label=label)
    picks = np.asarray((feats.get("modal") or {}).get("frequencies_hz", []), float)
    top = float(np.nanmax(y[1:])) if len(y) > 1 else 1.0
    for i, fp in enumerate(picks):
        ax.axvline(fp, color="#d62728", lw=0.8, ls="--", label="picked resonances" if i == 0 else None)
    model = _model_frequencies(rd)
    for i, fm in enumerate(model):
        ax.plot([fm], [top * 1.5], "v", color="#2ca02c", label="identified model" if i == 0 else None)
    if len(picks):
        ax.set_xlim(0, min(f[-1], 1.25 * picks.max()))
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("indicator")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return _fig_png(fig)


def _model_frequencies(rd: RunData) -> np.ndarray:
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
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.pcolormesh(t * 1e6, freqs / 1e3, Wm, shading="auto", cmap="viridis")
    if isinstance(ridge, dict) and "times_s" in ridge:
        ax.plot(np.asarray(ridge["times_s"]) * 1e6, np.asarray(ridge["frequencies_hz"]) / 1e3, "w.-",
                ms=3, lw=0.8, label="picked arrival ridge")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("time after trigger (µs)")
    ax.set_ylabel("frequency (kHz)")
    ax.set_title(f"|CWT| of {rec.meta.get('shot', 'wave shot')}, channel {name} ({sc.wavelet})", fontsize=9)
    return _fig_png(fig)


def fig_dispersion(rd: RunData, feats: dict) -> str | None:
    ws = _waves_list(feats.get("waves"))
    if not ws:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    for w in ws:
        f = np.asarray(w.get("frequency_hz", []), float)
        v = np.asarray(w.get("group_velocity_m_s", []), float)
        s = np.asarray(w.get("sigma_m_s", np.zeros_like(v)), float)
        ax.errorbar(f / 1e3, v, yerr=s, fmt="o", ms=3, capsize=2,
                    label=f"measured {w.get('mode', '')} {w.get('direction_deg', 0):g}°")
    params = services.parameters_of(lookup(rd.results, IDENT_GROUPS))
    lam = _laminate(rd)
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
    return _fig_png(fig)


def _laminate(rd: RunData):
    """The laminate of the run's specimen, or None."""
    try:
        return specimen_from_dict(tomllib.loads(rd.specimen_toml), "run file").laminate
    except Exception:  # noqa: BLE001 - the figure just lacks the model curve
        return None


def fig_gap(gap: dict) -> str | None:
    effects = [e for e in (gap.get("effects") or []) if isinstance(e, dict)]
    g = gap.get("gap") or {}
    if not effects:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 3.0))
    names = [str(e.get("name")) for e in effects]
    after = [float(e.get("gap_after", np.nan)) for e in effects]
    ax.barh(names[::-1], after[::-1], color="#9ecae1", label="gap after modelling the effect")
    before = _scalar(g.get("before"))
    if before is not None:
        ax.axvline(before, color="#d62728", ls="--", label="gap before")
    ax.set_xlabel("gap (misfit measure)")
    ax.legend(fontsize=8)
    return _fig_png(fig)


def _scalar(v: Any) -> float | None:
    if isinstance(v, (int, float, np.floating, np.integer)):
        return float(v)
    if isinstance(v, dict):
        for k in ("total", "rms", "value", "chi2"):
            if k in v:
                return _scalar(v[k])
    return None


# ------------------------------------------------------------------ html
def _fmt(v: float) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    a = abs(v)
    if a >= 1e6:
        return f"{v / 1e9:.4g} GPa" if a >= 1e8 else f"{v:.4g}"
    return f"{v:.4g}"


def _param(name: str, v: float) -> str:
    """A constant in its usual unit: GPa for moduli, kg/m^3 for density, bare for ratios."""
    if v is None or not math.isfinite(v):
        return "—"
    if name.startswith("nu"):
        return f"{v:.4g}"
    if name == "density":
        return f"{v:.4g} kg/m³"
    return f"{v / 1e9:.4g} GPa"


def _table(rows: list[list[str]], head: list[str]) -> str:
    h = "".join(f"<th>{html.escape(x)}</th>" for x in head)
    b = "".join("<tr>" + "".join(f"<td>{x}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{b}</table>"


def _note(text: str) -> str:
    return f'<p class="note">{html.escape(text)}</p>'


def section_setup(rd: RunData) -> str:
    out = []
    if rd.specimen_toml:
        try:
            sp = specimen_from_dict(tomllib.loads(rd.specimen_toml), "run file")
            lam = sp.laminate
            angles = ", ".join(f"{p.angle_deg:g}" for p in lam.plies) if hasattr(lam.plies[0], "angle_deg") else ""
            rows = [["name", html.escape(sp.name)],
                    ["plate", f"{sp.length * 1e3:.1f} × {sp.width * 1e3:.1f} mm, "
                              f"{lam.thickness * 1e3:.3f} mm thick, {sp.mass * 1e3:.1f} g"],
                    ["plies", f"{len(lam.plies)}" + (f" [{angles}]°" if angles else "")]]
            out.append(_table(rows, ["specimen", ""]))
            mats = tomllib.loads(rd.specimen_toml).get("materials", {})
            mrows = [[html.escape(n)] + [html.escape(f"{k} = {v:g}") for k, v in m.items()]
                     for n, m in mats.items() if isinstance(m, dict)]
            width = max((len(r) for r in mrows), default=1)
            out.append(_table([r + [""] * (width - len(r)) for r in mrows],
                              ["material"] + ["nominal constants (SI)"] + [""] * (width - 2)))
        except Exception as e:  # noqa: BLE001 - a report still gets written
            out.append(_note(f"specimen text stored in the run could not be read: {e}"))
    else:
        out.append(_note("no specimen recorded in this run"))
    if rd.rig_toml:
        try:
            rig = rig_from_text(rd.rig_toml, "run file")
            rows = [[html.escape(d.name), d.role, html.escape(d.product), f"{d.timing.rate_hz:g}",
                     f"{d.timing.samples}", f"{d.timing.pretrigger}",
                     html.escape(", ".join(c.name for c in d.channels)),
                     html.escape(f"{d.trigger.channel} {d.trigger.level_v:g} V {d.trigger.slope}"
                                 if d.trigger else "—")] for d in rig.devices]
            out.append(f"<p>Rig: {html.escape(rig.name)}</p>")
            out.append(_table(rows, ["device", "role", "product", "rate (Hz)", "samples", "pre-trigger",
                                     "channels", "trigger"]))
        except Exception as e:  # noqa: BLE001
            out.append(_note(f"rig text stored in the run could not be read: {e}"))
    backends = sorted({r.backend for r in rd.hammer + rd.wave})
    out.append(f"<p>Shots: {rd.counts.get('hammer', 0)} hammer, {rd.counts.get('wave', 0)} wave; "
               f"backend {html.escape(', '.join(backends) or '—')}; "
               f"{html.escape(str(rd.attrs.get('creator', '')))}, file created "
               f"{html.escape(str(rd.attrs.get('file_time', '')))}.</p>")
    t = services.session_state(rd).get("setup", {}).get("temperature_c")
    if isinstance(t, (int, float)) and math.isfinite(t):
        out.append(f"<p>Air temperature (environment probe): {t:.2f} °C</p>")
    return "".join(out)


def section_constants(rd: RunData) -> str:
    ident = lookup(rd.results, IDENT_GROUPS)
    params = ident.get("parameters") if isinstance(ident, dict) else None
    if not isinstance(params, dict) or not params:
        return _note("no identification in this run (run labid identify, or Identify in the panel)")
    nominal = {}
    try:
        mats = tomllib.loads(rd.specimen_toml).get("materials", {})
        nominal = next(iter(mats.values())) if mats else {}
    except tomllib.TOMLDecodeError:
        pass
    rows = []
    for n, p in params.items():
        v, s = float(p.get("value", np.nan)), float(p.get("std", np.nan))
        nom = nominal.get(n)
        rows.append([html.escape(n), _param(n, v), _param(n, s), f"{100 * s / abs(v):.2g} %" if v else "—",
                     _param(n, float(nom)) if isinstance(nom, (int, float)) else "—"])
    res = ident.get("residual") or {}
    conv = ident.get("converged")
    extra = (f"<p>converged: {html.escape(str(bool(conv)))}; residual: "
             + ", ".join(f"{html.escape(k)} = {_fmt(_scalar(v)) if _scalar(v) is not None else '—'}"
                         for k, v in res.items()) + "</p>")
    out = _table(rows, ["parameter", "value", "std", "rel. std", "nominal (specimen file)"]) + extra
    # other data sets identified separately (identification_<data>): one column each
    others = {k[len("identification_"):]: v for k, v in sorted(rd.results.items())
              if k.startswith("identification_") and isinstance(v, dict) and isinstance(v.get("parameters"), dict)}
    if others:
        sets = {"combined" if not ident.get("data") else str(ident.get("data")): params}
        sets.update({k: v["parameters"] for k, v in others.items()})
        names = list(dict.fromkeys(n for ps in sets.values() for n in ps))
        cells = []
        for n in names:
            row = [html.escape(n)]
            for ps in sets.values():
                p = ps.get(n)
                row.append("—" if not isinstance(p, dict) else
                           f"{_param(n, float(p.get('value', np.nan)))} ± "
                           f"{_param(n, float(p.get('std', np.nan)))}")
            nom = nominal.get(n)
            row.append(_param(n, float(nom)) if isinstance(nom, (int, float)) else "—")
            cells.append(row)
        out += "<p>By data set:</p>" + _table(cells, ["parameter"] + [f"{k} data" for k in sets] + ["nominal"])
    return out


def section_gap(rd: RunData) -> str:
    gap = lookup(rd.results, GAP_GROUPS)
    if not isinstance(gap, dict) or not gap:
        return _note("no gap diagnosis in this run (run labid diagnose, or Diagnose in the panel)")
    g = gap.get("gap") or {}
    out = [f"<p><b>Verdict: {html.escape(str(gap.get('verdict', '—')))}</b>. Gap before: "
           f"{html.escape(_fmt(_scalar(g.get('before'))) if _scalar(g.get('before')) is not None else '—')}, "
           f"after: {html.escape(_fmt(_scalar(g.get('after'))) if _scalar(g.get('after')) is not None else '—')}.</p>"]
    where = gap.get("where") or []
    if where:
        out.append("<p>Where: " + html.escape(", ".join(str(w) if not isinstance(w, dict) else
                                                       str(w.get("name", w)) for w in where)) + "</p>")
    effects = [e for e in (gap.get("effects") or []) if isinstance(e, dict)]
    if effects:
        rows = [[str(i + 1), html.escape(str(e.get("name"))), _fmt(_scalar(e.get("magnitude"))),
                 html.escape(str(e.get("unit", ""))), _fmt(_scalar(e.get("gap_after"))),
                 _fmt(_scalar(e.get("score")))] for i, e in enumerate(effects)]
        out.append(_table(rows, ["rank", "effect", "magnitude", "unit", "gap after", "score"]))
        png = fig_gap(gap)
        if png:
            out.append(_img(png, "gap before and after each effect"))
    return "".join(out)


CSS = """body{font-family:sans-serif;max-width:980px;margin:1em auto;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;border-bottom:1px solid #ccc;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}td,th{border:1px solid #ccc;padding:2px 6px;
text-align:left}th{background:#f0f0f0}.note{color:#7a5a00;background:#fff6dc;padding:4px 8px;
border-left:4px solid #e0b040}img{max-width:100%}"""


def build_report(run: str | Path) -> str:
    """The HTML text of the report of run file ``run``."""
    rd = services.open_run(run, max_shots=20)
    feats = features_of(rd)
    parts = [f"<h1>labid test report — {html.escape(Path(run).name)}</h1>",
             f"<p>Generated {time.strftime('%Y-%m-%d %H:%M:%S %Z')} from {html.escape(str(run))}.</p>",
             "<h2>1. Specimen and setup</h2>", section_setup(rd),
             "<h2>2. Spectra with picks</h2>"]
    if not rd.hammer:
        parts.append(_note("no hammer shots in this run"))
    else:
        png = fig_spectrum(rd, feats)
        parts.append(_img(png, "spectra with picks") if png else _note("no spectrum"))
        m = feats.get("modal") or {}
        fr = m.get("frequencies_hz")
        if fr is not None and len(fr):
            sig = m.get("sigma_hz", [np.nan] * len(fr))
            parts.append(_table([[str(i + 1), f"{float(f):.3f}", f"{float(s):.3g}"]
                                 for i, (f, s) in enumerate(zip(fr, sig))], ["mode", "frequency (Hz)", "σ (Hz)"]))
        else:
            parts.append(_note("no resonance picks stored in this run (run labid analyze)"))
    parts.append("<h2>3. Scalogram</h2>")
    png = fig_scalogram(rd, feats) if rd.wave else None
    parts.append(_img(png, "scalogram") if png else _note("no wave shots in this run"))
    parts.append("<h2>4. Dispersion fit</h2>")
    png = fig_dispersion(rd, feats)
    parts.append(_img(png, "group velocity") if png else _note("no group velocities in this run"))
    parts += ["<h2>5. Identified constants</h2>", section_constants(rd),
              "<h2>6. Gap diagnosis</h2>", section_gap(rd)]
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>labid report {html.escape(Path(run).name)}"
            f"</title><style>{CSS}</style></head><body>{''.join(parts)}</body></html>\n")


def write_report(run: str | Path, out: str | Path | None = None) -> str:
    """Write the report of ``run`` to ``out`` (default: RUN.html next to it); returns the path."""
    out = Path(out) if out else Path(run).with_suffix(".html")
    text = build_report(run)
    atomic.write_text(out, text, key="--out")    # temp + rename (issue 15)
    return str(out)
