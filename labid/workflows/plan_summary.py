"""The console summary of a test plan (``labid plan``; the setup view's Plan box shows it too).

Plain text from the plan's document (``PlanResult.to_dict()``): the verdict first (which
wanted constants reach the target, which cannot and what limits them), then the table of
predicted stds (recommended plan, the user's rig, each compared rig), the recommended
layout, the waves' recommendation and the identify command to use. Relative stds in %.
"""
from __future__ import annotations

__all__ = ["plan_text"]


def _pct(v: float | None) -> str:
    if v is None:
        return "-"
    if v >= 10:
        return ">1000 %"
    return f"{100 * v:.3g} %"


def _why(c: dict, constants) -> str:
    lim = c.get("limited_by") or {}
    src = lim.get("source", "")
    if src == "data (type A)":
        cw = lim.get("correlated_with")
        return "the data" + (f" (correlation {cw['correlation']:+.2f} with {cw['constant']})" if cw else "")
    if src == "sensor masses":
        return f"the accelerometers' mass uncertainty ({100 * lim['share']:.0f} % of the variance)"
    if src:
        return (f"{src} ({'held at nominal, its prior' if src in constants else 'type-B input'}: "
                f"{100 * lim['share']:.0f} % of the variance)")
    return ""


def plan_text(doc: dict) -> str:
    """The summary (module docstring)."""
    out = []
    rec, rigs, w = doc["recommended"], doc["rigs"], doc["waves"]
    meas = doc["measurement"]
    p = doc["plate"]
    out.append(f"{doc['specimen']} ({1e3 * p['length_m']:g} x {1e3 * p['width_m']:g} x "
               f"{1e3 * p['thickness_m']:.3g} mm): plan for {', '.join(doc['want'])} to u <= "
               f"{100 * doc['target_u']:g} % (prior {_prior(doc['prior_rel'])}, {doc['draws']} draws, "
               f"{doc['criterion']}-optimal{', budget: ' + doc['budget'] if doc['budget'] != 'none' else ''})")
    miss = [n for n in doc["want"] if not rec["constants"][n]["meets_target"]]
    if not miss:
        out.append(f"VERDICT: every wanted constant reaches {100 * doc['target_u']:g} % with the recommended plan"
                   + (" (modal and guided waves)" if w.get("recommended") else " (modal data alone)"))
    else:
        out.append(f"VERDICT: {', '.join(miss)} cannot reach {100 * doc['target_u']:g} % with this test:")
        for n in miss:
            c = rec["constants"][n]
            out.append(f"  {n}: {_pct(c['std_rel'])} at best, limited by {_why(c, doc['constants'])}")
    if w.get("recommended"):
        mo = doc["recommended_modal_only"]["constants"]
        lost = [n for n in doc["want"] if n in mo and mo[n]["std_rel"] > 0.10]
        if lost:
            vals = ", ".join(f"{n} {_pct(mo[n]['std_rel'])}" for n in lost)
            out.append(f"  without the guided waves: {vals} (modal data alone cannot bring them below 10 %)")
    out.append("")
    out.append(f"modal test: band {meas['band_hz']:.0f} Hz (hammer and acquisition); the model's "
               f"{rec['modes_in_band']} modes in it (at most {meas['max_modes']}, --max-modes), peak sigma {100 * meas['sigma_rel']:.3g} %, "
               f"{len(rec['accelerometers'])} accelerometer(s) of {1e3 * rec['accelerometers'][0]['mass_kg']:.3g} g "
               f"(+-{100 * meas['mass_u_rel']:.3g} %)")
    heads = ["recommended"] + [r["label"] + (f" (#{r['rank']})" if "rank" in r else "") for r in rigs]
    cols = [rec] + rigs
    if w.get("recommended"):   # what the same layout gives without the waves
        heads.insert(1, "modal only")
        cols.insert(1, doc["recommended_modal_only"])
    names = list(rec["constants"])
    width = max(14, *(len(h) + 2 for h in heads))
    out.append("constant  " + "".join(f"{h:<{width}}" for h in heads) + "all fitted, data alone")
    for n in names:
        row = f"{n:<10}"
        for c in cols:
            cc = c["constants"].get(n)
            cell = "-" if cc is None else _pct(cc["std_rel"]) + ("" if cc["meets_target"] or not cc["wanted"] else " MISS")
            row += f"{cell:<{width}}"
        ident = doc["constants"][n]
        row += f"{_pct(ident['plan_std_rel'])}{'' if ident['identifiable'] else ' (not identifiable)'}"
        out.append(row)
    for n, u in doc.get("held", {}).items():
        ident = doc["constants"][n]
        lim = ident.get("limited_by") or {}
        out.append(f"{n:<10}held at nominal (prior {_pct(u)}): the data alone give {_pct(ident['plan_std_rel'])}"
                   + (f", correlation {lim['correlation']:+.2f} with {lim['constant']}" if lim else ""))
    out.append(f"worst wanted std: recommended {_pct(rec['worst_std_rel'])}, {rigs[0]['label']} "
               f"{_pct(rigs[0]['worst_std_rel'])} ({doc['improvement_worst_std']:.2f}x)")
    out.append("")
    out.append("recommended layout (m, origin at a corner, x along the length):")
    for i, a in enumerate(rec["accelerometers"], 1):
        out.append(f"  acc{i:<3} x = {a['x']:.4f}  y = {a['y']:.4f}")
    out.append(f"  hammer x = {rec['hammer']['x']:.4f}  y = {rec['hammer']['y']:.4f}")
    ms = rec["modes_seen"]
    out.append(f"  modes seen: {ms['nominal']} of {rec['modes_in_band']} at the nominal constants "
               f"({ms['min']}-{ms['max']} over the prior)")
    if doc["key_modes"]:
        out.append("  key modes: " + ", ".join(f"{k['mode'] + 1} {k['family']} {k['frequency_hz']:.0f} Hz"
                                              for k in doc["key_modes"]))
    out.append("")
    if w.get("recommended"):
        s = w["source"]
        out.append(f"guided waves: RECOMMENDED for {', '.join(w.get('needed_for') or doc['want'])}: "
                   f"{s['kind']} source at x = {s['x']:.4f}, y = {s['y']:.4f}; A0 over "
                   f"{w['band_hz'][0] / 1e3:.3g}-{w['band_hz'][1] / 1e3:.3g} kHz at {w['rate_hz'] / 1e6:g} MHz")
        for leg in w["legs"]:
            f = leg["points_hz"]
            out.append(f"  {leg['direction_deg']:g} deg: sensors at {leg['near_m']:.3f} and {leg['far_m']:.3f} m "
                       f"from the source ({len(f)} reflection-free points"
                       + (f", {f[0] / 1e3:.0f}-{f[-1] / 1e3:.0f} kHz, sigma "
                          f"{100 * max(leg['sigma_rel']):.2g} %" if f else "") + ")")
    elif w.get("needed_for"):
        out.append("guided waves: not recommended: " + w.get("reason", "modal data suffice"))
    else:
        out.append("guided waves: not needed (modal data reach the target)")
    out.append(f"identify with: {doc['identify']}")
    for n in doc.get("notes", []):
        out.append(f"note: {n}")
    return "\n".join(out) + "\n"


def _prior(prior: dict) -> str:
    vals = set(round(v, 6) for v in prior.values())
    if len(vals) == 1:
        return f"+-{100 * vals.pop():g} %"
    return ", ".join(f"{k} +-{100 * v:g} %" for k, v in prior.items())
