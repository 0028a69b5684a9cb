"""Where the gap lies: feature labels, groups of features, their chi^2, held-out folds.

Groups: modality, mode, mode family (from the predicted mode shapes),
frequency band, wave mode and direction. Two interleaved folds (alternate
modes by frequency, low/high wave bands) give the held-out gap.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Mapping

import numpy as np

from ..features import Features
from ..fit.chisq import chi2_sf
from ..forward import ForwardModel

__all__ = ["GroupStat", "feature_labels", "mode_families", "groups", "group_table", "folds", "held_out"]


@dataclass(frozen=True)
class GroupStat:
    """chi^2 of the whitened residuals of one group of features."""

    group: str
    n: int
    chi2: float
    share: float
    rms: float
    mean: float
    p_value: float
    significant: bool

    def to_dict(self) -> dict:
        return asdict(self)


def feature_labels(problem: Features) -> list[dict]:
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


def mode_families(fw: ForwardModel, params: Mapping[str, float]) -> list[str]:
    """Family of each measured mode from the predicted (paired) shape on a grid:
    'torsion' (w ~ xy twist), 'bending-x', 'bending-y' or 'plate(m,n)' with m, n
    the sign changes along the two centre lines."""
    mf = fw.modal_forward()
    modes, idx, _ = mf.solve(dict(params))
    p = fw.features
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


def groups(labels: list[dict], families: list[str] | None) -> dict[str, np.ndarray]:
    """Feature indices of every group (modality, mode, band, family, wave set, mode, direction)."""
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


def group_table(r: np.ndarray, groups: dict[str, np.ndarray], alpha: float) -> list[GroupStat]:
    """chi^2 of every group, largest excess over its size first; significant at ``alpha``."""
    total = float(r @ r)
    rows = []
    for k, idx in groups.items():
        rr = r[idx]
        c2 = float(rr @ rr)
        p = float(chi2_sf(c2, len(idx)))
        rows.append(GroupStat(group=k, n=int(len(idx)), chi2=c2,
                              share=c2 / total if total > 0 else 0.0,
                              rms=float(np.sqrt(np.mean(rr ** 2))),
                              mean=float(np.mean(rr)),
                              p_value=p, significant=bool(p < alpha)))
    rows.sort(key=lambda d: (-d.chi2 + d.n))
    return rows


def folds(labels: list[dict]) -> list[np.ndarray]:
    """Two interleaved folds: alternate modes (by frequency) and low/high wave bands."""
    a = np.zeros(len(labels), bool)
    modal = [i for i, lb in enumerate(labels) if lb["modality"] == "modal"]
    for k, i in enumerate(sorted(modal, key=lambda i: labels[i]["frequency_hz"])):
        a[i] = k % 2 == 0
    for i, lb in enumerate(labels):
        if lb["modality"] == "waves":
            a[i] = lb["band"] == "low"
    return [a, ~a]


def held_out(r: np.ndarray, J: np.ndarray, w: np.ndarray, dtheta_prior: np.ndarray,
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
