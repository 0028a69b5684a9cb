"""The test report: one self-contained HTML file per run (figures as base64 PNG), laid out
as a test certificate.

``write_report(RUN.h5, out=None) -> path`` (``labid report``). A header block (report
number, revision, date, lab, client, operator, specimen ID, method) from the optional
``[report]`` table of the specimen or rig file (docs/formats.md; the specimen's entries win),
then: 1 specimen, method, test conditions and the sensor calibration used (overdue channels
first); 2 identified constants in engineering notation with the expanded uncertainty
U = k x std (k = 2) and the statement of what it covers, the fit's consistency, pairing, held
constants, flags and the GUM budget (``uncertainty_budget``) when the identification holds
them; 3 spectra with picks and the modal loss factors by family; 4 scalogram; 5 dispersion fit; 6 gap diagnosis; 7 signatures.
Long tables (the picks with their sigma, the pairing, the constants by data set) are in
appendices. A section whose data the run does not hold is replaced by a one-line note
saying what is missing.

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

import html
import math
import time
import tomllib
from pathlib import Path
from typing import Any

from ..base import atomic
from .. import services
from ..base.errors import UserError
from .figures import fig_dispersion, fig_gap, fig_scalogram, fig_spectrum, img, scalar
from ..inputs.rig import rig_from_text
from ..services import GAP_GROUPS, IDENT_GROUPS, RunData, features_of, lookup
from ..inputs.specimen import specimen_from_dict
from ..base.summary import constant_cells, eng

#: coverage factor of the expanded uncertainty (about 95 % for a normal distribution)
K = 2.0
#: the method the identification implements
METHOD = ("combined low/high-frequency dynamic identification: free-free modal frequencies (plate FE) "
          "and guided-wave group velocities (SAFE) fitted together; I. Bartoli, A. Marzani, "
          "\"A low/high frequency combined approach for the identification of mechanical properties of "
          "composite structural elements\", Theoret. Appl. Mech. 39(1), 1-25, Belgrade 2012")
#: fields of the [report] table, in the order of the header block
REPORT_FIELDS = (("lab", "Laboratory"), ("client", "Client"), ("operator", "Operator"),
                 ("specimen_id", "Specimen ID"), ("method", "Method / standard"),
                 ("temperature_c", "Temperature (°C)"), ("suspension", "Suspension"),
                 ("revision", "Revision"))
#: tables longer than this go to an appendix
SHORT_TABLE = 12


# ------------------------------------------------------------------ html
def _fmt(v: float) -> str:
    """A plain number (4 significant digits; '—' for none), never given a unit by its size."""
    return eng(v)


def _param(name: str, v: float) -> str:
    """A constant in engineering notation with its unit: '136.7 GPa', '1550 kg/m³', '0.3'."""
    return constant_cells(name, v, None)[0]


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
            mrows = [[html.escape(n)] + [html.escape(f"{k} = {_param(k, v)}" if isinstance(v, (int, float))
                                                      else f"{k} = {v}") for k, v in m.items()]
                     for n, m in mats.items() if isinstance(m, dict)]
            width = max((len(r) for r in mrows), default=1)
            out.append(_table([r + [""] * (width - len(r)) for r in mrows],
                              ["material"] + ["nominal constants"] + [""] * (width - 2)))
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
    out.append(section_calibration(rd))
    backends = sorted({r.backend for r in rd.hammer + rd.wave})
    out.append(f"<p>Shots: {rd.counts.get('hammer', 0)} hammer, {rd.counts.get('wave', 0)} wave; "
               f"backend {html.escape(', '.join(backends) or '—')}; "
               f"{html.escape(str(rd.attrs.get('creator', '')))}, file created "
               f"{html.escape(str(rd.attrs.get('file_time', '')))}.</p>")
    return "".join(out)


def section_calibration(rd: RunData) -> str:
    """The sensor calibration the shots were recorded with (issue 16: serial, sensitivity,
    dates, source: sheet or TEDS) and, first, any channel recorded past its due date."""
    try:
        cal = services.run_calibration(rd.path)
    except Exception as e:  # noqa: BLE001 - a report still gets written
        return _note(f"the calibration stored in the run could not be read: {e}")
    chans = cal.get("channels") or {}
    if not chans:
        return _note("no calibration record in this run (sensitivities from the rig file)")
    out = "".join(f"<p class='warn'><b>Calibration overdue:</b> {html.escape(line)}.</p>"
                  for line in cal.get("overdue") or [])
    keys = ["serial", "sensitivity", "calibration_date", "due_date", "source"]
    rows = [[html.escape(ch)] + [html.escape(str(e.get(k, "—"))) for k in keys] for ch, e in chans.items()]
    return out + "<p>Sensor calibration used:</p>" + _table(rows, ["channel"] + keys)


def report_fields(rd: RunData) -> dict:
    """The ``[report]`` table of the rig file, overridden by the specimen file's ({} if none)."""
    out: dict = {}
    for text in (rd.rig_toml, rd.specimen_toml):
        try:
            t = tomllib.loads(text or "").get("report")
        except tomllib.TOMLDecodeError:
            continue
        if isinstance(t, dict):
            out.update({k: v for k, v in t.items() if v not in (None, "")})
    return out


def _nominal(rd: RunData) -> dict:
    try:
        mats = tomllib.loads(rd.specimen_toml).get("materials", {})
        return next(iter(mats.values())) if mats else {}
    except (tomllib.TOMLDecodeError, StopIteration):
        return {}


def _conditions(rd: RunData, fields: dict, feats: dict) -> list[list[str]]:
    """Test conditions: temperature, suspension, shots, instruments."""
    rows = []
    t = fields.get("temperature_c")
    src = "[report] table"
    if not isinstance(t, (int, float)):
        t, src = services.session_state(rd).get("setup", {}).get("temperature_c"), "environment probe"
    if not isinstance(t, (int, float)):
        t, src = (feats.get("rig") or {}).get("temperature_c"), "features file (rig)"
    rows.append(["temperature", f"{float(t):.1f} °C ({src})" if isinstance(t, (int, float)) and math.isfinite(t)
                 else "not recorded"])
    sus = fields.get("suspension")
    if not sus:
        sup = (feats.get("rig") or {}).get("supports") or []
        sus = (f"free-free, resting on {len(sup)} soft support(s) at "
               + ", ".join(f"({float(p.get('x', 0)) * 1e3:.0f}, {float(p.get('y', 0)) * 1e3:.0f}) mm"
                           for p in sup if isinstance(p, dict))) if sup else "not recorded"
    rows.append(["suspension", html.escape(str(sus))])
    acc = (feats.get("rig") or {}).get("accelerometers") or []
    if acc:
        rows.append(["accelerometers", f"{len(acc)}, " + ", ".join(
            f"{1e3 * float(a.get('mass_kg', 0)):.1f} g" for a in acc if isinstance(a, dict))
            + " each (included in the modal model)"])
    rows.append(["shots", f"{rd.counts.get('hammer', 0)} hammer hits, {rd.counts.get('wave', 0)} wave shots"])
    return rows


def section_method(rd: RunData, fields: dict, feats: dict) -> str:
    method = fields.get("method")
    out = [f"<p><b>Method.</b> {html.escape(str(method)) + '; ' if method else ''}{html.escape(METHOD)}.</p>"]
    out.append(_table(_conditions(rd, fields, feats), ["test conditions", ""]))
    return "".join(out)


def uncertainty_statement(ident: dict) -> str:
    """What the std covers and the coverage factor (GUM, JCGM 100:2008)."""
    scale = ident.get("sigma_scale") or {}
    scaled = (" The data sigmas were scaled by the Birge ratio where the fit's χ² per point exceeded 1 ("
              + ", ".join(f"{html.escape(k)} × {float(v):.3g}" for k, v in scale.items()) + ").") if scale else ""
    return ("<p class='unc'><b>Uncertainty.</b> u (std) is the standard uncertainty of each constant: the "
            "posterior standard deviation of the weighted least-squares estimate, the measurement sigmas of "
            "the features (σ of each resonance frequency, of each group velocity) propagated through the "
            f"model's sensitivities.{scaled} It covers the scatter of the measured features only; it does not "
            "cover model-form errors (boundary conditions, sensor masses, temperature, geometry), which the gap "
            f"diagnosis (section 6) examines. The expanded uncertainty U = k · u uses a coverage factor k = {K:g}, "
            "a coverage probability of about 95 % for a normal distribution (JCGM 100:2008, GUM).</p>")


def budget_html(budget: Any, params: dict) -> str:
    """The GUM budget (``uncertainty_budget`` of labid identify, docs/uncertainty.md): per
    constant u_c and U, and the standard uncertainty each input contributes."""
    consts = budget.get("constants") if isinstance(budget, dict) else None
    if not isinstance(consts, dict) or not consts:
        return ""
    names = [n for n in params if n in consts]
    sources = list(dict.fromkeys(src for n in names for src in (consts[n].get("contributions") or {})))
    rows = [[html.escape(str(src))] + [
        constant_cells(n, consts[n].get("value"), (consts[n]["contributions"].get(src) or {}).get("u"))[1]
        if src in (consts[n].get("contributions") or {}) else "—" for n in names] for src in sources]
    rows.append(["<b>combined u_c</b>"] + [constant_cells(n, consts[n].get("value"), consts[n].get("u_combined"))[1]
                                           for n in names])
    rows.append([f"<b>expanded U (k={_fmt(scalar(budget.get('coverage_factor')))})</b>"] + [
        "<b>" + constant_cells(n, consts[n].get("value"), consts[n].get("U"))[1] + "</b>" for n in names])
    return ("<p><b>Uncertainty budget</b> (GUM: type A from the fit, type B from the specimen's "
            "[uncertainty] inputs; standard uncertainty contributed by each source):</p>" + _table(rows, ["source"] + names))


def certified(ident: Any) -> str:
    """Which kept identification the report certifies (``services.store_result``: number, time, writer)."""
    st = ident.stored or {}
    what = " ".join(x for x in (f"no. {st.get('number', '?')}", st.get("time"), st.get("by")) if x)
    return f"<p>Identification certified: {html.escape(what)}, data {html.escape(ident.data_set)}.</p>"


def section_constants(rd: RunData, appendix: list) -> str:
    ident = services.identification_of(lookup(rd.results, IDENT_GROUPS))
    params = ident.parameters if ident is not None else None
    if not params:
        return _note("no identification in this run (run labid identify, or Identify in the panel)")
    nominal = _nominal(rd)
    rows = []
    for n, p in params.items():
        if not isinstance(p, dict):
            continue
        ok, why = ident.status(n)        # the one definition of "identified" (a held constant: no)
        nom = _param(n, float(nominal[n])) if isinstance(nominal.get(n), (int, float)) else "—"
        v, u, U, rel = constant_cells(n, p.get("value"), p.get("std"), K)
        rows.append([html.escape(n), f"<b>{v}</b>" if ok else v, u, f"<b>{U}</b>" if ok else U, rel, nom,
                     "yes" if ok else f"no: {html.escape(why)}"])
    for n, val in ((n, v) for n, v in ident.held.items() if n not in params):   # older results
        rows.append([html.escape(n), _param(n, val.get("value") if isinstance(val, dict) else val), "held",
                     "—", "—", "—", "no: held at its start"])
    out = certified(ident)
    out += _table(rows, ["constant", "value", "u (std)", f"U (k={K:g})", "U / value", "nominal (specimen file)",
                         "identified"])
    ident = ident.to_dict()
    out += uncertainty_statement(ident)
    fit = ident.get("fit")
    if isinstance(fit, dict):
        chi2, dof, pv = scalar(fit.get("chi2")), scalar(fit.get("dof")), scalar(fit.get("p_value"))
        cons = fit.get("consistent")
        out += (f"<p><b>Fit consistency.</b> χ² = {_fmt(chi2)} for {_fmt(dof)} degrees of freedom, "
                f"p = {_fmt(pv)}: {'consistent with the stated sigmas' if cons else 'NOT consistent'}"
                f"{'' if cons is not None else ' (not stated)'}.</p>")
    res = ident.get("residual") or {}
    conv = ident.get("converged")
    out += (f"<p>Converged: {html.escape('yes' if conv else 'NO')}; relative rms residual: "
            + ", ".join(f"{html.escape(k.replace('_rms_rel', ''))} {_fmt(scalar(v))}" for k, v in res.items())
            + ".</p>")
    flags = ident.get("flags") or []
    warns = [w for w in (ident.get("warnings") or []) if isinstance(w, str)]
    if flags or warns:
        out += "<p><b>Flags and notes:</b></p><ul>" + "".join(
            f"<li>{html.escape(str(f) if not isinstance(f, dict) else f.get('message', str(f)))}</li>"
            for f in list(flags) + warns) + "</ul>"
    out += budget_html(ident.get("uncertainty_budget"), params)
    # other data sets identified separately (identification_<data>): appendix
    others = {k[len("identification_"):]: services.identification_of(v) for k, v in sorted(rd.results.items())
              if k.startswith("identification_") and services.identification_of(v) is not None}
    if others:
        first = services.identification_of(ident)
        sets = {first.data_set if first.data else "combined": first}
        sets.update(others)
        names = list(dict.fromkeys(n for r in sets.values() for n in r.parameters))
        cells = []
        for n in names:
            row = [html.escape(n)]
            for r in sets.values():
                p = r.parameters.get(n)
                row.append("—" if not isinstance(p, dict) else
                           f"{_param(n, p.get('value'))} ± {constant_cells(n, p.get('value'), p.get('std'))[1]}"
                           + ("" if r.is_identified(n) else " *"))
            nom = nominal.get(n)
            row.append(_param(n, float(nom)) if isinstance(nom, (int, float)) else "—")
            cells.append(row)
        appendix.append(("Constants by data set", "<p>By data set (value ± u):</p>" + _table(
            cells, ["constant"] + [f"{k} data" for k in sets] + ["nominal"]) + "<p>* fitted, not identified.</p>"))
        out += f"<p>The constants identified from each data set alone: Appendix {_letter(len(appendix))}.</p>"
    return out


def _letter(i: int) -> str:
    return "ABCDEFGHIJ"[i - 1]


def section_picks(feats: dict, ident: Any, appendix: list) -> str:
    """A one-line summary of the picks; their table (with sigma) and the pairing: appendix
    when long."""
    m = feats.get("modal") or {}
    fr = m.get("frequencies_hz")
    if fr is None or not len(fr):
        return _note("no resonance picks stored in this run (run labid analyze)")
    sig = m.get("sigma_hz") or [None] * len(fr)
    rows = [[str(i + 1), f"{float(f):.3f}", eng(s, "Hz", 3) if s is not None else "—"]
            for i, (f, s) in enumerate(zip(fr, sig))]
    tab = _table(rows, ["peak", "frequency (Hz)", "σ (Hz)"])
    out = f"<p>{len(fr)} resonances picked, {float(min(fr)):.1f} Hz to {eng(max(fr), 'Hz', 4)}.</p>"
    if len(rows) > SHORT_TABLE:
        appendix.append(("Resonance picks and their σ", tab))
        out += f"<p>The picks with their σ: Appendix {_letter(len(appendix))}.</p>"
    else:
        out += tab
    pairs = ident.get("pairing") if isinstance(ident, dict) else None
    if isinstance(pairs, list) and pairs:
        prow = []
        for p in pairs:
            if not isinstance(p, dict):
                continue
            meas, pred = scalar(p.get("measured_hz")), scalar(p.get("predicted_hz"))
            diff = ("predicted mode without a peak" if meas is None else "peak without a mode" if pred is None
                    else f"{100 * (pred - meas) / meas:+.2f} %")
            prow.append([html.escape(str(p.get("peak", "—"))), "—" if meas is None else f"{meas:.3f}",
                         html.escape(str(p.get("mode_index", "—"))), html.escape(str(p.get("family") or "—")),
                         "—" if pred is None else f"{pred:.3f}", diff])
        ptab = _table(prow, ["peak", "measured (Hz)", "FE mode", "family (m,n)", "predicted (Hz)", "difference"])
        if len(prow) > SHORT_TABLE:
            appendix.append(("Pairing of measured peaks and FE modes", ptab))
            out += f"<p>Pairing of the peaks with the FE modes (families): Appendix {_letter(len(appendix))}.</p>"
        else:
            out += "<p>Pairing of the peaks with the FE modes:</p>" + ptab
    return out


def section_damping(feats: dict, appendix: list) -> str:
    """Damping as a result (issue 16): the modal loss factor per family (median, scatter) and,
    in an appendix when long, per mode; from the features' ``damping`` section."""
    d = feats.get("damping") if isinstance(feats, dict) else None
    if not isinstance(d, dict) or not d.get("modes"):
        return ""
    fams = d.get("families") or {}
    rows = [[html.escape(str(name)), str(len(v.get("modes") or [])), _fmt(scalar(v.get("median_loss_factor"))),
             _fmt(scalar(v.get("scatter")))] for name, v in fams.items() if isinstance(v, dict)]
    a = d.get("all") or {}
    rows.append(["<b>all modes</b>", str(len(d["modes"])), _fmt(scalar(a.get("median_loss_factor"))),
                 _fmt(scalar(a.get("scatter")))])
    out = ("<p><b>Damping.</b> Modal loss factor η = 2ζ of the picked peaks, by mode family "
           "(median and sample standard deviation):</p>" + _table(rows, ["family", "modes", "median η", "scatter"]))
    mrows = [[f"{scalar(m.get('frequency_hz')):.3f}", html.escape(str(m.get("label") or "—")),
              _fmt(scalar(m.get("loss_factor")))] for m in d["modes"] if isinstance(m, dict)]
    tab = _table(mrows, ["frequency (Hz)", "mode (m,n)", "η"])
    if len(mrows) > SHORT_TABLE:
        appendix.append(("Loss factor per mode", tab))
        out += f"<p>The loss factor of each mode: Appendix {_letter(len(appendix))}.</p>"
    else:
        out += tab
    return out


def _effect_magnitude(e: dict) -> str:
    unit = str(e.get("unit") or "")
    v = scalar(e.get("magnitude"))
    if v is None:
        return "—"
    if unit in ("", "1"):
        return f"{v:.3g} (ratio)"
    return eng(v, unit, 3) if unit.isalpha() and len(unit) <= 2 else f"{v:.3g} {html.escape(unit)}"


def section_gap(rd: RunData) -> str:
    gap = lookup(rd.results, GAP_GROUPS)
    if not isinstance(gap, dict) or not gap:
        return _note("no gap diagnosis in this run (run labid diagnose, or Diagnose in the panel)")
    g = gap.get("gap") or {}
    gunit = html.escape(str(g.get("unit") or "rms of residual/σ"))
    out = [f"<p><b>Verdict: {html.escape(str(gap.get('verdict', '—')))}</b>. Gap before: "
           f"{html.escape(_fmt(scalar(g.get('before'))))}, after: {html.escape(_fmt(scalar(g.get('after'))))} "
           f"({gunit}).</p>"]
    where = gap.get("where") or []
    if where:
        out.append("<p>Where: " + html.escape(", ".join(str(w) if not isinstance(w, dict) else
                                                       str(w.get("name", w)) for w in where)) + "</p>")
    effects = [e for e in (gap.get("effects") or []) if isinstance(e, dict)]
    if effects:
        rows = [[str(i + 1), html.escape(str(e.get("name"))), _effect_magnitude(e),
                 _fmt(scalar(e.get("gap_after"))), _fmt(scalar(e.get("score")))] for i, e in enumerate(effects)]
        out.append(_table(rows, ["rank", "effect", "magnitude", f"gap after ({gunit})", "score"]))
        png = fig_gap(gap)
        if png:
            out.append(img(png, "gap before and after each effect"))
    return "".join(out)


def section_signatures(fields: dict) -> str:
    op = html.escape(str(fields.get("operator", "")))
    rows = "".join(f"<tr><td>{role}</td><td>{name}</td><td class='sig'></td><td class='sig'></td></tr>"
                   for role, name in (("Tested by", op), ("Checked by", ""), ("Approved by", "")))
    return (f"<table class='signatures'><tr><th>role</th><th>name</th><th>signature</th><th>date</th></tr>{rows}"
            "</table><p class='small'>This report shall not be reproduced except in full. The results relate "
            "only to the specimen tested.</p>")


CSS = """body{font-family:sans-serif;max-width:980px;margin:1em auto;color:#222}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;border-bottom:1px solid #ccc;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}td,th{border:1px solid #ccc;padding:2px 6px;
text-align:left}th{background:#f0f0f0}.note{color:#7a5a00;background:#fff6dc;padding:4px 8px;
border-left:4px solid #e0b040}img{max-width:100%}table.cert{width:100%}table.cert th{width:18%}
.unc{font-size:.9em;background:#f4f8fc;padding:6px 8px;border-left:4px solid #7aa6d6}
table.signatures{width:100%}td.sig{height:2.6em;width:30%}.small{font-size:.8em;color:#555}
.appendix{page-break-before:always}"""


def header_block(rd: RunData, run: str | Path, fields: dict) -> str:
    sp_name = ""
    try:
        sp_name = str(tomllib.loads(rd.specimen_toml or "").get("name", ""))
    except tomllib.TOMLDecodeError:
        pass
    rows = [["Report no.", html.escape(Path(run).stem)],
            ["Revision", html.escape(str(fields.get("revision", "0")))],
            ["Date of issue", time.strftime("%Y-%m-%d")],
            ["Run file", html.escape(str(run))]]
    for key, label in REPORT_FIELDS:
        if key in ("revision", "temperature_c", "suspension", "method"):
            continue
        rows.append([label, html.escape(str(fields.get(key, "—")))])
    rows.insert(4, ["Specimen", html.escape(sp_name or "—")])
    rows.append(["Method", html.escape(str(fields.get("method") or "Bartoli & Marzani 2012, combined "
                                           "modal + guided-wave identification (section 1)"))])
    cells = "".join(f"<tr><th>{a}</th><td>{b}</td></tr>" for a, b in rows)
    missing = [label for key, label in REPORT_FIELDS[:4] if key not in fields]
    note = _note("no [report] table in the specimen or rig file: " + ", ".join(missing).lower()
                 + " not stated (docs/formats.md)") if missing else ""
    return f"<table class='cert'>{cells}</table>{note}"


def build_report(run: str | Path, identification: int | None = None) -> str:
    """The HTML text of the report of run file ``run``; ``identification``: the number of the
    kept identification it certifies (default: the newest)."""
    rd = services.open_run(run, max_shots=20)
    if identification is not None and not isinstance(
            chosen := services.read_result(run, "identification", identification), dict):
        kept = [r["number"] for r in services.result_history(run, "identification")]
        raise UserError(f"no identification no. {identification}; kept: {kept}", file=str(run), key="--identification")
    if identification is not None:
        rd.results["identification"] = chosen
    feats = features_of(rd)
    fields = report_fields(rd)
    ident = lookup(rd.results, IDENT_GROUPS)
    appendix: list[tuple[str, str]] = []
    parts = ["<h1>Test report: elastic constants of a composite plate</h1>",
             header_block(rd, run, fields),
             "<h2>1. Specimen, method and test conditions</h2>", section_setup(rd),
             section_method(rd, fields, feats),
             "<h2>2. Identified constants</h2>", section_constants(rd, appendix),
             "<h2>3. Spectra with picks</h2>"]
    if not rd.hammer:
        parts.append(_note("no hammer shots in this run"))
    else:
        png = fig_spectrum(rd, feats)
        parts.append(img(png, "spectra with picks") if png else _note("no spectrum"))
    if rd.hammer or (feats.get("modal") or {}).get("frequencies_hz"):
        parts.append(section_picks(feats, ident, appendix))
        parts.append(section_damping(feats, appendix))
    parts.append("<h2>4. Scalogram</h2>")
    png = fig_scalogram(rd, feats) if rd.wave else None
    parts.append(img(png, "scalogram") if png else _note("no wave shots in this run"))
    parts.append("<h2>5. Dispersion fit</h2>")
    png = fig_dispersion(rd, feats)
    parts.append(img(png, "group velocity") if png else _note("no group velocities in this run"))
    parts += ["<h2>6. Gap diagnosis</h2>", section_gap(rd),
              "<h2>7. Signatures</h2>", section_signatures(fields)]
    for i, (title, body) in enumerate(appendix, 1):
        parts.append(f"<h2 class='appendix'>Appendix {_letter(i)}. {html.escape(title)}</h2>{body}")
    parts.append(f"<p class='small'>Generated by labid {time.strftime('%Y-%m-%d %H:%M:%S %Z')} from "
                 f"{html.escape(str(run))}, revision {html.escape(str(fields.get('revision', '0')))}.</p>")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>labid report {html.escape(Path(run).name)}"
            f"</title><style>{CSS}</style></head><body>{''.join(parts)}</body></html>\n")


def write_report(run: str | Path, out: str | Path | None = None, identification: int | None = None) -> str:
    """Write the report of ``run`` to ``out`` (default: RUN.html next to it); returns the path.
    ``identification``: the kept identification it certifies (default: the newest)."""
    out = Path(out) if out else Path(run).with_suffix(".html")
    text = build_report(run, identification)
    atomic.write_text(out, text, key="--out")    # temp + rename (issue 15)
    return str(out)
