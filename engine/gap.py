"""Sim-to-real gap diagnosis: is there a gap, where, which unmodelled effect, how far it shrinks.

Procedure (``diagnose``), on features whitened by their sigmas (plus a small
model-discretisation allowance, ``GapOptions.model_rel_sigma``):

1. Best fit of the constants (``engine.fit.estimate``, log-parameters,
   Gaussian prior ``prior_rel_std`` about the nominal values); chi^2 of the
   whitened residuals against the chi^2 law on the degrees of freedom left
   (n minus the trace of the hat matrix): a gap is declared when the p-value
   is below ``alpha`` (the false-alarm rate on clean data).
2. Where: chi^2 split by modality, mode, mode family (from the predicted mode
   shapes), frequency band, wave mode and direction.
3. Which: every candidate effect (``engine.gap_forward.EFFECTS``) gives a
   whitened signature s (secant at its typical magnitude). Projected on the
   orthogonal complement of the constants' whitened Jacobian (prior rows
   included), s_perp is what the constants cannot absorb; |s_perp| * range
   below ``detect_sigma`` means *undetectable*, reported with the bias
   the absorbed effect puts into the constants (per unit magnitude). The
   ``top_k`` best linear candidates are refitted jointly with the constants
   (Levenberg-Marquardt on the nonlinear residuals from the nominal constants,
   constants' Jacobian frozen at nominal, effect column by secant), ranked by
   chi^2 (equal parameter count, so by BIC too), and checked on held-out
   data (two interleaved folds of modes and of wave bands, linearised about
   the fit).
4. Verdict: ``none`` without a significant gap; the best effect when it
   passes the chi^2 test (p > ``accept_alpha``), beats "no effect" by BIC and
   shrinks the held-out gap; otherwise ``unattributed``. Effects whose chi^2
   is within ``confusable_dchi2`` of the best form the confusable set.

Gap figures are rms whitened residuals (1 = noise level).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy import stats

from .gap_forward import EFFECTS, ForwardModel, GapError, GapProblem
from .fit import DataBlock, Prior, estimate, whitened_jacobian

__all__ = ["GapOptions", "diagnose", "gap_test", "feature_labels", "GapError"]


@dataclass(frozen=True)
class GapOptions:
    """Tuning of the diagnosis (see module docstring)."""

    alpha: float = 0.01
    accept_alpha: float = 0.001
    prior_rel_std: float = 0.3
    model_rel_sigma: tuple[float, float] = (1.5e-4, 2e-4)   # (modal, waves) relative
    detect_sigma: float = 3.0
    top_k: int = 4
    confusable_dchi2: float = 4.0
    candidates: tuple[str, ...] = tuple(EFFECTS)
    gn_iter: int = 15


# ---------------------------------------------------------------- helpers --
def _reference(name: str, problem: GapProblem) -> float:
    """Effect value meaning 'absent' (the nominal sensor length for the aperture)."""
    return float(problem.rig.sensor_length_m) if name == "sensor_aperture" else 0.0


def feature_labels(problem: GapProblem) -> list[dict]:
    """One dict per feature: modality, index, frequency, set label, band."""
    out = []
    if problem.modal is not None:
        f = np.asarray(problem.modal.frequency_hz, float)
        order = np.argsort(np.argsort(f))
        n = len(f)
        for i, fi in enumerate(f):
            band = ("low", "mid", "high")[min(2, int(3 * order[i] / max(n, 1)))]
            out.append({"modality": "modal", "set": "modal", "index": i, "frequency_hz": float(fi),
                        "band": band, "label": f"mode {i + 1} ({fi:.1f} Hz)"})
    for w in problem.waves:
        f = np.asarray(w.frequency_hz, float)
        med = np.median(f)
        for i, fi in enumerate(f):
            out.append({"modality": "waves", "set": w.label, "index": i, "frequency_hz": float(fi),
                        "band": "low" if fi <= med else "high",
                        "label": f"{w.label} {fi / 1e3:.0f} kHz"})
    return out


def _mode_families(fw: ForwardModel, params: Mapping[str, float]) -> list[str]:
    """Family of each measured mode from the predicted (paired) shape on a grid:
    'torsion' (w ~ xy twist), 'bending-x', 'bending-y' or 'plate(m,n)' with m, n
    the sign changes along the two centre lines."""
    mf = fw.modal_forward()
    modes, idx = mf.solve(dict(params))
    p = fw.problem
    n = 21
    xs, ys = np.linspace(0, p.length, n), np.linspace(0, p.width, n)
    X, Y = np.meshgrid(xs, ys)
    W = fw.base.shapes_at(modes, np.column_stack([X.ravel(), Y.ravel()]))[idx].reshape(len(idx), n, n)
    twist = ((X - p.length / 2) * (Y - p.width / 2)).ravel()
    out = []
    for w in W:
        wf = w.ravel()
        c = abs(wf @ twist) / (np.linalg.norm(wf) * np.linalg.norm(twist) + 1e-300)
        cx = w[n // 2, :]   # along x at mid y
        cy = w[:, n // 2]   # along y at mid x
        tol = 0.05 * np.max(np.abs(w))

        def changes(v):
            s = np.sign(v[np.abs(v) > tol])
            return int(np.sum(s[1:] != s[:-1]))
        mx, my = changes(cx), changes(cy)
        if c > 0.75:
            out.append("torsion")
        elif mx >= 1 and my == 0 and np.min(np.abs(cy)) > tol:
            out.append("bending-x")
        elif my >= 1 and mx == 0 and np.min(np.abs(cx)) > tol:
            out.append("bending-y")
        else:
            out.append(f"plate({mx},{my})")
    return out


def _groups(labels: list[dict], families: list[str] | None) -> dict[str, np.ndarray]:
    g: dict[str, list[int]] = {}
    for i, lb in enumerate(labels):
        keys = [lb["modality"]]
        if lb["modality"] == "modal":
            keys += [f"modal:{lb['label']}", f"modal:band:{lb['band']}"]
            if families is not None:
                keys.append(f"modal:family:{families[lb['index']]}")
        else:
            keys += [f"waves:{lb['set']}", f"waves:{lb['set']}:band:{lb['band']}",
                     f"waves:mode:{lb['set'].split('@')[0]}",
                     f"waves:direction:{lb['set'].split('@')[1]}"]
        for k in keys:
            g.setdefault(k, []).append(i)
    return {k: np.array(v) for k, v in g.items()}


def _group_table(r: np.ndarray, groups: dict[str, np.ndarray], alpha: float) -> list[dict]:
    total = float(r @ r)
    rows = []
    for k, idx in groups.items():
        rr = r[idx]
        c2 = float(rr @ rr)
        rows.append({"group": k, "n": int(len(idx)), "chi2": c2,
                     "share": c2 / total if total > 0 else 0.0,
                     "rms": float(np.sqrt(np.mean(rr ** 2))),
                     "mean": float(np.mean(rr)),
                     "p_value": float(stats.chi2.sf(c2, len(idx))),
                     "significant": bool(stats.chi2.sf(c2, len(idx)) < alpha)})
    rows.sort(key=lambda d: (-d["chi2"] + d["n"]))
    return rows


def _folds(labels: list[dict]) -> list[np.ndarray]:
    """Two interleaved folds: alternate modes (by frequency) and low/high wave bands."""
    a = np.zeros(len(labels), bool)
    modal = [i for i, lb in enumerate(labels) if lb["modality"] == "modal"]
    for k, i in enumerate(sorted(modal, key=lambda i: labels[i]["frequency_hz"])):
        a[i] = k % 2 == 0
    for i, lb in enumerate(labels):
        if lb["modality"] == "waves":
            a[i] = lb["band"] == "low"
    return [a, ~a]


def _held_out(r: np.ndarray, J: np.ndarray, w: np.ndarray, dtheta_prior: np.ndarray,
              folds: list[np.ndarray]) -> float:
    """rms of held-out whitened residuals, each fold refitted (linearised) on the rest.

    r: whitened residual at the full fit; J: its Jacobian (columns = unknowns,
    the first len(w) being constants with prior sqrt-weights w about
    ``dtheta_prior`` = theta - theta_prior)."""
    held = []
    k = J.shape[1]
    wp = np.zeros(k)
    wp[:len(w)] = w
    rp = np.zeros(k)
    rp[:len(w)] = w * dtheta_prior
    for hold in folds:
        fit = ~hold
        if not hold.any() or not fit.any():
            continue
        A = np.vstack([J[fit], np.diag(wp)])
        b = np.concatenate([r[fit], rp])
        d = -np.linalg.lstsq(A, b, rcond=1e-12)[0]
        held.append(r[hold] + J[hold] @ d)
    if not held:
        return float("nan")
    h = np.concatenate(held)
    return float(np.sqrt(np.mean(h ** 2)))


def gap_test(r: np.ndarray, J: np.ndarray, w: np.ndarray, alpha: float) -> dict:
    """Chi^2 test of whitened residuals r of a (prior-regularised) least-squares fit.

    J: whitened Jacobian (n, k) at the fit; w: prior sqrt-precisions (k,).
    Degrees of freedom n - trace(H), H = J (J'J + diag(w^2))^-1 J'; a gap is
    significant when P(chi^2_dof >= r'r) < alpha (the false-alarm rate).
    """
    r = np.asarray(r, float)
    n = len(r)
    A = J.T @ J + np.diag(np.asarray(w, float) ** 2)
    dof = max(n - float(np.trace(J @ np.linalg.solve(A, J.T))), 1.0)
    chi = float(r @ r)
    p = float(stats.chi2.sf(chi, dof))
    return {"chi2": chi, "dof": dof, "p_value": p, "threshold": float(stats.chi2.isf(alpha, dof)),
            "significant": bool(p < alpha)}


# ---------------------------------------------------------------- diagnosis --
class _Fit:
    """Whitened residual machinery around one forward model."""

    def __init__(self, problem: GapProblem, fw: ForwardModel, opts: GapOptions):
        self.problem, self.fw, self.opts = problem, fw, opts
        y = fw.observed
        sig = fw.sigma
        nm = fw.n_modal
        rel = np.concatenate([np.full(nm, opts.model_rel_sigma[0]),
                              np.full(len(y) - nm, opts.model_rel_sigma[1])])
        self.y, self.sigma = y, np.sqrt(sig ** 2 + (rel * y) ** 2)
        self.names = problem.param_names()
        self.nominal = problem.nominal()

    def residual(self, params, effects) -> np.ndarray:
        r = (self.fw.predict(params, effects) - self.y) / self.sigma
        if not np.all(np.isfinite(r)):
            raise GapError("model undefined (a wave mode absent) for these constants/effects")
        return r

    def jacobian(self, params: Mapping[str, float], effects: Mapping[str, float],
                 fd_step: float = 1e-5) -> np.ndarray:
        """Whitened d residual / d log p: analytic modal rows, forward differences for waves."""
        from .gap_forward import F_REF, temperature_params
        fw, nm, names = self.fw, self.fw.n_modal, self.names
        parts = []
        if nm:
            pT = temperature_params(params, effects.get("temperature", 0.0))
            mf = fw.modal_forward(effects.get("sensor_mass", 0.0), effects.get("support_stiffness", 0.0),
                                  effects.get("thickness", 0.0))
            f0, dfdp = mf.jacobian(pT, list(names))
            Jm = dfdp * np.array([pT[n] for n in names])[None, :]
            eta = effects.get("viscoelastic", 0.0)
            if eta:
                g = 1.0 / (1.0 - eta / np.pi)
                fo = F_REF * (f0 / F_REF) ** g
                Jm = Jm * (g * fo / f0)[:, None]
            parts.append(Jm / self.sigma[:nm, None])
        if len(self.y) > nm:
            base = np.concatenate(fw.predict_waves(params, effects))
            cols = []
            for n_ in names:
                p2 = dict(params)
                p2[n_] = params[n_] * math.exp(fd_step)
                cols.append((np.concatenate(fw.predict_waves(p2, effects)) - base) / fd_step)
            Jw = np.column_stack(cols) / self.sigma[nm:, None]
            parts.append(np.where(np.isfinite(Jw), Jw, 0.0))
        return np.vstack(parts)

    def blocks(self) -> list[DataBlock]:
        fw, nm = self.fw, self.fw.n_modal
        out = []
        if nm:
            def jac(p, names):
                f, J = fw.modal_forward().jacobian(dict(p), list(names))
                return f, J
            out.append(DataBlock("modal", self.y[:nm], self.sigma[:nm],
                                 lambda p: fw.predict_modal(p, {}), jac, kind="modal"))
        if len(self.y) > nm:
            def wpredict(p):
                y = np.concatenate(fw.predict_waves(p, {}))
                if not np.all(np.isfinite(y)):
                    raise GapError("group velocity undefined (mode absent) for these constants")
                return y

            def wjac(p, names):
                y = wpredict(p)
                cols = []
                for n_ in names:
                    p2 = dict(p)
                    p2[n_] = p[n_] * math.exp(1e-5)
                    try:
                        c_ = (np.concatenate(fw.predict_waves(p2, {})) - y) / (1e-5 * p[n_])
                    except ValueError:
                        c_ = np.zeros_like(y)
                    cols.append(np.where(np.isfinite(c_), c_, 0.0))
                return y, np.column_stack(cols)
            out.append(DataBlock("waves", self.y[nm:], self.sigma[nm:], wpredict, wjac, kind="waves"))
        return out


def _unpack(x, names):
    return {n: float(v) for n, v in zip(names, x)}


def diagnose(problem: GapProblem, options: GapOptions | None = None,
             forward: ForwardModel | None = None) -> dict:
    """Gap diagnosis of measured features against the nominal model (see module docstring).

    Returns a JSON-ready dict with CONTRACT section 3 keys (``gap``, ``where``,
    ``effects``, ``verdict``) and the details (groups, constants, residuals).
    """
    opts = options or GapOptions()
    unknown = set(opts.candidates) - set(EFFECTS)
    if unknown:
        raise GapError(f"candidates {sorted(unknown)}: expected names from {list(EFFECTS)}")
    fw = forward or ForwardModel(problem)
    F = _Fit(problem, fw, opts)
    names, nominal = F.names, F.nominal
    blocks = F.blocks()
    prior = Prior(mean=nominal, rel_std={n: opts.prior_rel_std for n in names})
    try:
        est = estimate(blocks, names, nominal, prior=prior, xtol=1e-4, dtol=1e-3, max_iter=30)
    except np.linalg.LinAlgError as exc:
        raise GapError(f"identification of the constants failed ({exc})") from None
    p_hat = est.params
    w = np.full(len(names), 1.0 / opts.prior_rel_std)
    theta_hat = np.log([p_hat[n] for n in names])
    theta_nom = np.log([nominal[n] for n in names])
    dtp = theta_hat - theta_nom
    jacs = whitened_jacobian(blocks, p_hat, names)
    J = np.vstack([jacs[b.name] for b in blocks])
    r0 = F.residual(p_hat, {})
    n = len(r0)
    k = len(names)
    test = gap_test(r0, J, w, opts.alpha)
    dof, chi0, p0 = test["dof"], test["chi2"], test["p_value"]
    threshold, significant = test["threshold"], test["significant"]

    labels = feature_labels(problem)
    families = None
    if problem.modal is not None:
        try:
            families = _mode_families(fw, p_hat)
        except Exception:  # noqa: BLE001 - families are descriptive only
            families = None
    groups = _groups(labels, families)
    table0 = _group_table(r0, groups, opts.alpha)
    folds = _folds(labels)
    ho0 = _held_out(r0, J, w, dtp, folds)

    # augmented Jacobian for projections (prior rows)
    Ja = np.vstack([J, np.diag(w)])
    cand = []
    for name in opts.candidates:
        spec = EFFECTS[name]
        if not any((m == "modal" and problem.modal is not None) or (m == "waves" and problem.waves)
                   for m in spec.modalities):
            continue
        a_ref = _reference(name, problem)
        h = spec.typical
        try:
            s = (F.residual(p_hat, {name: a_ref + h}) - r0) / h
        except (ValueError, KeyError) as exc:
            cand.append({"name": name, "error": str(exc)})
            continue
        sa = np.concatenate([s, np.zeros(k)])
        c = np.linalg.lstsq(Ja, sa, rcond=1e-12)[0]
        sp = sa - Ja @ c
        ns, np_ = float(np.linalg.norm(s)), float(np.linalg.norm(sp))
        reach = max(abs(spec.lo - a_ref), abs(spec.hi - a_ref))
        detectable = np_ * reach >= opts.detect_sigma
        a_lin = float(-(sp[:n] @ r0) / np_ ** 2) if np_ > 0 else 0.0
        a_lin = float(np.clip(a_ref + a_lin, spec.lo, spec.hi) - a_ref)
        chi_lin = float(np.sum((r0 + a_lin * sp[:n]) ** 2))
        cand.append({
            "name": name, "unit": spec.unit, "signature_norm": ns, "unabsorbed_norm": np_,
            "absorbed_fraction": 1.0 - (np_ / ns) ** 2 if ns > 0 else 1.0,
            "detectable": bool(detectable),
            "bias_in_constants_per_unit": {nm_: float(np.expm1(ci) if abs(ci) < 50 else ci)
                                           for nm_, ci in zip(names, c)},
            "_c": c, "_s": s, "magnitude_linear": a_ref + a_lin, "chi2_linear": chi_lin,
        })

    # joint refits of the top candidates
    ranked = sorted([c for c in cand if "error" not in c and c["detectable"]],
                    key=lambda c: c["chi2_linear"])
    if ranked:
        Jnom = F.jacobian(nominal, {})
        for c in ranked[:opts.top_k]:
            _refit(c, F, problem, Jnom, w, theta_nom, folds)

    refit = [c for c in cand if "chi2" in c]
    refit.sort(key=lambda c: c["chi2"])
    best = refit[0] if refit else None
    lnn = math.log(n)
    verdict = "none"
    confusable: list[str] = []
    if significant:
        verdict = "unattributed"
        if best is not None:
            p_best = float(stats.chi2.sf(best["chi2"], max(dof - 1, 1)))
            better = chi0 - best["chi2"] > lnn
            held_ok = not (best["held_out_after"] > ho0)
            best["p_value"] = p_best
            if p_best > opts.accept_alpha and better and held_ok:
                verdict = best["name"]
                confusable = [c["name"] for c in refit[1:]
                              if c["chi2"] - best["chi2"] < opts.confusable_dchi2]
    # scores: relative evidence (BIC weights, equal dimension) over refitted + linear
    chi_all = {c["name"]: c.get("chi2", c.get("chi2_linear")) for c in cand if "error" not in c}
    ref = min(list(chi_all.values()) + [chi0 + lnn])
    wts = {k_: math.exp(-0.5 * (v - ref)) for k_, v in chi_all.items()}
    wsum = sum(wts.values()) + math.exp(-0.5 * (chi0 + lnn - ref))
    effects = []
    for c in sorted([c for c in cand if "error" not in c],
                    key=lambda c: (c.get("chi2", math.inf), c["chi2_linear"])):
        mag = c.get("magnitude", c["magnitude_linear"])
        chi_e = chi_all[c["name"]]
        effects.append({
            "name": c["name"], "magnitude": float(mag), "std": c.get("std"), "unit": c["unit"],
            "gap_after": float(math.sqrt(chi_e / n)), "score": float(wts[c["name"]] / wsum),
            "delta_chi2": float(chi0 - chi_e), "refitted": "chi2" in c,
            "held_out_after": c.get("held_out_after"), "detectable": c["detectable"],
            "absorbed_fraction": float(c["absorbed_fraction"]),
            "bias_in_constants_per_unit": c["bias_in_constants_per_unit"],
            "constants_after": c.get("constants"), "iterations": c.get("iterations"),
        })
    chosen = next((c for c in refit if c["name"] == verdict), None)
    after_r = chosen["_r"] if chosen is not None else r0
    gap = {
        "before": float(math.sqrt(chi0 / n)),
        "after": float(math.sqrt(float(after_r @ after_r) / n)),
        "held_out_before": ho0,
        "held_out_after": chosen["held_out_after"] if chosen is not None else ho0,
        "chi2_before": chi0, "chi2_after": float(after_r @ after_r),
        "dof": float(dof), "n": n, "p_value_before": p0,
        "p_value_after": chosen.get("p_value") if chosen is not None else p0,
        "threshold_chi2": threshold, "false_alarm_rate": opts.alpha, "significant": bool(significant),
        "unit": "rms of residual/sigma (1 = noise level)",
    }
    where = [g for g in table0 if g["significant"]] if significant else []
    out = {
        "gap": gap,
        "where": [g["group"] for g in where],
        "where_detail": where,
        "effects": effects,
        "verdict": verdict,
        "confusable": ([verdict] + confusable) if confusable else [],
        "undetectable": [{"name": c["name"], "absorbed_fraction": float(c["absorbed_fraction"]),
                          "unit": c["unit"],
                          "bias_in_constants_per_unit": c["bias_in_constants_per_unit"]}
                         for c in cand if "error" not in c and not c["detectable"]],
        "errors": {c["name"]: c["error"] for c in cand if "error" in c},
        "groups": table0,
        "constants": {"before": p_hat,
                      "before_std": {n_: float(s_) for n_, s_ in zip(names, est.std)},
                      "after": chosen["constants"] if chosen is not None else p_hat,
                      "relative_change": ({n_: chosen["constants"][n_] / p_hat[n_] - 1.0 for n_ in names}
                                          if chosen is not None else {n_: 0.0 for n_ in names})},
        "features": {"labels": [lb["label"] for lb in labels],
                     "modality": [lb["modality"] for lb in labels],
                     "set": [lb["set"] for lb in labels],
                     "residual_before": r0.tolist(), "residual_after": after_r.tolist(),
                     "sigma": F.sigma.tolist(),
                     "mode_families": families},
        "identification": {"converged": bool(est.converged), "message": est.message},
    }
    return out


def _refit(c: dict, F: _Fit, problem: GapProblem, Jnom: np.ndarray, w: np.ndarray,
           theta_nom: np.ndarray, folds) -> None:
    """Joint fit of the constants and one effect; fills c.

    Levenberg-Marquardt on the nonlinear whitened residuals, from the nominal
    constants and the linear estimate of the effect, with the constants'
    Jacobian frozen at the nominal point (``Jnom``; the true constants lie
    within tens of per cent of nominal) and the effect's column re-evaluated
    by a secant at every iterate. Covariance from the final Gauss-Newton matrix.
    """
    name = c["name"]
    spec = EFFECTS[name]
    names = F.names
    k = len(names)
    h = 0.1 * spec.typical
    a = float(np.clip(c["magnitude_linear"], spec.lo, spec.hi))
    theta = theta_nom.copy()

    def resid(th, a_):
        return F.residual(_unpack(np.exp(th), names), {name: a_})

    def col(th, a_, r_):
        step = h if a_ + h <= spec.hi else -h
        return (resid(th, a_ + step) - r_) / step

    try:
        r = resid(theta, a)
        s = col(theta, a, r)
    except ValueError as exc:
        c.update({"error": f"refit failed: {exc}"})
        return
    cost = float(r @ r)
    mu = 1e-3
    it = 0
    converged = False
    for it in range(1, F.opts.gn_iter + 1):
        A = np.vstack([np.column_stack([Jnom, s]), np.column_stack([np.diag(w), np.zeros(k)])])
        b = np.concatenate([r, w * (theta - theta_nom)])
        M, g = A.T @ A, A.T @ b
        D = np.diag(np.maximum(np.diag(M), 1e-12 * np.max(np.diag(M))))
        ok = False
        for _ in range(10):
            try:
                d = -np.linalg.solve(M + mu * D, g)
            except np.linalg.LinAlgError:
                mu *= 10
                continue
            th_new = theta + np.clip(d[:k], -0.5, 0.5)
            a_new = float(np.clip(a + d[k], spec.lo, spec.hi))
            try:
                r_new = resid(th_new, a_new)
            except ValueError:
                mu *= 10
                continue
            c_new = float(r_new @ r_new + np.sum((w * (th_new - theta_nom)) ** 2))
            if c_new < cost + float(np.sum((w * (theta - theta_nom)) ** 2)) or c_new == 0:
                ok = True
                break
            mu *= 4
        if not ok:
            converged = True   # no decrease possible: at the minimum (to the frozen Jacobian)
            break
        gain = cost + float(np.sum((w * (theta - theta_nom)) ** 2)) - c_new
        theta, a, r = th_new, a_new, r_new
        cost = float(r @ r)
        mu = max(mu / 3, 1e-9)
        s = col(theta, a, r)
        if gain < 1e-3 * max(1.0, cost):
            converged = True
            break
    Jf = np.column_stack([Jnom, s])
    A = Jf.T @ Jf + np.diag(np.concatenate([w ** 2, [0.0]]))
    try:
        std = float(math.sqrt(max(np.linalg.inv(A)[k, k], 0.0)))
    except np.linalg.LinAlgError:
        std = float("inf")
    c.update({
        "iterations": it, "converged": converged,
        "magnitude": float(a), "std": std, "chi2": float(r @ r), "_r": r,
        "constants": _unpack(np.exp(theta), names),
        "held_out_after": _held_out(r, Jf, w, theta - theta_nom, folds),
    })
