"""The target packet's scalogram peak in its predicted window, every frequency at once.

Moved out of ``engine.wavefeatures.picks.arrivals_of`` (issue 24, session 29), where it was a Python
loop over the frequencies (a sixth of a tone-burst sweep's analysis): the windows are gathered into
one (frequencies, widest window) array and every test is one array expression. The float operations
are those of the loop, element by element, so the picks are equal bit for bit
(tests/unit/engine/test_wave_vectorised.py holds the loop as the reference). Units: s, Hz.
"""
from __future__ import annotations

import numpy as np

__all__ = ["target_peaks", "pick_widths"]


def target_peaks(A: np.ndarray, t: np.ndarray, fs: float, a_lo: np.ndarray, a_hi: np.ndarray, sig: np.ndarray,
                 claim: np.ndarray, o_mid: np.ndarray, o_half: np.ndarray, predicted: np.ndarray
                 ) -> tuple[np.ndarray, list[str]]:
    """Per row of |W| ``A`` (nf, n) on the time axis ``t`` (s): the sample of the target's peak, and
    why there is none ('' where there is one).

    The window: the target's range [a_lo, a_hi] (s) widened by 2 ``sig`` (its time std), inside
    the record; its local maxima at >= 5 % of the strongest one; a maximum is the target's when
    no foreign packet claiming it (``claim``, (packets, nf)) lies nearer in units of its
    uncertainty (``o_mid``, ``o_half``: their centres and half-widths, (packets, nf)) than the
    target in its own; the strongest such maximum. ``predicted``: rows with a prediction."""
    nf, n = A.shape
    best = np.zeros(nf, int)
    why = [""] * nf
    k0 = np.ones(nf, int)
    k1 = np.zeros(nf, int)
    p = np.flatnonzero(predicted)
    k0[p] = np.maximum(np.ceil((a_lo[p] - 2 * sig[p] - t[0]) * fs), 1)
    k1[p] = np.minimum(np.floor((a_hi[p] + 2 * sig[p] - t[0]) * fs) + 1, n - 1)
    for i in np.flatnonzero(~predicted):
        why[i] = "no prediction"
    for i in np.flatnonzero(predicted & (k1 - k0 < 3)):
        why[i] = "window outside the record"
    rows = np.flatnonzero(predicted & (k1 - k0 >= 3))
    if rows.size == 0:
        return best, why
    w = k1[rows] - k0[rows]                    # samples k0 .. k1 - 1, each with both neighbours
    j = np.arange(int(w.max()))
    pos = k0[rows, None] + j                   # (rows, widest window), past a row's window: its last sample
    pos = np.minimum(pos, (k1[rows] - 1)[:, None])
    a, before, after = A[rows[:, None], pos], A[rows[:, None], pos - 1], A[rows[:, None], pos + 1]
    peak = (a >= before) & (a > after) & (j < w[:, None])
    any_peak = peak.any(axis=1)
    top = np.where(peak, a, 0).max(axis=1)
    peak &= a >= 0.05 * top[:, None]
    tc = t[pos]
    mid, half = 0.5 * (a_lo[rows] + a_hi[rows]), 0.5 * (a_hi[rows] - a_lo[rows]) + sig[rows]
    z_t = np.abs(tc - mid[:, None]) / half[:, None]
    mine = peak.copy()
    with np.errstate(invalid="ignore", divide="ignore"):
        for q in range(claim.shape[0]):        # a foreign packet nearer than the target: not the target's
            c = claim[q, rows]
            if c.any():
                z_o = np.abs(tc[c] - o_mid[q, rows[c], None]) / o_half[q, rows[c], None]
                mine[c] &= ~(z_o < z_t[c])
    found = mine.any(axis=1)
    first = np.argmax(np.where(mine, a, -1), axis=1)
    for r, i in enumerate(rows):
        if found[r]:
            best[i] = pos[r, first[r]]
        else:
            why[i] = "no packet at the predicted time" if any_peak[r] else "peak on the window edge"
    return best, why


def pick_widths(A: np.ndarray, t: np.ndarray, fs: float, tc: np.ndarray, st: np.ndarray, rows: np.ndarray):
    """At the picks ``tc`` (s) of ``rows``: how much wider than predicted (amplitude std ``st``, s)
    the packet is, from the curvature of log|W| (1 / (fs sqrt(-d2)), clipped to 1-3; 1 where it is
    not curved or on the record's edge), and |W| at the pick's sample. The float operations of
    the per-row loop they replace (``picks.arrivals_of``), element by element. (The crosstalk's
    level and slope are taken at the target's predicted time, ``judge.crosstalk_at``.)"""
    n = A.shape[1]
    kc = np.rint((tc - t[0]) * fs).astype(int)
    kk = np.clip(kc, 1, n - 2)
    with np.errstate(invalid="ignore", divide="ignore"):     # |W| = 0 (float32 floors 1e-300 at 0)
        la, lb, lc = (np.log(np.maximum(A[rows, kk + j], 1e-300)) for j in (-1, 0, 1))
        d2 = la - 2 * lb + lc
        w = np.clip(1.0 / (fs * np.sqrt(-d2.astype(float))) / st, 1.0, 3.0)
    widen = np.where((kc >= 1) & (kc < n - 1) & (d2 < 0), w, 1.0)
    return widen, A[rows, kk]
