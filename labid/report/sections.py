"""Sections of the certificate other than the results (``labid.report.certificate`` lays them out).

Specimen and its receipt, method and deviations, equipment with calibration dates (ISO/IEC
17025 7.8.2-7.8.3), test conditions with the temperature's source, resonance picks with one
mode label per peak, damping, gap diagnosis. Each returns HTML text; a section whose data the
run lacks says so in one line. Everything is read from the run (``labid.services``).
"""
from __future__ import annotations

import datetime as dt
import html
import math
import tomllib
from typing import Any, Mapping

from .. import services
from ..base.summary import constant_cells, eng
from ..inputs.rig import rig_from_text
from ..inputs.specimen import specimen_from_dict
from ..services import GAP_GROUPS, RunData, lookup
from .figures import scalar

#: tables longer than this go to an appendix
SHORT_TABLE = 12


def fmt(v: Any) -> str:
    """A plain number with 4 significant digits, '—' for None/NaN."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    return f"{v:.4g}"


def table(rows: list[list[str]], head: list[str], cls: str = "") -> str:
    h = "".join(f"<th>{html.escape(x)}</th>" for x in head)
    b = "".join("<tr>" + "".join(f"<td>{x}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table{f' class={cls!r}' if cls else ''}><tr>{h}</tr>{b}</table>"


def note(text: str) -> str:
    return f'<p class="note">{html.escape(text)}</p>'


def letter(i: int) -> str:
    return "ABCDEFGHIJ"[i - 1]


def appendix_ref(appendix: list, title: str, body: str) -> str:
    """Add an appendix; its letter."""
    appendix.append((title, body))
    return letter(len(appendix))


# ------------------------------------------------------------------ specimen and receipt
def section_specimen(rd: RunData, fields: Mapping) -> str:
    out = []
    if not rd.specimen_toml:
        out.append(note("no specimen recorded in this run"))
    else:
        try:
            doc = tomllib.loads(rd.specimen_toml)
            sp = specimen_from_dict(doc, "run file")
            lam = sp.laminate
            angles = ", ".join(f"{p.angle_deg:g}" for p in lam.plies) if hasattr(lam.plies[0], "angle_deg") else ""
            rows = [["description", html.escape(sp.name)],
                    ["identification", html.escape(str(fields.get("specimen_id", "not stated")))],
                    ["plate", f"{sp.length * 1e3:.1f} mm × {sp.width * 1e3:.1f} mm, "
                              f"{lam.thickness * 1e3:.3f} mm thick, {sp.mass * 1e3:.1f} g (nominal)"],
                    ["plies", f"{len(lam.plies)}" + (f" [{angles}]°" if angles else "")],
                    ["date of receipt", html.escape(str(fields.get("received", "not stated")))],
                    ["condition on receipt", html.escape(str(fields.get("condition", "not stated")))]]
            out.append(table(rows, ["specimen", ""]))
            mats = doc.get("materials", {})
            mrows = [[html.escape(n), html.escape(", ".join(
                f"{k} = {param(k, v)}" if isinstance(v, (int, float)) else f"{k} = {v}" for k, v in m.items()))]
                for n, m in mats.items() if isinstance(m, dict)]
            out.append(table(mrows, ["material", "nominal constants (specimen file; start of the fit)"]))
        except Exception as e:  # noqa: BLE001 - a report still gets written
            out.append(note(f"specimen text stored in the run could not be read: {e}"))
    return "".join(out)


def param(name: str, v: float) -> str:
    """A constant in engineering notation with its unit: '136.7 GPa', '1550 kg/m³', '0.3'."""
    return constant_cells(name, v, None)[0]


# ------------------------------------------------------------------ equipment
def section_equipment(rd: RunData) -> tuple[str, list[str]]:
    """The equipment table (each acquisition device, then each sensor with serial, sensitivity,
    calibration date, due date and source) and the deviations it implies."""
    deviations: list[str] = []
    try:
        cal = services.run_calibration(rd.path)
    except Exception as e:  # noqa: BLE001 - a report still gets written
        cal = {}
        deviations.append(f"the calibration stored in the run could not be read ({e})")
    chans = cal.get("channels") or {}
    rows = []
    try:
        rig = rig_from_text(rd.rig_toml, "run file") if rd.rig_toml else None
    except Exception as e:  # noqa: BLE001
        rig = None
        deviations.append(f"the rig text stored in the run could not be read ({e})")
    seen = set()
    for d in (rig.devices if rig else ()):
        rows.append([f"<b>{html.escape(d.name)}</b> ({d.role} DAQ)", html.escape(d.product or "—"),
                     html.escape(d.daq_device or "—"), f"{eng(d.timing.rate_hz, 'Hz', 3)}, {d.adc_bits} bit",
                     "—", "—", "—"])
        for c in d.channels:
            seen.add(c.name)
            e = chans.get(c.name)
            if e:
                rows.append([f"&nbsp;&nbsp;{html.escape(c.name)} ({c.kind})", html.escape(str(e.get("serial", "—"))),
                             html.escape(c.physical or "—"), _sensitivity(c.kind, e.get("sensitivity")),
                             html.escape(str(e.get("calibration_date") or "—")),
                             html.escape(str(e.get("due_date") or "—")), html.escape(str(e.get("source", "—")))])
            else:
                rows.append([f"&nbsp;&nbsp;{html.escape(c.name)} ({c.kind})", "—", html.escape(c.physical or "—"),
                             _sensitivity(c.kind, c.sensitivity), "not recorded", "not recorded", "rig file"])
    for ch, e in chans.items():
        if ch not in seen:
            rows.append([html.escape(ch), html.escape(str(e.get("serial", "—"))), "—",
                         _sensitivity("", e.get("sensitivity")), html.escape(str(e.get("calibration_date") or "—")),
                         html.escape(str(e.get("due_date") or "—")), html.escape(str(e.get("source", "—")))])
    if not rows:
        return note("no equipment recorded in this run"), deviations
    missing = [r for r in rows if r[4] == "not recorded"]
    if not chans:
        deviations.append("no calibration record in this run: the sensitivities are the rig file's nominal "
                          "values, with no calibration date or traceability")
    elif missing:
        deviations.append(f"{len(missing)} channel(s) without a calibration record")
    warn = ""
    for line in cal.get("overdue") or []:
        deviations.append(f"calibration overdue: {line}")
        warn += f"<p class='warn'><b>Calibration overdue:</b> {html.escape(line)}.</p>"
    return warn + table(rows, ["instrument", "serial / model", "physical channel", "sensitivity / rate",
                        "calibrated on", "calibration due", "source"], "equipment"), deviations


def _sensitivity(kind: str, v: Any) -> str:
    x = scalar(v) if not isinstance(v, str) else None
    if x is None:
        return html.escape(str(v)) if v is not None else "—"
    unit = {"accelerometer": "V/(m/s²)", "force": "V/N", "voltage": "V/V"}.get(kind, "V/unit")
    return f"{x:.4g} {unit}"


# ------------------------------------------------------------------ conditions
def temperature(rd: RunData, fields: Mapping, feats: Mapping) -> tuple[float | None, str]:
    """The test temperature (°C) and where it comes from: the [report] table, the shots'
    environment probe reading, the panel's probe, the features file's rig."""
    t = fields.get("temperature_c")
    if isinstance(t, (int, float)):
        return float(t), "[report] table"
    for r in rd.hammer + rd.wave:
        v = (r.meta or {}).get("temperature_c")
        if isinstance(v, (int, float)) and math.isfinite(v):
            return float(v), f"environment probe, shot {r.meta.get('shot', '')}"
    t = services.session_state(rd).get("setup", {}).get("temperature_c")
    if isinstance(t, (int, float)) and math.isfinite(t):
        return float(t), "environment probe (panel)"
    t = (feats.get("rig") or {}).get("temperature_c")
    if isinstance(t, (int, float)) and math.isfinite(t):
        return float(t), "features file (rig.temperature_c)"
    return None, ""


def test_dates(rd: RunData) -> str:
    stamps = sorted(r.timestamp for r in rd.hammer + rd.wave if isinstance(r.timestamp, (int, float)))
    if not stamps:
        return html.escape(str(rd.attrs.get("file_time", "not recorded")))
    a, b = (dt.datetime.fromtimestamp(s, dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC") for s in (stamps[0],
                                                                                                   stamps[-1]))
    return a if a == b else f"{a} to {b}"


def conditions(rd: RunData, fields: Mapping, feats: Mapping) -> tuple[list[list[str]], list[str]]:
    """Rows of the test-conditions table and the deviations they imply."""
    rows, dev = [], []
    t, src = temperature(rd, fields, feats)
    rows.append(["ambient temperature", f"{t:.1f} °C ({html.escape(src)})" if t is not None else "not recorded"])
    if t is None:
        dev.append("ambient temperature not recorded (no [report] temperature_c, environment probe or "
                   "features rig.temperature_c)")
    sus = fields.get("suspension")
    if not sus:
        sup = (feats.get("rig") or {}).get("supports") or []
        sus = (f"free-free, resting on {len(sup)} soft support(s) at "
               + ", ".join(f"({float(p.get('x', 0)) * 1e3:.0f} mm, {float(p.get('y', 0)) * 1e3:.0f} mm)"
                           for p in sup if isinstance(p, dict))) if sup else "not recorded"
    rows.append(["suspension", html.escape(str(sus))])
    acc = (feats.get("rig") or {}).get("accelerometers") or []
    if acc:
        rows.append(["accelerometers on the plate", f"{len(acc)}, " + ", ".join(
            f"{1e3 * float(a.get('mass_kg', 0)):.1f} g" for a in acc if isinstance(a, dict))
            + " (included in the modal model)"])
    backends = sorted({r.backend for r in rd.hammer + rd.wave if r.backend})
    rows.append(["shots", f"{rd.counts.get('hammer', 0)} hammer hits, {rd.counts.get('wave', 0)} wave shots; "
                          f"backend {html.escape(', '.join(backends) or '—')}"])
    rows.append(["date(s) of test", test_dates(rd)])
    if "mock" in backends:
        dev.append("the shots were recorded on the simulated rig (mock backend), not measured on a specimen")
    return rows, dev


# ------------------------------------------------------------------ picks, one label per peak
def peak_labels(feats: Mapping, ident: Any) -> dict[int, str]:
    """One (m,n) label per peak index: the identified model's (the pairing) where the run
    holds it, else the analysis' (nominal model) labels of the damping section."""
    out: dict[int, str] = {}
    modes = ((feats.get("damping") or {}).get("modes") or []) if isinstance(feats, Mapping) else []
    freqs = list((feats.get("modal") or {}).get("frequencies_hz") or [])
    for m in modes:
        if isinstance(m, Mapping) and m.get("label"):
            f = scalar(m.get("frequency_hz"))
            i = min(range(len(freqs)), key=lambda j: abs(freqs[j] - f)) if (freqs and f is not None) else None
            if i is not None:
                out[i] = str(m["label"])
    pairs = ident.get("pairing") if isinstance(ident, Mapping) else None
    for p in pairs if isinstance(pairs, list) else []:
        if isinstance(p, Mapping) and isinstance(p.get("peak"), int) and p.get("family"):
            out[p["peak"]] = str(p["family"])
    return out


def section_picks(feats: Mapping, ident: Any, appendix: list) -> str:
    """A one-line summary of the picks; the picks (with sigma and their one mode label) and the
    pairing go to an appendix when long. Peaks are numbered from 1 everywhere."""
    m = feats.get("modal") or {}
    fr = m.get("frequencies_hz")
    if fr is None or not len(fr):
        return note("no resonance picks stored in this run (run labid analyze)")
    labels = peak_labels(feats, ident)
    sig = m.get("sigma_hz") or [None] * len(fr)
    rows = [[str(i + 1), f"{float(f):.3f}", eng(s, "Hz", 3) if s is not None else "—",
             html.escape(labels.get(i, "—"))] for i, (f, s) in enumerate(zip(fr, sig))]
    tab = table(rows, ["peak", "frequency (Hz)", "σ (Hz)", "mode (m,n)"])
    out = f"<p>{len(fr)} resonances picked, {float(min(fr)):.1f} Hz to {eng(max(fr), 'Hz', 4)}.</p>"
    if len(rows) > SHORT_TABLE:
        out += f"<p>The picks with their σ and mode label: Appendix {appendix_ref(appendix, 'Resonance picks and their σ', tab)}.</p>"
    else:
        out += tab
    pairs = ident.get("pairing") if isinstance(ident, Mapping) else None
    if isinstance(pairs, list) and pairs:
        prow = []
        for p in pairs:
            if not isinstance(p, Mapping):
                continue
            meas, pred = scalar(p.get("measured_hz")), scalar(p.get("predicted_hz"))
            diff = ("predicted mode without a peak" if meas is None else "peak without a mode" if pred is None
                    else f"{100 * (pred - meas) / meas:+.2f} %")
            pk = p.get("peak")
            mi = p.get("mode_index")
            prow.append([str(pk + 1) if isinstance(pk, int) else "—", "—" if meas is None else f"{meas:.3f}",
                         str(mi + 1) if isinstance(mi, int) else "—", html.escape(str(p.get("family") or "—")),
                         "—" if pred is None else f"{pred:.3f}", diff])
        ptab = table(prow, ["peak", "measured (Hz)", "FE mode", "mode (m,n)", "predicted (Hz)", "difference"])
        if len(prow) > SHORT_TABLE:
            out += ("<p>Pairing of the peaks with the identified model's modes: Appendix "
                    f"{appendix_ref(appendix, 'Pairing of measured peaks and FE modes', ptab)}.</p>")
        else:
            out += "<p>Pairing of the peaks with the identified model's modes:</p>" + ptab
    return out


def section_damping(feats: Mapping, ident: Any, appendix: list) -> str:
    """The modal loss factor per family (median, scatter) and per mode, each mode under the
    one label :func:`peak_labels` gives its peak."""
    d = feats.get("damping") if isinstance(feats, Mapping) else None
    if not isinstance(d, Mapping) or not d.get("modes"):
        return ""
    labels = peak_labels(feats, ident)
    freqs = list((feats.get("modal") or {}).get("frequencies_hz") or [])
    modes = []
    for m in d["modes"]:
        if not isinstance(m, Mapping):
            continue
        f, eta = scalar(m.get("frequency_hz")), scalar(m.get("loss_factor"))
        i = min(range(len(freqs)), key=lambda j: abs(freqs[j] - f)) if (freqs and f is not None) else None
        modes.append((f, labels.get(i, str(m.get("label") or "unlabelled")), eta))
    fams: dict[str, list[float]] = {}
    for _, lab, eta in modes:
        if eta is not None and math.isfinite(eta):
            fams.setdefault(services.family_of(lab), []).append(eta)
    rows = [[html.escape(name), str(len(v)), fmt(_median(v)), fmt(_std(v))] for name, v in fams.items()]
    allv = [e for v in fams.values() for e in v]
    rows.append(["<b>all modes</b>", str(len(allv)), fmt(_median(allv)), fmt(_std(allv))])
    out = ("<p><b>Damping.</b> Modal loss factor η = 2ζ of the picked peaks (dimensionless), by mode family "
           "(median and sample standard deviation), with the peaks' mode labels of the table of picks:</p>"
           + table(rows, ["family", "modes", "median η", "scatter"]))
    mrows = [[f"{f:.3f}" if f is not None else "—", html.escape(lab), fmt(eta)] for f, lab, eta in modes]
    tab = table(mrows, ["frequency (Hz)", "mode (m,n)", "η"])
    if len(mrows) > SHORT_TABLE:
        out += f"<p>The loss factor of each mode: Appendix {appendix_ref(appendix, 'Loss factor per mode', tab)}.</p>"
    else:
        out += tab
    return out


def _median(v: list[float]) -> float | None:
    s = sorted(v)
    n = len(s)
    return None if not n else (s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2]))


def _std(v: list[float]) -> float | None:
    if len(v) < 2:
        return None
    m = sum(v) / len(v)
    return math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))


# ------------------------------------------------------------------ gap
def effect_magnitude(e: Mapping) -> str:
    unit = str(e.get("unit") or "")
    v = scalar(e.get("magnitude"))
    if v is None:
        return "—"
    if unit in ("", "1"):
        return f"{v:.3g} (ratio)"
    return eng(v, unit, 3) if unit.isalpha() and len(unit) <= 2 else f"{v:.3g} {html.escape(unit)}"


def section_gap(rd: RunData) -> tuple[str, dict | None]:
    """The gap diagnosis text and table; the diagnosis (for its figure) or None."""
    gap = lookup(rd.results, GAP_GROUPS)
    if not isinstance(gap, dict) or not gap:
        return note("no gap diagnosis in this run (run labid diagnose, or Diagnose in the panel)"), None
    g = gap.get("gap") or {}
    gunit = html.escape(str(g.get("unit") or "rms of residual/σ"))
    out = [f"<p><b>Verdict: {html.escape(str(gap.get('verdict', '—')))}</b>. Gap before: "
           f"{html.escape(fmt(scalar(g.get('before'))))}, after: {html.escape(fmt(scalar(g.get('after'))))} "
           f"({gunit}).</p>"]
    where = gap.get("where") or []
    if where:
        out.append("<p>Where: " + html.escape(", ".join(str(w) if not isinstance(w, dict) else
                                                       str(w.get("name", w)) for w in where)) + "</p>")
    effects = [e for e in (gap.get("effects") or []) if isinstance(e, dict)]
    if effects:
        rows = [[str(i + 1), html.escape(str(e.get("name"))), effect_magnitude(e),
                 fmt(scalar(e.get("gap_after"))), fmt(scalar(e.get("score")))] for i, e in enumerate(effects)]
        out.append(table(rows, ["rank", "effect", "magnitude", "gap after (same unit)", "score"]))
    return "".join(out), gap
