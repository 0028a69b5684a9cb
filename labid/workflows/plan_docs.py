"""The plan's predictions laid out as plain data (``labid.workflows.plan``): per layout the
predicted stds and what limits each constant, the waves' legs, the key modes, what the held
constants cost the fit. Relative stds as fractions; positions in m.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from engine.design import DesignProblem, Layout, criterion, evaluate
from engine.design import waves as dwaves

__all__ = ["std_table", "layout_doc", "waves_doc", "held_misfit", "key_modes"]


def std_table(prob: DesignProblem, ev, target: float, want: Sequence[str]) -> dict:
    """Per fitted constant: rms (over draws) and worst std, type-A std, meets the target, and
    what limits it: the largest share of its variance (the data, type A, with the fitted
    constant it correlates with most; or one held input), with every share."""
    std = ev.std[:, 0, :]
    names = prob.names
    cov0 = ev.cov[0, 0]
    sd0 = np.sqrt(np.diag(cov0))
    corr = cov0 / np.outer(sd0, sd0)
    out = {}
    for k, n in enumerate(names):
        rms = float(np.sqrt(np.mean(std[:, k] ** 2)))
        var = {"data (type A)": float(np.mean(ev.type_a[:, 0, k] ** 2))}
        var.update({p: float(np.mean(v[:, 0, k])) for p, v in ev.parts.items()})
        total = sum(var.values()) or 1.0
        share = {p: v / total for p, v in sorted(var.items(), key=lambda t: -t[1]) if v / total >= 0.005}
        top = next(iter(share)) if share else "data (type A)"
        lim = {"source": top, "share": share.get(top, 1.0)}
        if top == "data (type A)" and len(names) > 1:
            c = np.abs(corr[k]).copy()
            c[k] = -1.0
            j = int(np.argmax(c))
            lim["correlated_with"] = {"constant": names[j], "correlation": float(corr[k, j])}
        out[n] = {"std_rel": rms, "std_rel_worst": float(std[:, k].max()),
                  "type_a_rel": float(np.sqrt(var["data (type A)"])),
                  "wanted": n in want, "meets_target": bool(rms <= target), "limited_by": lim, "shares": share}
    return out


def layout_doc(prob: DesignProblem, sensors, tap, masses, families: list[str], target: float,
               want: Sequence[str], kind: str) -> dict:
    """One layout's predictions: positions, criterion, worst wanted std, per-constant table, modes seen."""
    ev = evaluate(prob, [list(sensors)], [tap], masses)
    consts = std_table(prob, ev, target, want)
    seen = ev.seen[:, :, 0]
    f0 = prob.mset.freqs[0]
    in_band = np.isfinite(f0) & (prob.meas.excitation(np.nan_to_num(f0)) > 0)
    pts = prob.mset.points
    return {
        "accelerometers": [{"x": float(pts[s, 0]), "y": float(pts[s, 1]), "mass_kg": float(m)}
                           for s, m in zip(sensors, masses)],
        "hammer": {"x": float(pts[tap, 0]), "y": float(pts[tap, 1])},
        "criterion": float(criterion(ev, kind)[0]),
        "worst_std_rel": max(c["std_rel"] for n, c in consts.items() if n in want),
        "constants": consts,
        "modes_in_band": int(in_band.sum()),
        "modes_seen": {"nominal": int(seen[0].sum()), "min": int(seen.sum(axis=1).min()),
                       "max": int(seen.sum(axis=1).max())},
        "unseen_at_nominal": [{"mode": int(i), "frequency_hz": float(f0[i]), "family": families[i],
                               "response": float(ev.response[0, i, 0])}
                              for i in np.flatnonzero(in_band & ~seen[0])],
    }


def waves_doc(w, timing_s: float, floor_rel: float, recommended: bool) -> dict:
    """The waves' part of the plan document (``w``: the plan's waves, with ``plan`` and ``rate_hz``)."""
    legs = []
    for leg in w.plan.legs:
        (xn, yn), (xf, yf) = leg.positions(w.plan.source)
        sig = 1.0 / np.sqrt(dwaves.leg_weights(leg, timing_s, floor_rel)) if leg.freqs else []
        legs.append({"direction_deg": leg.direction_deg, "near_m": leg.near_m, "far_m": leg.far_m,
                     "near_xy": [xn, yn], "far_xy": [xf, yf], "points_hz": list(leg.freqs),
                     "cg_m_s": list(leg.cg), "sigma_rel": [float(v) for v in sig]})
    return {"recommended": bool(recommended), "mode": "A0",
            "source": {"kind": "pencil", "x": w.plan.source[0], "y": w.plan.source[1]},
            "rate_hz": w.rate_hz, "band_hz": list(w.plan.band_hz), "legs": legs, "n_points": w.plan.n_points}


def held_misfit(prob: DesignProblem, best: Layout, masses) -> dict:
    """Per held constant (nominal draw): the chi^2 per degree of freedom its prior std adds to
    the fit, E ||P W^1/2 J_x u_x||^2 / (n - p), P the projection off the fitted constants'
    columns (what they cannot absorb). Well above 1, the fit will be inconsistent."""
    ev = evaluate(prob, [list(best.sensors)], [best.tap], masses)
    seen = ev.seen[0, :, 0]
    n, p = int(seen.sum()), len(prob.fit)
    if n <= p:
        return {}
    r = np.maximum(ev.response[0, seen, 0], 1e-12)
    var = prob.meas.sigma_rel ** 2 * (1.0 + (prob.meas.v_ref / r) ** 2)
    if prob.model_error is not None:
        var = var + prob.model_error[seen] ** 2
    A = prob.mset.jac[0][seen][:, list(prob.fit)] / np.sqrt(var)[:, None]
    Q, _ = np.linalg.qr(A)
    out = {}
    for i, u in zip(prob.fixed, prob.fixed_u):
        x = prob.mset.jac[0][seen, i] * u / np.sqrt(var)
        res = x - Q @ (Q.T @ x)
        out[prob.mset.names[i]] = float(res @ res / (n - p))
    return out


def key_modes(prob: DesignProblem, best: Layout, masses, n: int = 3) -> list[int]:
    """The seen modes (nominal draw) of largest leverage w_i J_i^T C J_i on the fitted constants."""
    ev = evaluate(prob, [list(best.sensors)], [best.tap], masses)
    r = np.maximum(ev.response[0, :, 0], 1e-12)
    w = ev.seen[0, :, 0] / (prob.meas.sigma_rel ** 2 * (1.0 + (prob.meas.v_ref / r) ** 2))
    J = prob.mset.jac[0][:, list(prob.fit)]
    lev = w * np.einsum("mp,pq,mq->m", J, ev.cov[0, 0], J)
    return [int(i) for i in np.argsort(lev)[::-1][:n] if lev[i] > 0]
