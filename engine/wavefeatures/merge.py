"""Curves measured with several wavelets (or several runs) merged into one per mode and direction.

A wavelet's length is a compromise: a long one resolves frequency (more independent points,
less bias), a short one resolves time (packets close to the direct one, an edge echo, the
other mode, stay apart). Where the echoes are is a matter of frequency (the group velocity
changes along the band), so one wavelet for the whole band is too long at the low end or too
short at the high end. Here, per frequency, the longest candidate wavelet whose picks pass
every check gives the point (``plan``, ``merge``), and independence is judged with each
point's own resolution (``independent_mask``). The same merge joins the curves of tone-burst
runs at different centre frequencies (``merge_runs``): each point keeps its own sigma.

Pure: arrays and ``engine.waves`` types in and out. Units: Hz, m/s.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from scipy import stats

from .. import waves

__all__ = ["by_length", "plan", "merge", "independent_mask", "merge_runs", "run_resolution", "off_curve", "left_out",
           "scattered", "odd_one", "names", "misfit_scale", "birge_chi2",
           "leave_one_out", "gross_points", "GROSS"]

SPACING = 2.0 * np.sqrt(2.0)      # independent points: this many frequency-stds apart (waves.independent_points)
LOO_SIGMAS, LOO_REL = 6.0, 0.20   # left_out: a point this many sigmas AND this far (relative) off the others' curve
GROSS_ALPHA = 0.01               # gross_points: a clean curve loses a point in < 1 % of draws
GROSS = "off the curve through the others"   # gross_points' reason in a curve's dropped counts


def by_length(cands: Sequence[waves.Wavelet]) -> list[waves.Wavelet]:
    """The wavelets from the longest (time std C sqrt(B) / 2f) to the shortest; ties keep order."""
    return sorted(cands, key=lambda w: -w.center * np.sqrt(w.bandwidth))


def plan(first: Mapping[waves.Wavelet, Mapping[str, waves.GroupVelocity]], max_wavelets: int = 3
         ) -> list[waves.Wavelet]:
    """The wavelets to measure with, longest first: per mode and frequency the longest
    candidate valid there on the first shot gets it; the ``max_wavelets`` that get the most
    frequencies (at least 3 each) are kept."""
    order = by_length(list(first))
    gain = {wl: 0 for wl in order}
    modes = {m for cur in first.values() for m in cur}
    for m in modes:
        taken = None
        for wl in order:
            g = first[wl].get(m)
            if g is None:
                continue
            new = g.valid if taken is None else (g.valid & ~taken)
            gain[wl] += int(new.sum())
            taken = g.valid.copy() if taken is None else (taken | g.valid)
    keep = [wl for wl in sorted(order, key=lambda w: -gain[w]) if gain[wl] >= 3][:max_wavelets]
    return [wl for wl in order if wl in keep] or order[:1]


def merge(curves: Mapping[waves.Wavelet, waves.GroupVelocity]) -> tuple[waves.GroupVelocity, list]:
    """One curve from several wavelets' curves on the same grid: per frequency the longest
    wavelet valid there. Returns the curve and the wavelet of each point (None: no point)."""
    order = by_length(list(curves))
    f = curves[order[0]].frequencies_hz
    v, s = np.full(f.size, np.nan), np.full(f.size, np.nan)
    valid = np.zeros(f.size, bool)
    which: list = [None] * f.size
    for wl in order:
        g = curves[wl]
        new = g.valid & ~valid
        v[new], s[new] = g.velocity_m_s[new], g.sigma_m_s[new]
        for i in np.flatnonzero(new):
            which[i] = wl
        valid |= new
    return waves.GroupVelocity(f, v, s, valid), which


def independent_mask(freqs_hz, valid, which: Sequence, spacing: float = SPACING) -> np.ndarray:
    """Valid frequencies nearly independent of their kept neighbour: greedy from the lowest,
    kept when at least ``spacing`` / 2 x (sum of the two points' wavelet frequency-stds) above
    the last kept one (with one wavelet: ``waves.independent_points``'s rule, taken at the
    upper point for both)."""
    f = np.asarray(freqs_hz, float)
    keep = np.zeros(f.size, bool)
    last = None
    for i in np.flatnonzero(np.asarray(valid, bool)):
        s_i = float(which[i].freq_std_hz(f[i]))
        # the std of the lower point's wavelet taken at the upper frequency (conservative)
        if last is None or f[i] - f[last] >= 0.5 * spacing * (s_i + float(which[last].freq_std_hz(f[i]))):
            keep[i] = True
            last = i
    return keep


def run_resolution(freqs_hz) -> float | None:
    """A run's frequency resolution, relative: the smallest gap between its consecutive
    independent points over the upper one's frequency (``independent_mask`` kept each point
    the first one past its wavelets' independence spacing, so the smallest gap is that
    spacing to within one grid step: 6-11 % for cmor2-5..cmor2-3, 32 % for cmor2-1).
    None with fewer than 2 points."""
    f = np.sort(np.asarray(freqs_hz, float))
    f = f[np.isfinite(f) & (f > 0)]
    if f.size < 2:
        return None
    return float(np.min(np.diff(f) / f[1:]))


def merge_runs(curves: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], rel_tol: float = 0.01,
               runs_out: list | None = None, dropped_out: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One dispersion curve from the independent points of several runs (e.g. tone bursts at
    different centre frequencies): ``curves`` are (frequency, velocity, sigma) arrays.

    Points of different runs closer than the runs' own independence spacing
    (``run_resolution``: the smaller of the two runs'; not below ``rel_tol``; a run with one
    point takes the median of the others') measure the group delay over nearly the same band:
    they are one point, not two (issue 24, session 27: two bursts' points 1.3-4 % apart
    counted twice while a run's own points lie 7-16 % apart). They are combined: inverse-
    variance mean of velocity and frequency (exact to first order on a smooth curve), sigma
    the larger of the propagated one and half their spread about the local slope of the smooth
    curve through all points (two runs that disagree say so; the curve's own dispersion
    between their frequencies is not a disagreement). Points off the smooth curve through the
    others (``off_curve``) are left out. Returns (frequency, velocity, sigma, number of runs
    combined in each point), by frequency; ``runs_out``, when given, receives each returned
    point's run indices (a list per point); ``dropped_out``, when given, counts the points left
    out under "off the smooth curve"."""
    pts = sorted((float(f), float(v), float(s), r) for r, (F, V, S) in enumerate(curves)
                 for f, v, s in zip(F, V, S) if np.isfinite(v) and np.isfinite(s) and s > 0)
    if not pts:
        e = np.array([])
        return e, e, e, np.array([], int)
    res = [run_resolution([p[0] for p in pts if p[3] == r]) for r in range(len(curves))]
    known = [x for x in res if x is not None]
    res = [x if x is not None else (float(np.median(known)) if known else rel_tol) for x in res]
    P = np.array([p[:3] for p in pts])
    slope = _slope(P[:, 0], P[:, 1], P[:, 2])
    out_f, out_v, out_s, out_n, out_r = [], [], [], [], []
    i = 0
    while i < len(pts):
        grp, runs = [pts[i]], {pts[i][3]}
        j = i + 1
        while j < len(pts) and pts[j][3] not in runs and \
                pts[j][0] - grp[-1][0] < max(rel_tol, min(res[pts[j][3]], res[grp[-1][3]])) * pts[j][0]:
            grp.append(pts[j])
            runs.add(pts[j][3])
            j += 1
        ff = np.array([p[0] for p in grp])
        vv = np.array([p[1] for p in grp])
        w = np.array([1.0 / p[2] ** 2 for p in grp])
        fm = float(np.sum(w * ff) / np.sum(w)) if len(grp) > 1 else float(ff[0])
        v = float(np.sum(w * vv) / np.sum(w)) if len(grp) > 1 else float(vv[0])
        s = float(1.0 / np.sqrt(np.sum(w))) if len(grp) > 1 else grp[0][2]
        if len(grp) > 1:
            r = vv - slope(fm) * (ff - fm)
            s = max(s, 0.5 * float(r.max() - r.min()))
        out_f.append(fm)
        out_v.append(v)
        out_s.append(s)
        out_n.append(len(grp))
        out_r.append(sorted(runs))
        i = j
    F, V, S, N = np.array(out_f), np.array(out_v), np.array(out_s), np.array(out_n, int)
    bad = off_curve(F, V, S)
    if dropped_out is not None and bad.any():
        dropped_out["off the smooth curve"] = dropped_out.get("off the smooth curve", 0) + int(bad.sum())
    if runs_out is not None:
        runs_out.extend(r for r, b in zip(out_r, bad) if not b)
    return F[~bad], V[~bad], S[~bad], N[~bad]


def _slope(f_hz, v, sigma, degree: int = 3):
    """dv/df (m/s per Hz) of the smooth curve through the points (a polynomial in ln f,
    weights 1/sigma, degree at most ``degree`` and 2 below the point count); 0 with fewer than
    4 distinct frequencies."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    if np.unique(f).size < 4:
        return lambda x: 0.0
    x0 = float(f.max())
    c = np.polynomial.polynomial.polyfit(np.log(f / x0), v, min(degree, np.unique(f).size - 2),
                                         w=1.0 / np.maximum(s, 1e-3 * np.abs(v)))
    dc = np.polynomial.polynomial.polyder(c)
    return lambda x: float(np.polynomial.polynomial.polyval(np.log(x / x0), dc)) / x


def off_curve(f_hz, v, sigma, degree: int = 3, k: float = 4.0, floor: float = 1e-3) -> np.ndarray:
    """Mask of points inconsistent with the smooth curve through the others: a group-velocity
    curve below the first cut-off is smooth in ln f, so a polynomial of ``degree`` in ln f is
    fitted (weights 1/sigma, iteratively leaving out the worst point) and a point farther
    than ``k`` x the robust scatter of the residuals (not below ``floor`` x the median velocity)
    is flagged (a pick on the wrong lobe of a packet split by a spectral notch, on a residual
    echo, or on another ridge where one wavelet of the merge locked). A point's own sigma does
    not excuse it: the bench's wrong-ridge points (bench/RESULTS.md, issue 24, session 24) came
    with sigmas of 0.6-3.9 %, 1-4 sigma from the truth, while the curve through the others
    scatters by 0.05-0.3 %. Fewer than degree + 4 points: only ``left_out``'s check (4 points on)."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    bad = np.zeros(f.size, bool)
    if f.size < degree + 4:
        bad[:] = left_out(f, v, s)
        return bad
    x = np.log(f / f.max())
    tol = floor * float(np.median(np.abs(v)))
    for _ in range(f.size // 4 + 1):
        keep = ~bad
        w = 1.0 / np.maximum(s[keep], 1e-3 * np.abs(v[keep]))
        c = np.polynomial.polynomial.polyfit(x[keep], v[keep], degree, w=w)
        res = v - np.polynomial.polynomial.polyval(x, c)
        mad = 1.4826 * float(np.median(np.abs(res[keep])))
        z = np.abs(res) / (k * max(mad, tol))
        z[bad] = 0.0
        j = int(np.argmax(z))
        if z[j] <= 1.0 or keep.sum() <= degree + 3:
            break
        bad[j] = True
    bad[~bad] = left_out(f[~bad], v[~bad], s[~bad])
    return bad


def left_out(f_hz, v, sigma, k: float = LOO_SIGMAS, rel: float = LOO_REL) -> np.ndarray:
    """Mask of points far off the smooth curve through all the others (a safety net for any
    curve of 4 points or more, its end points included, which ``off_curve``'s fit through them
    cannot judge): each point in turn is left out and compared with the curve through the others
    (``leave_one_out``); the point is off when its residual exceeds ``k`` x its combined
    uncertainty AND ``rel`` x the velocity. The worst such point goes, then the check is repeated
    on the rest while 4 remain. ``rel`` = 20 % (``LOO_REL``): A0's sqrt(f) rise extrapolated one
    point beyond a quadratic in ln f, or S0's knee, miss by < 2 % on an independent-point grid;
    the gross mislabels seen are 20-60 % (issue 24, session 28: a far-edge echo taken for S0, 58 %
    slow with a 0.7 % sigma, at a merged sweep's low end). ``gross_points`` is the same test
    without ``rel``, on its own sigmas, for one point (or a small fraction) of a curve."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    bad = np.zeros(f.size, bool)
    while (~bad).sum() >= 4:
        idx = np.flatnonzero(~bad)
        r, u = leave_one_out(f[idx], v[idx], s[idx])
        sc = np.minimum(np.abs(r) / (k * u), np.abs(r) / (rel * np.abs(v[idx])))
        j = int(np.argmax(sc))
        if sc[j] <= 1.0:
            break
        bad[idx[j]] = True
    return bad


def leave_one_out(f_hz, v, sigma, octaves: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(residual, combined uncertainty) of each point against the smooth curve through the others
    (m/s): a polynomial in ln f of degree min(2, others - 2), weights 1 / max(sigma, 0.1 % of v),
    through the others (all of them, or with ``octaves`` those within that many octaves of the
    point, at least its 4 nearest), evaluated at the point. The uncertainty is
    sqrt(its sigma^2 + the prediction's variance from the others' sigmas + the others' rms
    residual^2 + the truncation error^2): the first two make residual / uncertainty a standard
    normal deviate when the sigmas are right and the polynomial holds; the third (the others'
    actual scatter about their curve, dof-corrected) keeps a point whose own sigma understates the
    curve's scatter (a 2-shot sigma, a bias along the curve) from looking gross; the fourth, the
    prediction's change from one degree lower (the last term's size at the point), covers the
    polynomial not being the curve where it extrapolates (an end point): without it the TRUE
    plate's curve, at the preamp sweep's frequencies and 0.002-0.02 % sigmas, lay up to 4.0 x
    this uncertainty off at a burst's top end (A0 90 deg 294 kHz, +0.03 %); with it at most 1.1
    over 187 burst and merged curves (bench/RESULTS.md, issue 24, session 30, branch h66). At
    least 4 points."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    x = np.log(f / f.max())
    w2 = 1.0 / np.maximum(s, 1e-3 * np.abs(v)) ** 2
    r, u = np.zeros(f.size), np.zeros(f.size)
    for j in range(f.size):
        o = np.arange(f.size) != j
        if octaves is not None:
            d = np.where(o, np.abs(x - x[j]), np.inf)
            o = d <= max(octaves * np.log(2.0), float(np.sort(d)[min(3, d.size - 2)]))
        deg = min(2, int(o.sum()) - 2)
        A = np.vander(x[o] - x[j], deg + 1, increasing=True)   # about the point: its value is the 0th coefficient
        H = np.linalg.solve(A.T @ (A * w2[o][:, None]), A.T * w2[o])   # weighted least squares, coefficients
        c = H[0]                                               # the prediction's weights on the others
        res = v[o] - A @ (H @ v[o])
        r[j] = v[j] - float(c @ v[o])
        rms2 = float(np.sum(res ** 2)) / max(int(o.sum()) - deg - 1, 1)
        B = A[:, :deg]
        trunc = float((c - np.linalg.solve(B.T @ (B * w2[o][:, None]), B.T * w2[o])[0]) @ v[o]) if deg else 0.0
        u[j] = np.sqrt(s[j] ** 2 + float(np.sum((c * s[o]) ** 2)) + rms2 + trunc ** 2)
    return r, u


def gross_points(f_hz, v, sigma, label: str = "the curve", alpha: float = GROSS_ALPHA, octaves: float = 0.5,
                 most: float = 0.25, min_points: int = 5, dropped_out: dict | None = None
                 ) -> tuple[np.ndarray, str]:
    """(mask, console note) of the one gross point (or the few: at most max(1, int(``most`` x n))) of a
    curve of n >= ``min_points`` points: a point whose residual from the smooth curve through the
    others within ``octaves`` of it exceeds k x its combined uncertainty (``leave_one_out``), k the
    two-sided normal quantile of ``alpha`` / n (Bonferroni: a clean curve whose sigmas are right
    loses a point in < ``alpha`` of draws; 3.1 for 5 points, 3.5 for 25). The worst goes, then the
    rest is judged again with the same k. When more points than the limit are off, the curve is
    biased rather than one point wrong: nothing is dropped (``misfit_scale`` scales its sigmas).
    ``most`` = 1/4: two of a burst's 8 A0 90 deg points were gross in the preamp sweep (+0.79 % and
    -2.16 % at 0.014 % and 0.002 % sigmas, file +40 %, seeds 1 and 2). ``octaves`` = 1/2 (each
    side): the truncation term grows with the window, so over a merged A0 curve (47-306 kHz) an
    octave each side left 0.9-1.1 % (median) of uncertainty, half an octave 0.34 %; the same
    gross points went and no fine one (bench/RESULTS.md, issue 24, session 30, branch h66).
    Why: one gross point (a burst's A0 90 deg point at -2.2 % with a 0.02 % sigma, issue 24,
    session 29) made the whole curve's Birge ratio 26, so every good point lost its weight in the
    sweep's merge while the bad one stayed. Tighter than ``left_out`` (no 20 % floor) for one
    point; ``left_out`` still takes any number of gross mislabels. ``dropped_out``, when given,
    counts the points dropped under ``GROSS``. Units: any, consistent."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    bad = np.zeros(f.size, bool)
    if f.size < min_points:
        return bad, ""
    k = float(stats.norm.isf(alpha / (2 * f.size)))
    cap = max(1, int(most * f.size))
    while True:
        idx = np.flatnonzero(~bad)
        r, u = leave_one_out(f[idx], v[idx], s[idx], octaves)
        j = int(np.argmax(np.abs(r) / u))
        if abs(r[j]) <= k * u[j]:
            break
        if bad.sum() >= cap:                  # more off than one point's worth: a biased curve
            return np.zeros(f.size, bool), ""
        bad[idx[j]] = True
    if not bad.any():
        return bad, ""
    if dropped_out is not None:
        dropped_out[GROSS] = dropped_out.get(GROSS, 0) + int(bad.sum())
    return bad, (f"{label}: " + ", ".join(f"{fi / 1e3:.4g} kHz" for fi in f[bad]) + f" dropped, {GROSS} "
                 f"(more than {k:.2g} x its uncertainty: its sigma, the others' curve and scatter)")


def scattered(f_hz, v, sigma, limit: float = 0.01) -> str:
    """Why a curve's points cannot stand together ('' when they can): below the first cut-off a
    group-velocity curve is smooth, so points that scatter about a parabola in ln f (a cubic
    from 7 points on; A0's dispersion bends a line by ~1 % over an octave) by more than
    ``limit`` (robust, relative) while their own sigmas are under half
    that are picks on different ridges or packets, not a curve (issue 24, session 24: the real
    Yeum et al. S0 from a mode-separated record, 5 points scattering by 4 %, sigmas 0.02-0.7 %,
    where an imperfectly cancelled A0 trails S0 within the burst's length). Fewer than 4 points:
    ''."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    if f.size < 4:
        return ""
    x = np.log(f / f.max())
    c = np.polynomial.polynomial.polyfit(x, v, 3 if f.size >= 7 else 2)
    rel = (v - np.polynomial.polynomial.polyval(x, c)) / v
    spread = 1.4826 * float(np.median(np.abs(rel - np.median(rel))))
    own = float(np.median(s / v))
    if spread > limit and own < 0.5 * spread:
        return (f"its {f.size} points scatter by {100 * spread:.1f} % about a smooth curve while their sigmas "
                f"say {100 * own:.2f} %: picks on different packets or ridges")
    return ""


def odd_one(f_hz, v, sigma, limit: float = 0.01) -> int | None:
    """The one point that makes a curve ``scattered`` (its index), or None: leave each point out
    in turn; the point is the one whose removal leaves at least 4 points that stand together
    (``scattered`` is '') most tightly (smallest robust scatter: an end point, extrapolated,
    also lies far off the others' curve) and that lies off the smooth curve through them by
    more than ``limit`` and 4 x their robust scatter (a pick on another ridge in a burst's 4-6-point
    curve, which ``off_curve`` cannot judge below 7 points: issue 24, session 24). None when no
    single point explains the scatter (then the curve is withheld whole)."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    if f.size < 5 or not scattered(f, v, s, limit):
        return None
    x = np.log(f / f.max())
    best, tight = None, np.inf
    for j in range(f.size):
        keep = np.arange(f.size) != j
        if scattered(f[keep], v[keep], s[keep], limit):
            continue
        c = np.polynomial.polynomial.polyfit(x[keep], v[keep], 3 if keep.sum() >= 7 else 2)
        rel = (v - np.polynomial.polynomial.polyval(x, c)) / v
        spread = 1.4826 * float(np.median(np.abs(rel[keep] - np.median(rel[keep]))))
        off = abs(rel[j])
        if off > max(limit, 4.0 * spread) and spread < tight:
            best, tight = j, spread
    return best


def names(which, mask) -> str:
    """The wavelets behind the points of ``mask``, e.g. 'cmor2-1 (4), cmor1-1 (2)'."""
    n: dict = {}
    for i in np.flatnonzero(mask):
        n[which[i].name] = n.get(which[i].name, 0) + 1
    return ", ".join(f"{k} ({v})" for k, v in n.items())


def misfit_scale(f_hz, v, sigma, label: str = "the curve", degree: int = 3, octaves: float = 1.0,
                 min_points: int = 7, level: float = 0.95) -> tuple[float, str]:
    """The factor (>= 1) the sigmas of a group-velocity curve are multiplied by when its points
    scatter about the smooth curve through them more than their sigmas allow, and a console
    note ('' when 1).

    The smooth curve: a polynomial in ln f of degree min(``degree``, m - 3) (weights 1/sigma;
    at least 2 degrees of freedom, at least a parabola: 5 points) on each of k pieces of the
    curve, consecutive and of equal point counts, k = ceil(the curve's span in octaves /
    ``octaves``) but at most n // ``min_points`` (at least 1). Why pieces: A0's group velocity
    over 47-306 kHz (2.7 octaves) is not a cubic in ln f to its 0.002-0.2 % sigmas (the true
    plate's curve misses it by 4.6-6.2 x those sigmas, 1-2 % at the low end); in pieces of an
    octave it is (0.02-0.51 x; bench/RESULTS.md, issue 24, session 29, branch h65). The chi2 and degrees of freedom of the
    pieces are summed; when chi2 exceeds the chi2(dof) ``level`` quantile the scale is
    sqrt(chi2 / dof): the Birge ratio (R. T. Birge, Phys. Rev. 40, 207 (1932)), the scale factor
    of the Particle Data Group's averages (PDG, Review of Particle Physics, Introduction,
    "Averaging procedures"). A sigma is never shrunk. Why at all: at high SNR the picks' sigmas
    (shot-to-shot scatter + the wavelet sweep term) see only noise, while the points carry
    deterministic biases of a few 0.1 % alternating along the curve (issue 24, session 29: S0
    along 0 deg, 36 / 36 points within 1 % but |err| / sigma rms 3.1). Fewer than 5 points: 1.
    Units: any, consistent (f > 0)."""
    chi2, dof, n = birge_chi2(f_hz, v, sigma, degree, octaves, min_points)
    if dof < 1 or chi2 <= stats.chi2.ppf(level, dof) or chi2 <= dof:
        return 1.0, ""
    scale = float(np.sqrt(chi2 / dof))
    return scale, (f"{label}: its {n} points scatter about a smooth curve by {scale:.2g} x their sigmas "
                   f"(chi2 / dof = {chi2:.3g} / {dof}): sigmas scaled by {scale:.2g} (a bias the "
                   "shot-to-shot scatter does not see)")


def birge_chi2(f_hz, v, sigma, degree: int = 3, octaves: float = 1.0, min_points: int = 7
               ) -> tuple[float, int, int]:
    """(chi2, degrees of freedom, points used) of a curve's points about ``misfit_scale``'s smooth
    curve (piecewise polynomial in ln f, weights 1/sigma); (0, 0, n) with fewer than 5 points
    (4 leave a line in ln f, which A0's saturation misses: the demo's 4-point A0, 62-181 kHz,
    1580-1686 m/s, lay 5 x its 0.3 % sigmas off a line)."""
    f, v, s = (np.asarray(a, float) for a in (f_hz, v, sigma))
    ok = np.isfinite(f) & np.isfinite(v) & np.isfinite(s) & (s > 0) & (f > 0)
    order = np.argsort(f[ok])
    f, v, s = f[ok][order], v[ok][order], s[ok][order]
    n = f.size
    if n < 5:
        return 0.0, 0, n
    k = max(1, min(int(np.ceil(np.log2(f[-1] / f[0]) / octaves - 1e-9)), n // min_points))
    chi2, dof = 0.0, 0
    for idx in np.array_split(np.arange(n), k):
        deg = min(degree, idx.size - 3)
        x = np.log(f[idx] / f[idx[-1]])
        c = np.polynomial.polynomial.polyfit(x, v[idx], deg, w=1.0 / s[idx])
        chi2 += float(np.sum(((v[idx] - np.polynomial.polynomial.polyval(x, c)) / s[idx]) ** 2))
        dof += idx.size - deg - 1
    return chi2, dof, n
