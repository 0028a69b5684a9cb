"""The test report: one self-contained HTML file per run (figures as base64 PNG), laid out as
a test certificate a laboratory can sign (ISO/IEC 17025:2017, 7.8).

``write_report(RUN.h5, out=None) -> path`` (``labid report``). Printed (any browser's print
to PDF, A4), every page carries the report number, its revision and "Page n of N"
(``@page`` margin boxes); the last line is an end mark. The header block gives a unique
report number (``[report] report_number``, else one derived from the run and its results),
revision, date of issue, laboratory, customer, specimen and its receipt, method, the
results group certified. Then:

1 specimen (description, identification, receipt); 2 method, deviations, equipment with
calibration dates and due dates (the calibration the shots were recorded with) and test
conditions (temperature and its source); 3 results: one row per constant with U (k = 2) of
the GUM budget, type A and type B beside it, which type-B inputs were declared and which
assumed, the chi^2 read both ways, a statement of conformity when ``[report.limits]``
gives limits, the budget (``labid.report.results``); 4-7 spectra with picks (one mode
label per peak everywhere), scalogram, dispersion, gap diagnosis, each figure numbered
with a caption; 8 authorisation; appendices for the long tables; end mark.

The ``[report]`` table of the specimen or rig file (docs/formats.md; the specimen's entries
win) fills the header. Everything shown is read from the run file through
``labid.services``; picks, velocities, constants and the diagnosis come from the workflow's
results, never recomputed. A section whose data the run lacks says so in one line.
"""
from __future__ import annotations

import hashlib
import html
import json
import time
import tomllib
from pathlib import Path
from typing import Any, Mapping

from .. import services
from ..base import atomic
from ..base.errors import UserError
from ..base.summary import constant_cells
from ..services import IDENT_GROUPS, RunData, features_of, lookup
from .figures import fig_dispersion, fig_gap, fig_scalogram, fig_spectrum, figure
from .results import results_html
from .sections import (appendix_ref, conditions, letter, note, section_damping, section_equipment, section_gap,
                       section_picks, section_specimen, table)

#: the method the identification implements
METHOD = ("combined low/high-frequency dynamic identification: free-free modal frequencies (plate FE) "
          "and guided-wave group velocities (SAFE) fitted together; I. Bartoli, A. Marzani, "
          "\"A low/high frequency combined approach for the identification of mechanical properties of "
          "composite structural elements\", Theoret. Appl. Mech. 39(1), 1-25, Belgrade 2012")
#: fields of the [report] table shown in the header block
REPORT_FIELDS = (("lab", "Laboratory"), ("client", "Customer"), ("operator", "Operator"),
                 ("specimen_id", "Specimen ID"))

CSS = """body{font-family:sans-serif;max-width:980px;margin:1em auto;color:#222}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;border-bottom:1px solid #ccc;margin-top:1.6em}
h3{font-size:1em;margin:1em 0 .3em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}td,th{border:1px solid #ccc;padding:2px 6px;
text-align:left;vertical-align:top}th{background:#f0f0f0}.note{color:#7a5a00;background:#fff6dc;padding:4px 8px;
border-left:4px solid #e0b040}img{max-width:100%}table.cert{width:100%}table.cert th{width:22%}
.unc{font-size:.9em;background:#f4f8fc;padding:6px 8px;border-left:4px solid #7aa6d6}
table.signatures{width:100%}td.sig{height:2.6em;width:30%}.small{font-size:.8em;color:#555}
table.results{width:100%}table.results td:nth-child(-n+6),table.results td:nth-child(8){white-space:nowrap}figure{margin:.8em 0;break-inside:avoid}
figcaption{font-size:.85em;color:#333;margin-top:.2em}.end{text-align:center;margin-top:2em;font-weight:bold}
.warn{color:#900}.appendix{break-before:page}tr{break-inside:avoid}h2,h3{break-after:avoid}
@page{size:A4;margin:16mm 14mm 18mm 14mm;
@bottom-left{content:"Report no. @NUMBER@, revision @REVISION@";font-size:8pt;color:#555}
@bottom-right{content:"Page " counter(page) " of " counter(pages);font-size:8pt;color:#555}}
@media print{body{max-width:none;margin:0;font-size:10pt}}"""


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


def nominal_constants(rd: RunData) -> dict:
    try:
        mats = tomllib.loads(rd.specimen_toml).get("materials", {})
        return next(iter(mats.values())) if mats else {}
    except (tomllib.TOMLDecodeError, StopIteration):
        return {}


def report_number(rd: RunData, fields: dict) -> str:
    """``[report] report_number``, else ``LID-<file date>-<8 hex>``: a digest of the run's
    identity (file name, creation time) and of the results it certifies, so that two runs, or
    one run with new results, never share a number."""
    if fields.get("report_number"):
        return str(fields["report_number"])
    stamp = str(rd.attrs.get("file_time", ""))
    certified = {k: rd.results.get(k) for k in ("identification", "diagnosis", "analysis") if k in rd.results}
    digest = hashlib.sha256(json.dumps([Path(rd.path).name, stamp, certified], sort_keys=True,
                                       default=str).encode()).hexdigest()[:8].upper()
    return f"LID-{stamp[:10].replace('-', '') or time.strftime('%Y%m%d')}-{digest}"


def header_block(rd: RunData, run: str | Path, fields: dict, number: str) -> str:
    sp_name = ""
    try:
        sp_name = str(tomllib.loads(rd.specimen_toml or "").get("name", ""))
    except tomllib.TOMLDecodeError:
        pass
    certified = next((g for g in IDENT_GROUPS if g in rd.results), None)
    ident = services.identification_of(rd.results.get(certified)) if certified else None
    st = (ident.stored or {}) if ident is not None else {}
    what = " ".join(x for x in (f"no. {st['number']}" if "number" in st else "", st.get("time"), st.get("by")) if x)
    rows = [["Report no.", f"<b>{html.escape(number)}</b>"],
            ["Revision", html.escape(str(fields.get("revision", "0")))],
            ["Date of issue", time.strftime("%Y-%m-%d")]]
    rows += [[label, html.escape(str(fields.get(key, "not stated")))] for key, label in REPORT_FIELDS]
    rows.insert(5, ["Specimen", html.escape(sp_name or "—")])
    rows += [["Date of receipt", html.escape(str(fields.get("received", "not stated")))],
             ["Method", html.escape(str(fields.get("method") or "Bartoli & Marzani 2012, combined modal + "
                                                                  "guided-wave identification (section 2)"))],
             ["Run file", html.escape(str(run))],
             ["Result certified", (f"/results/{certified}" + (f", {html.escape(what)}" if what else "")
                                   + (f", data {html.escape(ident.data_set)}" if ident is not None else ""))
              if certified else "none (no identification)"]]
    cells = "".join(f"<tr><th>{a}</th><td>{b}</td></tr>" for a, b in rows)
    missing = [label for key, label in REPORT_FIELDS if key not in fields]
    msg = note("no [report] table in the specimen or rig file: " + ", ".join(missing).lower()
               + " not stated (docs/formats.md)") if missing else ""
    return f"<table class='cert'>{cells}</table>{msg}"


def section_method(rd: RunData, fields: dict, feats: dict, ident: Any) -> str:
    method = fields.get("method")
    out = [f"<p><b>Method.</b> {html.escape(str(method)) + '; ' if method else ''}{html.escape(METHOD)}.</p>"]
    equipment, dev = section_equipment(rd)
    rows, cdev = conditions(rd, fields, feats)
    dev = ([str(fields["deviations"])] if fields.get("deviations") else []) + dev + cdev
    data = ident.get("data") if isinstance(ident, dict) else None
    if isinstance(data, list) and data and set(data) != {"modal", "waves"}:
        dev.append(f"only {' + '.join(map(str, data))} data: the method combines modal and guided-wave data")
    out.append("<h3>Deviations from the method</h3>" + ("<ul>" + "".join(f"<li>{html.escape(d)}</li>" for d in dev)
                                                         + "</ul>" if dev else "<p>None.</p>"))
    out.append("<h3>Equipment</h3>" + equipment)
    out.append("<h3>Test conditions</h3>" + table(rows, ["condition", ""]))
    return "".join(out)


def section_results(rd: RunData, ident: Any, fields: dict, appendix: list) -> str:
    params = ident.get("parameters") if isinstance(ident, dict) else None
    if not isinstance(params, dict) or not params:
        return note("no identification in this run (run labid identify, or Identify in the panel)")
    limits = fields.get("limits") if isinstance(fields.get("limits"), dict) else None
    out = results_html(ident, nominal_constants(rd), limits)
    res = ident.get("residual") or {}
    out += (f"<p>Converged: {'yes' if ident.get('converged') else 'NO'}; relative rms residual: "
            + ", ".join(f"{html.escape(k.replace('_rms_rel', ''))} {v:.3g}" for k, v in res.items()
                        if isinstance(v, (int, float))) + ".</p>")
    notes = [str(f) if not isinstance(f, dict) else str(f.get("message", f))
             for f in list(ident.get("flags") or []) + [w for w in ident.get("warnings") or [] if isinstance(w, str)]]
    if notes:
        out += "<p><b>Flags and notes:</b></p><ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in notes) + "</ul>"
    others = {k[len("identification_"):]: v for k, v in sorted(rd.results.items())
              if k.startswith("identification_") and isinstance(v, dict) and isinstance(v.get("parameters"), dict)}
    if others:
        out += ("<p>The constants identified from each data set alone (information, not certified): Appendix "
                f"{appendix_ref(appendix, 'Constants by data set', by_data_set(ident, others, rd))}.</p>")
    return out


def by_data_set(ident: dict, others: dict, rd: RunData) -> str:
    first = services.identification_of(ident)
    sets = {first.data_set if first.data else "combined": first}
    sets.update({k: services.identification_of(v) for k, v in others.items()})
    names = list(dict.fromkeys(n for r in sets.values() for n in r.parameters))
    nominal = nominal_constants(rd)
    cells = []
    for n in names:
        row = [html.escape(n)]
        for r in sets.values():
            p = r.parameters.get(n)
            row.append("—" if not isinstance(p, dict) else
                       f"{constant_cells(n, p.get('value'), None)[0]} ± {constant_cells(n, p.get('value'), p.get('std'), 1)[1]}"
                       + ("" if r.is_identified(n) else " *"))
        nom = nominal.get(n)
        row.append(constant_cells(n, float(nom), None)[0] if isinstance(nom, (int, float)) else "—")
        cells.append(row)
    return ("<p>By data set (value ± u, type A only):</p>" + table(cells, ["constant"] + [f"{k} data" for k in sets]
                                                                    + ["nominal"]) + "<p>* fitted, not identified.</p>")


def section_signatures(fields: dict) -> str:
    op = html.escape(str(fields.get("operator", "")))
    rows = "".join(f"<tr><td>{role}</td><td>{name}</td><td class='sig'></td><td class='sig'></td></tr>"
                   for role, name in (("Tested by", op), ("Checked by", ""), ("Approved by (authorises "
                                                                              "this report)", "")))
    return (f"<table class='signatures'><tr><th>role</th><th>name</th><th>signature</th><th>date</th></tr>{rows}"
            "</table><p class='small'>This report shall not be reproduced except in full without the written "
            "approval of the laboratory. The results relate only to the specimen tested, as received.</p>")


class Figures:
    """Numbered figures with captions, in the order they are placed."""

    def __init__(self):
        self.n = 0

    def add(self, png: str | None, caption: str, missing: str) -> str:
        if not png:
            return note(missing)
        self.n += 1
        return figure(png, self.n, caption)


def report_figures(rd: RunData) -> dict[str, str | None]:
    """The figures that do not depend on the diagnosis (base64 PNG or None: spectrum, scalogram,
    dispersion), drawn from ``rd`` (``services.open_run(run, max_shots=REPORT_SHOTS)``); the demo
    draws them in its second process while the diagnosis runs (issue 29)."""
    feats = features_of(rd)
    return {"spectrum": fig_spectrum(rd, feats) if rd.hammer else None,
            "scalogram": fig_scalogram(rd, feats) if rd.wave else None,
            "dispersion": fig_dispersion(rd, feats)}


#: shots of each kind the report reads (its spectrum and scalogram)
REPORT_SHOTS = 20


def build_report(run: str | Path, identification: int | None = None, figures: Mapping | None = None) -> str:
    """The HTML text of the report of run file ``run``; ``identification``: the number of the
    kept identification it certifies (default: the newest). ``figures``: figures drawn already
    (:func:`report_figures` of this run's data and ``"gap"``: ``figures.fig_gap`` of its stored
    diagnosis); the missing ones are drawn here."""
    rd = services.open_run(run, max_shots=REPORT_SHOTS)
    if identification is not None and not isinstance(
            chosen := services.read_result(run, "identification", identification), dict):
        kept = [r["number"] for r in services.result_history(run, "identification")]
        raise UserError(f"no identification no. {identification}; kept: {kept}", file=str(run), key="--identification")
    if identification is not None:
        rd.results["identification"] = chosen
    feats = features_of(rd)
    fields = report_fields(rd)
    ident = lookup(rd.results, IDENT_GROUPS)
    number = report_number(rd, fields)
    revision = str(fields.get("revision", "0"))
    appendix: list[tuple[str, str]] = []
    figs = Figures()
    drawn: Mapping = figures or {}             # (read when placed: a Mapping may still be drawing them)
    if identification is not None or not {"spectrum", "scalogram", "dispersion"} <= set(drawn):
        drawn = {**drawn, **report_figures(rd)}   # (given ones: not for another identification)
    parts = ["<h1>Test report: elastic constants of a composite plate</h1>",
             header_block(rd, run, fields, number),
             "<h2>1. Specimen</h2>", section_specimen(rd, fields),
             "<h2>2. Method, equipment and test conditions</h2>", section_method(rd, fields, feats, ident),
             "<h2>3. Results: identified constants</h2>", section_results(rd, ident, fields, appendix),
             "<h2>4. Spectra with picks</h2>"]
    if not rd.hammer:
        parts.append(note("no hammer shots in this run"))
    else:
        parts.append(figs.add(drawn["spectrum"], "Summed normalised spectrum of the hammer hits "
                              "(dimensionless indicator, log scale) against frequency (Hz), with the picked "
                              "resonances (dashed) and the identified model's frequencies (triangles).",
                              "no spectrum"))
    if rd.hammer or (feats.get("modal") or {}).get("frequencies_hz"):
        parts.append(section_picks(feats, ident, appendix))
        parts.append(section_damping(feats, ident, appendix))
    parts.append("<h2>5. Scalogram</h2>")
    parts.append(figs.add(drawn["scalogram"],
                          "Scalogram |CWT| (colour bar: magnitude in the channel's unit) of the first wave shot, time after the "
                          "trigger (µs) against frequency (kHz), with the picked arrival ridge.",
                          "no wave shots in this run"))
    parts.append("<h2>6. Dispersion fit</h2>")
    parts.append(figs.add(drawn["dispersion"], "Measured group velocities (m/s, error bars ±σ) against "
                          "frequency (kHz), with the SAFE curves at the nominal and the identified constants.",
                          "no group velocities in this run"))
    gap_text, gap = section_gap(rd)
    parts += ["<h2>7. Gap diagnosis</h2>", gap_text]
    if gap is not None:
        png = drawn["gap"] if "gap" in drawn else fig_gap(gap)
        if png:
            parts.append(figs.add(png, "Gap (rms of residual/σ) before and after modelling each candidate "
                                       "effect.", ""))
    parts += ["<h2>8. Authorisation</h2>", section_signatures(fields)]
    for i, (title, body) in enumerate(appendix, 1):
        parts.append(f"<h2 class='appendix'>Appendix {letter(i)}. {html.escape(title)}</h2>{body}")
    parts.append(f"<p class='small'>Generated by labid {time.strftime('%Y-%m-%d %H:%M:%S %Z')} from "
                 f"{html.escape(str(run))}.</p>")
    parts.append(f"<p class='end'>— End of report {html.escape(number)} —</p>")
    css = CSS.replace("@NUMBER@", number.replace('"', "'")).replace("@REVISION@", revision.replace('"', "'"))
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Test report {html.escape(number)}"
            f"</title><style>{css}</style></head><body>{''.join(parts)}</body></html>\n")


def write_report(run: str | Path, out: str | Path | None = None, identification: int | None = None,
                 figures: Mapping | None = None) -> str:
    """Write the report of ``run`` to ``out`` (default: RUN.html next to it); returns the path.
    ``identification``: the kept identification it certifies (default: the newest);
    ``figures``: as :func:`build_report`."""
    out = Path(out) if out else Path(run).with_suffix(".html")
    text = build_report(run, identification, figures)
    atomic.write_text(out, text, key="--out")    # temp + rename (issue 15)
    return str(out)
