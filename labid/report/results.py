"""Section 2 of the certificate: the results, one uncertainty statement per constant (issue 26).

``results_html(ident, nominal, limits) -> str``: one row per constant, never two (a constant
both fitted and "held" under a weak prior is one row whose status says so):

- the value, the expanded uncertainty U (k = 2) **of the GUM budget** (``uncertainty_budget``
  of ``labid identify``: U = k u_c, u_c^2 = u_A^2 + u_B^2) with the type-A and type-B standard
  uncertainties beside it; without a budget U = k u_A and the type B is said to be not evaluated;
- which type-B inputs were declared (the specimen's ``[uncertainty]`` table) and which are
  assumed defaults;
- the chi^2 reading both ways (chi^2/nu << 1: the stated sigmas are too large; >> 1: too small,
  or the model misses an effect);
- a statement of conformity when ``[report.limits]`` gives limits (decision rule: the
  interval value +- U against the limits, ILAC-G8:09/2019 guarded acceptance).

Units SI in, engineering notation out (``labid.base.summary``).
"""
from __future__ import annotations

import html
import math
from typing import Any, Mapping

from ..base.results import Identification
from ..base.summary import constant_cells, eng, finite
from .figures import scalar

#: coverage factor when the identification holds no budget (about 95 %, normal distribution)
K = 2.0
#: chi^2 tail probability below which the fit's chi^2 is called improbably large or small
TAIL = 1e-3


def _in_prefix(name: str, value: Any, x: Any) -> str:
    """An uncertainty ``x`` of constant ``name`` in the SI prefix of its value."""
    return constant_cells(name, value, x, 1.0)[1]


def _table(rows: list[list[str]], head: list[str], cls: str = "") -> str:
    h = "".join(f"<th>{x}</th>" for x in head)
    b = "".join("<tr>" + "".join(f"<td>{x}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table{f' class={cls!r}' if cls else ''}><tr>{h}</tr>{b}</table>"


def _percent(x: float) -> str:
    """A relative uncertainty in %, 2 significant digits, never in e-notation (130 %, 5.3 %)."""
    return f"{x:.0f} %" if x >= 99.5 else f"{x:.2g} %"


def constant_rows(ident: Mapping, nominal: Mapping) -> list[dict]:
    """One dict per constant (name, value, U, k, u_a, u_b, status, nominal, in_budget), the
    fitted ones first, then those held fixed; a name appears once."""
    params = ident.get("parameters") if isinstance(ident.get("parameters"), Mapping) else {}
    held = ident.get("held") if isinstance(ident.get("held"), Mapping) else {}
    budget = ident.get("uncertainty_budget") if isinstance(ident.get("uncertainty_budget"), Mapping) else {}
    bconst = budget.get("constants") if isinstance(budget.get("constants"), Mapping) else {}
    k_b = finite(budget.get("coverage_factor")) or K
    typed = Identification.from_dict(ident)
    rows = []
    for n, p in params.items():
        if not isinstance(p, Mapping):
            continue
        v, std = finite(p.get("value")), finite(p.get("std"))
        b = bconst.get(n) if isinstance(bconst.get(n), Mapping) else None
        if b is not None:
            u_a = finite(b.get("u_type_a"))
            u_a = std if u_a is None else u_a
            u_b, u_c = finite(b.get("u_type_b")), finite(b.get("u_combined"))
            if u_b is None and u_c is not None and u_a is not None:     # u_c^2 = u_A^2 + u_B^2
                u_b = math.sqrt(max(u_c * u_c - u_a * u_a, 0.0))
            row = dict(U=finite(b.get("U")), k=k_b, u_a=u_a, u_b=u_b, in_budget=True)
        else:
            row = dict(U=None if std is None else K * std, k=K, u_a=std, u_b=None, in_budget=False)
        ok, why = typed.status(n)          # the one definition of "identified" (labid.base.results)
        if n in held:
            h = held[n]
            why = f"held at {h.get('value') if isinstance(h, Mapping) else h} under a weak prior ({why})"
        status = "identified" if ok else "not identified" + (f": {why}" if why else "")
        rows.append(dict(name=n, value=v, status=status, nominal=finite(nominal.get(n)), **row))
    for n, h in held.items():
        if n in params:
            continue        # fitted under a weak prior: its one row above says "held"
        val = h.get("value") if isinstance(h, Mapping) else h
        why = h.get("reason") if isinstance(h, Mapping) else None
        rows.append(dict(name=n, value=finite(val), U=None, k=K, u_a=None, u_b=None, in_budget=False,
                         status="held at this value, not fitted" + (f" ({why})" if why else ""),
                         nominal=finite(nominal.get(n))))
    return rows


def results_table(rows: list[dict]) -> str:
    """The bold results table: value, U (k = 2) with U/value, type A and type B u, status, nominal."""
    k = rows[0]["k"] if rows else K
    cells = []
    for r in rows:
        n, v = r["name"], r["value"]
        vs = constant_cells(n, v, None)[0]
        U = _in_prefix(n, v, r["U"]) if r["U"] is not None else "—"
        rel = _percent(100 * r["U"] / abs(v)) if (r["U"] is not None and v) else "—"
        ua = _in_prefix(n, v, r["u_a"]) if r["u_a"] is not None else "—"
        ub = (_in_prefix(n, v, r["u_b"]) if r["u_b"] is not None
              else "not evaluated" if r["U"] is not None else "—")
        cells.append([html.escape(n), f"<b>{vs}</b>", f"<b>{U}</b>", rel, ua, ub, html.escape(r["status"]),
                      constant_cells(n, r["nominal"], None)[0] if r["nominal"] is not None else "—"])
    return _table(cells, ["constant", "value", f"U (k = {k:g})", "U / value", "u type A (fit)",
                          "u type B (inputs)", "status", "nominal (specimen file)"], "results")


def inputs_statement(budget: Mapping | None) -> str:
    """Which type-B inputs were declared in the specimen file and which are assumed defaults."""
    inputs = [x for x in (budget or {}).get("inputs") or [] if isinstance(x, Mapping)]
    if not inputs:
        return ("<p class='unc'><b>Type B not evaluated.</b> This identification holds no GUM budget: "
                "U covers the type-A (fit) uncertainty only; the dimensions, density and sensor positions "
                "are taken as exact (add an [uncertainty] table to the specimen file and rerun labid "
                "identify).</p>")

    def item(x: Mapping) -> str:
        unit = str(x.get("unit") or "")
        u = finite(x.get("u"))
        return html.escape(f"{x.get('name')} {eng(u, unit.replace('^3', '³'), 2) if u is not None else '—'}")

    declared = [item(x) for x in inputs if x.get("source") == "specimen"]
    default = [item(x) for x in inputs if x.get("source") != "specimen"]
    out = "<p class='unc'><b>Type-B inputs.</b> "
    out += ("Declared in the specimen file's [uncertainty] table: " + ", ".join(declared) + ". "
            if declared else "None declared in the specimen file. ")
    if default:
        out += ("<b>Assumed defaults</b> (not measured by the laboratory; docs/uncertainty.md): "
                + ", ".join(default) + ".")
    return out + "</p>"


def chi2_reading(ident: Mapping) -> str:
    """The fit's chi^2 read both ways: too small (sigmas too large) or too large (sigmas too
    small, or an effect the model lacks); an inconsistent fit says so first."""
    fit = ident.get("fit")
    if not isinstance(fit, Mapping):
        return ""
    chi2, dof, p = scalar(fit.get("chi2")), scalar(fit.get("dof")), scalar(fit.get("p_value"))
    if chi2 is None or not dof:
        return ""
    r = chi2 / dof
    head = f"χ² = {chi2:.3g} for ν = {dof:.0f} degrees of freedom, χ²/ν = {r:.3g}"
    if p is not None:
        ps = "p > 0.999" if p > 0.999 else "p < 0.001" if p < 0.001 else f"p = {p:.3g}"
        head += f" (probability of a larger χ²: {ps})"
    if p is not None and p > 1.0 - TAIL or (p is None and r < 0.5):
        reading = (f"χ²/ν ≪ 1: the residuals are about {1 / math.sqrt(max(r, 1e-12)):.2g} times smaller than "
                   "the stated sigmas of the features, so those sigmas are too large and the type-A "
                   "uncertainty is overstated (pessimistic).")
    elif p is not None and p < TAIL or (p is None and r > 2.0):
        reading = (f"χ²/ν ≫ 1: the residuals are about {math.sqrt(r):.2g} times larger than the stated sigmas: "
                   "the sigmas are too small, or the model misses an effect (see the gap diagnosis); the "
                   "constants are not consistent with the data.")
    else:
        reading = "χ²/ν ≈ 1: the residuals match the stated sigmas of the features."
    first = ("<b>The fit is NOT consistent with its data: the constants above are not identified.</b> "
             if fit.get("consistent") is False else "")
    scale = ident.get("sigma_scale") or {}
    scaled = (" The data sigmas were scaled by the Birge ratio where χ² per point exceeded 1 ("
              + ", ".join(f"{html.escape(str(k))} × {float(v):.3g}" for k, v in scale.items()
                          if finite(v) is not None) + ").") if isinstance(scale, Mapping) and scale else ""
    return (f"<p><b>Fit consistency.</b> {first}{head}. {reading}{scaled} (Reading: χ²/ν ≪ 1 means the "
            "stated sigmas are too large; χ²/ν ≫ 1 means they are too small or the model is incomplete.)</p>")


def conformity(rows: list[dict], limits: Mapping | None) -> str:
    """Statement of conformity against ``limits`` ({name: [low, high]} in SI; None for an
    open side). Decision rule: conforms when value +- U lies within the limits, does not
    conform when it lies wholly outside, else no statement (the interval straddles a limit)."""
    if not isinstance(limits, Mapping) or not limits:
        return ""
    by = {r["name"]: r for r in rows}
    out = []
    for n, lim in limits.items():
        r = by.get(n)
        lo, hi = (lim[0], lim[1]) if isinstance(lim, (list, tuple)) and len(lim) == 2 else (None, None)
        lo, hi = finite(lo), finite(hi)
        spec = " to ".join(constant_cells(n, x, None)[0] if x is not None else "—" for x in (lo, hi))
        if r is None or r["value"] is None:
            out.append([html.escape(n), spec, "—", "not measured"])
            continue
        v, U = r["value"], r["U"] if r["U"] is not None else float("inf")
        a, b = v - U, v + U
        inside = (lo is None or a >= lo) and (hi is None or b <= hi)
        outside = (lo is not None and b < lo) or (hi is not None and a > hi)
        verdict = ("conforms" if inside and r["status"] == "identified" else
                   "does not conform" if outside else
                   "no statement: not identified" if r["status"] != "identified" else
                   "no statement: value ± U straddles a limit")
        out.append([html.escape(n), spec, f"{constant_cells(n, v, None)[0]} ± {_in_prefix(n, v, r['U'])}",
                    f"<b>{verdict}</b>"])
    return ("<p><b>Statement of conformity</b> (decision rule: the interval value ± U (k = 2) against the "
            "specification's limits; conforms when it lies within them, does not conform when it lies "
            "wholly outside, no statement when it straddles a limit; ILAC-G8:09/2019):</p>"
            + _table(out, ["constant", "specification", "value ± U", "decision"]))


def results_html(ident: Mapping, nominal: Mapping, limits: Mapping | None = None) -> str:
    """Section 2's results: the table, the uncertainty and inputs statements, the chi^2
    reading and the statement of conformity."""
    rows = constant_rows(ident, nominal)
    budget = ident.get("uncertainty_budget") if isinstance(ident.get("uncertainty_budget"), Mapping) else None
    k = rows[0]["k"] if rows else K
    what = ("U is the expanded uncertainty of the GUM budget below: U = k · u_c with u_c² = u_A² + u_B², "
            "u_A the type-A standard uncertainty of the fit (the measured features' sigmas propagated through "
            "the model) and u_B the type-B one (the specimen's dimensions, density and sensor positions "
            "propagated through the same model)" if budget else
            "U = k · u_A, u_A the type-A standard uncertainty of the fit (the measured features' sigmas "
            "propagated through the model's sensitivities)")
    return (results_table(rows)
            + f"<p class='unc'><b>Uncertainty.</b> {what}; coverage factor k = {k:g}, a coverage probability "
              "of about 95 % for a normal distribution (JCGM 100:2008, GUM). It does not cover model-form "
              "errors (boundary conditions, unmodelled sensor effects), which the gap diagnosis examines.</p>"
            + inputs_statement(budget) + chi2_reading(ident) + conformity(rows, limits)
            + budget_html(budget, [r['name'] for r in rows]))


def budget_html(budget: Any, names: list[str]) -> str:
    """The GUM budget (``uncertainty_budget`` of labid identify, docs/uncertainty.md): per
    constant the standard uncertainty each input contributes, u_c and U; a type-B input
    that is an assumed default is marked so."""
    consts = budget.get("constants") if isinstance(budget, Mapping) else None
    if not isinstance(consts, Mapping) or not consts:
        return ""
    names = [n for n in names if n in consts]
    source = {str(x.get("name")): x.get("source") for x in budget.get("inputs") or [] if isinstance(x, Mapping)}
    sources = list(dict.fromkeys(src for n in names for src in (consts[n].get("contributions") or {})))

    def label(src: str) -> str:
        tag = " (default)" if source.get(src) == "default" else " (declared)" if source.get(src) else ""
        return html.escape(src.replace("_", " ") + tag)

    rows = [[label(src)] + [
        _in_prefix(n, consts[n].get("value"), (consts[n]["contributions"].get(src) or {}).get("u"))
        if src in (consts[n].get("contributions") or {}) else "—" for n in names] for src in sources]
    rows.append(["<b>combined u_c</b>"] + [_in_prefix(n, consts[n].get("value"), consts[n].get("u_combined"))
                                           for n in names])
    k = finite(budget.get("coverage_factor")) or K
    rows.append([f"<b>expanded U (k = {k:g})</b>"] + [
        "<b>" + _in_prefix(n, consts[n].get("value"), consts[n].get("U")) + "</b>" for n in names])
    return ("<p><b>Uncertainty budget</b> (GUM: type A from the fit, type B from the specimen's "
            "[uncertainty] inputs; standard uncertainty contributed by each source, in the unit of the "
            "constant; the expanded U is the one of the results table):</p>"
            + _table(rows, ["source"] + [html.escape(n) for n in names], "budget"))
