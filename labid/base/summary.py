"""Plain-text console summaries shared by the commands, the panel and the report.

Pure functions on plain data (no I/O, no Qt, no engine import), each returning a
``str`` of lines ending in a newline unless stated:

- ``eng(value, unit, digits=4) -> str``: engineering notation with an SI prefix,
  ``eng(1.367e11, "Pa") == "136.7 GPa"``, ``eng(4.94e-4, "Hz") == "494.0 µHz"``;
  ``unit=""`` gives a bare number (``0.3``); NaN/None gives ``"—"``.
- ``unit_of(name, plain=False) -> str``: SI unit of an elastic constant by name: ``E*``/``G*``/``C*`` ->
  ``Pa``, ``nu*`` -> ``""``, ``density``/``rho`` -> ``kg/m³``, ``thickness`` -> ``m``; ``plain``:
  ASCII for files (``kg/m^3``, ``1`` for a ratio: the CSV's ``unit`` column).
- ``display_unit(name) -> (unit, scale)``: the fixed unit of a console or panel column and
  the factor from SI: Pa constants in ``("GPa", 1e-9)``, others in their ``unit_of`` with 1.
- ``constant_cells(name, value, std, k=2) -> (value, std, U, rel U)``: the cells of one
  constant as text, std and U in the value's prefix.
- ``constants_table(parameters, k=2, nominal=None) -> str``: one row per constant of
  ``{name: {"value", "std"}}`` (an identification's ``parameters``): value, std,
  U = k x std, relative U, nominal (if given).
- ``pairing_table(pairs) -> str``: a list of ``{peak, measured_hz, mode_index, family,
  predicted_hz}`` (any may be None): measured peak against FE mode, difference in %;
  a row with no peak reads "predicted mode without a peak", one with no mode
  "peak without a mode".
- ``modes_table(frequencies_hz, families=None, sigma_hz=None) -> str``: mode number,
  frequency (Hz), family label ((m,n), torsion, in-plane) and sigma when given.
- ``dispersion_table(modes) -> str``: one row per guided-wave mode of a
  ``labid dispersion`` result (``label``, ``cutoff_hz``, ``frequency_hz``,
  ``phase_velocity_m_s``, ``group_velocity_m_s``): cut-off, frequency span, number
  of points and the velocities at the lowest and highest frequency.
- ``next_step(counts, results) -> (current, next)``: where a run stands and what comes next,
  from its shot counts (``{"hammer": n, "wave": m}``) and results group names:
  ``("analysed: 39 resonances", "identify (Identification tab, or labid identify)")``.
- ``stream(args)``: where a command's summary goes: stdout, or None when ``--json -``
  holds stdout for the JSON result.
- ``table(head, rows, align=None) -> str``: the text table itself (columns padded,
  a dashed rule under the head); numbers right-aligned by default.
- ``budget_text(uncertainty_budget) -> str``: the GUM budget of an identification as
  ``labid identify`` prints it (per constant U, u_c, type A/B and each input's share).
"""
from __future__ import annotations

import math
import sys
from typing import Any, Iterable, Mapping, Sequence

__all__ = ["eng", "finite", "unit_of", "display_unit", "constant_cells", "constants_table", "pairing_table",
           "modes_table", "dispersion_table", "next_step", "stream", "table", "budget_text", "PREFIXES"]

#: SI prefixes by power of 1000
PREFIXES = {-4: "p", -3: "n", -2: "µ", -1: "m", 0: "", 1: "k", 2: "M", 3: "G", 4: "T"}
DASH = "—"


def finite(v: Any) -> float | None:
    """``v`` as a finite float, or None (not a number, NaN, inf)."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _exp3(x: float) -> int:
    """Power of 1000 of the engineering notation of x (0 for 0), clamped to PREFIXES."""
    if x == 0:
        return 0
    e = math.floor(math.log10(abs(x)) / 3)
    return max(min(e, 4), -4)


def _digits(x: float, digits: int) -> str:
    """x with ``digits`` significant digits, no exponent, no trailing zeros beyond them."""
    x = float(f"{x:.{digits}g}")   # round first: 0.99996 -> 1.0, then count decimals
    if x == 0:
        return "0"
    dec = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
    s = f"{x:.{dec}f}"
    return s


def eng(value: Any, unit: str = "", digits: int = 4, exp3: int | None = None) -> str:
    """``value`` in engineering notation with ``unit`` (SI prefix chosen so 1 <= |mantissa| < 1000,
    or forced by ``exp3``): ``eng(1.367e11, 'Pa') -> '136.7 GPa'``. Without a unit, a bare
    number with ``digits`` significant digits. ``'—'`` for None/NaN."""
    x = finite(value)
    if x is None:
        return DASH
    if not unit:
        return f"{x:.{digits}g}"
    e = _eng_exp(x, digits) if exp3 is None else exp3
    m = x / 1000.0 ** e
    s = _digits(m, digits) if m != 0 else "0"
    return f"{s} {PREFIXES[e]}{unit}"


def _eng_exp(x: float, digits: int) -> int:
    """Power of 1000 ``eng`` uses for x: rounding that carries to 1000 (999.96) moves up."""
    e = _exp3(x)
    if x != 0 and abs(float(f"{x / 1000.0 ** e:.{digits}g}")) >= 1000 and e < 4:
        e += 1
    return e


def unit_of(name: str, plain: bool = False) -> str:
    """SI unit of a constant by name (see module doc); ``plain``: ASCII, '1' for a ratio."""
    n = str(name)
    low = n.lower()
    if low.startswith("nu"):
        return "1" if plain else ""
    if low in ("density", "rho"):
        return "kg/m^3" if plain else "kg/m³"
    if low in ("thickness", "length", "width"):
        return "m"
    if n[:1] in ("E", "G", "C"):
        return "Pa"
    return "1" if plain else ""


def display_unit(name: str) -> tuple[str, float]:
    """(unit, scale) of a fixed-unit column: moduli (``unit_of`` Pa) in GPa (scale 1e-9),
    Poisson ratios bare (``""``), density in kg/m³, lengths in m (scale 1)."""
    u = unit_of(name)
    return ("GPa", 1e-9) if u == "Pa" else (u, 1.0)


def constant_cells(name: str, value: Any, std: Any, k: float = 2.0) -> tuple[str, str, str, str]:
    """(value, std, U = k x std, U / |value|) as text, std and U in the value's SI prefix."""
    u = unit_of(name)
    v, s = finite(value), finite(std)
    if u and u != "kg/m³" and v is not None:
        e = _eng_exp(v, 4)
        vs = eng(v, u, 4, exp3=e)
        ss = eng(s, u, 2, exp3=e) if s is not None else DASH
        us = eng(k * s, u, 2, exp3=e) if s is not None else DASH
    elif u == "kg/m³":
        vs = f"{_digits(v, 4)} {u}" if v is not None else DASH
        ss = f"{_digits(s, 2)} {u}" if s is not None else DASH
        us = f"{_digits(k * s, 2)} {u}" if s is not None else DASH
    else:
        vs, ss = eng(v, "", 4), eng(s, "", 2)
        us = eng(k * s, "", 2) if s is not None else DASH
    rel = f"{100 * k * s / abs(v):.2g} %" if (v and s is not None) else DASH
    return vs, ss, us, rel


def table(head: Sequence[str], rows: Iterable[Sequence[Any]], align: str | None = None) -> str:
    """Text table: columns padded to their widest cell, a rule under the head. ``align``
    is one character per column, 'l' or 'r' (default: 'l' for the first, 'r' for others)."""
    rows = [[DASH if c is None else str(c) for c in r] for r in rows]
    n = len(head)
    align = align or ("l" + "r" * (n - 1))
    w = [max([len(head[i])] + [len(r[i]) for r in rows if i < len(r)]) for i in range(n)]

    def line(cells):
        out = []
        for i in range(n):
            c = cells[i] if i < len(cells) else ""
            out.append(c.ljust(w[i]) if align[i] == "l" else c.rjust(w[i]))
        return "  ".join(out).rstrip()

    return "\n".join([line(list(head)), "  ".join("-" * x for x in w)] + [line(r) for r in rows]) + "\n"


def constants_table(parameters: Mapping[str, Mapping], k: float = 2.0,
                    nominal: Mapping[str, float] | None = None) -> str:
    """Identified constants: value, std, expanded U = k x std, relative U, nominal."""
    rows = []
    for name, p in (parameters or {}).items():
        if not isinstance(p, Mapping):
            continue
        vs, ss, us, rel = constant_cells(name, p.get("value"), p.get("std"), k)
        row = [name, vs, ss, us, rel]
        if nominal is not None:
            nv = nominal.get(name)
            row.append(constant_cells(name, nv, None)[0] if finite(nv) is not None else DASH)
        rows.append(row)
    head = ["constant", "value", "std", f"U (k={k:g})", "rel. U"] + (["nominal"] if nominal is not None else [])
    return table(head, rows)


def _hz(v: Any, digits: int = 2) -> str:
    x = finite(v)
    return DASH if x is None else f"{x:.{digits}f}"


def pairing_table(pairs: Sequence[Mapping]) -> str:
    """Measured peaks against FE modes (see module doc)."""
    rows = []
    for p in pairs or []:
        meas, pred = finite(p.get("measured_hz")), finite(p.get("predicted_hz"))
        peak, idx = p.get("peak"), p.get("mode_index")
        if meas is None:
            note = "predicted mode without a peak"
        elif pred is None:
            note = "peak without a mode"
        else:
            note = f"{100 * (pred - meas) / meas:+.2f} %"
        rows.append([DASH if peak is None else str(peak), _hz(meas), DASH if idx is None else str(idx),
                     str(p.get("family") or DASH), _hz(pred), note])
    return table(["peak", "measured (Hz)", "FE mode", "family", "predicted (Hz)", "difference"], rows,
                 align="rrrlrl")


def modes_table(frequencies_hz: Sequence[float], families: Sequence[str] | None = None,
                sigma_hz: Sequence[float] | None = None) -> str:
    """Mode number, frequency (Hz), family label and sigma (Hz) when given."""
    rows = []
    for i, f in enumerate(frequencies_hz):
        r = [str(i + 1), _hz(f, 3)]
        if sigma_hz is not None:
            r.append(f"{float(sigma_hz[i]):.3g}" if i < len(sigma_hz) and finite(sigma_hz[i]) is not None
                     else DASH)
        if families is not None:
            r.append(families[i] if i < len(families) else DASH)
        rows.append(r)
    head = ["mode", "frequency (Hz)"] + (["σ (Hz)"] if sigma_hz is not None else []) + \
        (["family (m,n)"] if families is not None else [])
    return table(head, rows, align="rr" + ("r" if sigma_hz is not None else "") + ("l" if families is not None else ""))


def dispersion_table(modes: Sequence[Mapping]) -> str:
    """Guided-wave modes of a dispersion result: cut-off, frequency span, points, velocities."""
    rows = []
    for m in modes or []:
        f = list(m.get("frequency_hz") or [])
        cp = list(m.get("phase_velocity_m_s") or [])
        cg = list(m.get("group_velocity_m_s") or [])
        if f:
            rows.append([str(m.get("label")), eng(m.get("cutoff_hz"), "Hz", 3) if finite(m.get("cutoff_hz")) else "0 Hz",
                         f"{eng(f[0], 'Hz', 3)} – {eng(f[-1], 'Hz', 3)}", str(len(f)),
                         f"{cp[0]:.0f} / {cp[-1]:.0f}", f"{cg[0]:.0f} / {cg[-1]:.0f}"])
        else:
            rows.append([str(m.get("label")), eng(m.get("cutoff_hz"), "Hz", 3), "not on the grid", "0", DASH, DASH])
    return table(["mode", "cut-off", "frequencies", "points", "c_p (m/s) low/high", "c_g (m/s) low/high"],
                 rows, align="lrrrrr")


def next_step(counts: Mapping[str, int], results: Mapping[str, Any] | Iterable[str]) -> tuple[str, str]:
    """(current step, next step) of a run from its shot counts and results (see module doc)."""
    names = set(results)
    h, w = int((counts or {}).get("hammer", 0)), int((counts or {}).get("wave", 0))
    if not h and not w:
        return "no shots yet", "acquire (Acquisition tab, or labid acquire)"
    shots = f"{h} hammer hit{'s' * (h != 1)}, {w} wave shot{'s' * (w != 1)}"
    if not names & {"analysis", "features"}:
        return f"acquired: {shots}", "analyse (Modes tab: Analyze run, or labid analyze)"
    if not any(n.startswith(("identification", "identify")) for n in names):
        return f"analysed: {shots}", "identify (Identification tab, or labid identify)"
    if not names & {"diagnosis", "gap", "diagnose"}:
        return "identified", "diagnose the sim-to-real gap (Gap tab, or labid diagnose)"
    return "identified and diagnosed", "write the report (File > Write report, or labid report)"


def stream(args):
    """``sys.stdout`` for a command's human summary, or None when ``--json -`` uses stdout."""
    return None if getattr(args, "json", None) == "-" else sys.stdout


def budget_text(b: Mapping[str, Any]) -> str:
    """Console table: per constant U (k, coverage), u_c, and each input's contribution."""
    lines = [f"  uncertainty budget (GUM): expanded U = k u_c, coverage {b['coverage']}:"]
    for n, c in b["constants"].items():
        unit, sc = display_unit(n)
        unit = f" {unit}" if unit else ""
        rel = f" ({100 * c['U_rel']:.2g} %)" if c.get("U_rel") is not None else ""
        lines.append(f"  {n:>7} = {c['value'] * sc:10.4g}{unit}, U (k={b.get('coverage_factor', 2.0):g}) "
                     f"{c['U'] * sc:.3g}{unit}{rel}  [u_c {c['u_combined'] * sc:.3g}: type A "
                     f"{c['u_type_a'] * sc:.3g}, type B {c['u_type_b'] * sc:.3g}]")
        if not math.isfinite(c["u_combined"]):
            lines.append("           no budget: the fit does not determine this constant (infinite type-A std)")
            continue
        rows = sorted(c["contributions"].items(), key=lambda kv: -kv[1]["u"])
        lines.append("           " + ", ".join(f"{k} {v['u'] * sc:.2g} ({100 * v['share']:.0f} %)"
                                              for k, v in rows if v["share"] >= 0.005))
    inp = ", ".join(f"{x['name']} {x['u']:.3g} {x['unit']}{'' if x['source'] == 'specimen' else ' (default)'}"
                    for x in b["inputs"])
    lines.append(f"  inputs (standard uncertainties): {inp}")
    if any(x["source"] != "specimen" for x in b["inputs"]):
        lines.append("  (default): assumed, not declared in the specimen's [uncertainty] table (docs/uncertainty.md)")
    lines += [f"  note: {n}" for n in b["notes"]]
    return "\n".join(lines) + "\n"
