"""Resonances of hammer-test spectra: candidates, exact-DFT pole fit, manual editing.

3. ``pick_peaks(spec)``: peaks of the indicator, then a local fit of every
   peak (clusters of close peaks fitted together) with the exact DFT model of
   truncated, sampled, exponentially decaying sinusoids,

       X_j(w_k) = sum_q C_jq / (1 - z_q e^{-i w_k / fs}) + smooth_j(w_k),
       z_q = exp(p_q / fs),  p_q = -sigma_q + i w_dq,

   with common poles ``p_q`` for all channels (and hits) and a complex
   low-order polynomial ``smooth_j`` for the conjugate poles, the
   neighbouring modes and the force spectrum. The fit is a variable
   projection least-squares problem over (f, ln sigma) of each pole; it is
   exact (up to noise) even when the record is truncated before the ringing
   has died out, so the frequency is obtained to a small fraction of a bin.
4. ``add_peak`` / ``remove_peak``: pure functions for manual editing.

Frequencies are undamped natural frequencies f_n = |p| / 2 pi in Hz; damping
is the viscous ratio zeta = sigma / |p|. Units SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np
from scipy import optimize, special

from .spectral import ModalError, Spectra, indicator

__all__ = ["Peak", "pick_peaks", "fit_peaks", "add_peak", "remove_peak"]


@dataclass(frozen=True)
class Peak:
    """One resonance.

    frequency_hz: undamped natural frequency |p|/(2 pi), Hz.
    damping_ratio: viscous damping ratio (exponential window removed).
    sigma_hz: standard uncertainty of the frequency from the fit covariance, Hz.
    snr_db: energy the mode explains per output over the noise energy of one
        bin (about the peak-to-noise ratio of the spectrum), dB.
    confidence: 0..1, from snr_db (0 at <= 10 dB, 1 at >= 30 dB), halved for
        implausible damping (<= 0 or > 0.2), 0 if the fit ended on a bound.
    shape: real operating shape at the channels (max |.| = 1), or empty.
    manual: True if added by hand.
    """

    frequency_hz: float
    damping_ratio: float
    sigma_hz: float
    snr_db: float
    confidence: float
    shape: tuple[float, ...] = ()
    manual: bool = False


# --------------------------------------------------------------------------- fitting
def _halfwidth_bins(ind: np.ndarray, k: int) -> float:
    """Half of the -3 dB width of the indicator peak at bin k, in bins (>= 0.5)."""
    half = ind[k] / 2.0
    lo = k
    while lo > 0 and ind[lo - 1] > half and ind[lo - 1] <= ind[lo] * 1.0001:
        lo -= 1
    hi = k
    while hi < len(ind) - 1 and ind[hi + 1] > half and ind[hi + 1] <= ind[hi] * 1.0001:
        hi += 1
    return max(0.5, (hi - lo) / 2.0)


def _parabolic(y: np.ndarray, k: int) -> float:
    """Sub-bin offset of the vertex of a parabola through y[k-1:k+2]."""
    if k <= 0 or k >= len(y) - 1:
        return 0.0
    a, b, c = y[k - 1], y[k], y[k + 1]
    den = a - 2 * b + c
    return 0.0 if den >= 0 else float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))


def _fit_cluster(spec: Spectra, data: np.ndarray, f0: np.ndarray, s0: np.ndarray,
                 band: tuple[int, int], poly_deg: int):
    """Variable-projection fit of len(f0) poles to data[:, band]. Returns (f_d, sigma, cov, C, resid_rms, basis_fn)."""
    fs = spec.fs_hz
    k0, k1 = band
    fk = spec.frequencies_hz[k0:k1]
    Y = data[:, k0:k1].T  # (nk, n_out)
    zeta = np.exp(-2j * np.pi * fk / fs)
    # a response starting at the onset n0, truncated at N (exact at the bins, time
    # origin moved to n0): sum_{n0..N-1} z^(n-n0) e^{-iw(n-n0)} = (1 - z^(N-n0) e^{iw n0}) / (1 - z e^{-iw})
    back = np.exp(2j * np.pi * fk * spec.onset / fs)
    m_after = spec.n_samples - spec.onset
    u = (fk - fk.mean()) / max(np.ptp(fk) / 2, spec.df)
    V = np.vander(u, poly_deg + 1, increasing=True).astype(complex)
    K = len(f0)
    scale = np.abs(Y).max() or 1.0
    Yn = Y / scale

    def basis(x):
        fq, sq = x[:K], np.exp(x[K:])
        z = np.exp((-sq + 2j * np.pi * fq) / fs)
        P = (1.0 - z[:, None] ** m_after * back[None, :]) / (1.0 - z[:, None] * zeta[None, :])
        Bp = P.T  # (nk, K); the conjugate poles are smooth here: left to the polynomial
        return np.concatenate([Bp, V], axis=1), Bp

    def resid(x):
        B, _ = basis(x)
        cn = np.abs(B).max(axis=0)
        C = np.linalg.lstsq(B / cn, Yn, rcond=None)[0]
        R = Yn - (B / cn) @ C
        return np.concatenate([R.real.ravel(), R.imag.ravel()])

    x0 = np.concatenate([f0, np.log(s0)])
    lo = np.concatenate([fk[0] * np.ones(K), np.full(K, np.log(1e-6))])
    hi = np.concatenate([fk[-1] * np.ones(K), np.full(K, np.log(2 * np.pi * np.ptp(fk) + 1e-3))])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    res = optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale=np.concatenate(
        [np.full(K, spec.df * 0.1), np.ones(K)]), xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=100)
    B, Bp = basis(res.x)
    n_out = Y.shape[1]
    cn = np.abs(B).max(axis=0)
    C = np.linalg.lstsq(B / cn, Y, rcond=None)[0] / cn[:, None]  # (K + deg + 1, n_out)
    rss = float(np.sum(np.abs(Y - B @ C) ** 2))
    # residual degrees of freedom (real): data minus the linear and nonlinear parameters
    dof = max(2 * Y.size - 2 * B.shape[1] * n_out - res.x.size, 1)
    s2 = rss / dof  # noise variance of one real part of one bin of one output
    J = res.jac * scale
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((res.x.size, res.x.size), np.nan)
    # SNR of each pole: the energy it explains per output, over the noise energy of one bin
    snr = np.zeros(K)
    for q in range(K):
        Bq = np.delete(B, q, axis=1) / np.delete(cn, q)
        rq = Y - Bq @ np.linalg.lstsq(Bq, Y, rcond=None)[0]
        snr[q] = 10 * np.log10(max(np.sum(np.abs(rq) ** 2) - rss, 1e-300) / n_out / (2 * s2))
    at_bound = (np.isclose(res.x, lo, rtol=0, atol=1e-6) | np.isclose(res.x, hi, rtol=0, atol=1e-6))
    at_bound = at_bound[:K] | at_bound[K:]
    return res.x[:K], np.exp(res.x[K:]), cov, C[:K], snr, at_bound


def _real_shape(C: np.ndarray, spec: Spectra) -> tuple[float, ...]:
    """Real operating shape over channels from the complex residues of one pole."""
    nc = len(spec.channels)
    if spec.frf is not None:
        v = C
    else:
        M = C.reshape(spec.n_hits, nc)
        v = np.linalg.svd(M, full_matrices=False)[2][0].conj()
    theta = -0.5 * np.angle(np.sum(v ** 2))
    r = np.real(v * np.exp(1j * theta))
    i = int(np.argmax(np.abs(r)))
    if r[i] == 0:
        return tuple(0.0 for _ in r)
    return tuple(float(a) for a in r / r[i])


def _confidence(snr_db: float, zeta: float) -> float:
    c = float(np.clip((snr_db - 10.0) / 20.0, 0.0, 1.0))
    if not 0 < zeta < 0.2:
        c *= 0.5
    return c


def _fit_all(spec: Spectra, f_init: Sequence[float], ind: np.ndarray, *, poly_deg: int = 2,
             min_halfband_bins: int = 6, halfband_widths: float = 5.0, manual: bool = False,
             halfwidths: Sequence[float] | None = None, snap: Sequence[bool] | None = None,
             cache: dict | None = None):
    """Peaks and their poles (z, residues per output) fitted near ``f_init``.

    Starting frequencies are snapped to the indicator's local maximum (+-2
    bins, parabolic vertex) unless ``snap[i]`` is False (candidates found in
    a residual, which the indicator itself does not show)."""
    f = spec.frequencies_hz
    df = spec.df
    data = spec.fit_data()
    fi = np.asarray(f_init, float)
    sn = np.ones(fi.size, bool) if snap is None else np.asarray(snap, bool)
    ks = np.clip(np.round(fi / df).astype(int), 1, len(f) - 2)
    ks = np.array([max(k - 2, 1) + int(np.argmax(ind[max(k - 2, 1):min(k + 3, len(f) - 1)])) if s_ else k
                   for k, s_ in zip(ks, sn)])
    order = np.argsort(ks, kind="stable")
    ks, fi, sn = ks[order], fi[order], sn[order]
    logi = np.log(np.maximum(ind, np.finfo(float).tiny))
    f0 = np.array([(k + _parabolic(logi, k)) * df if s_ else x for k, x, s_ in zip(ks, fi, sn)])
    if halfwidths is None:
        hw = np.array([_halfwidth_bins(ind, k) for k in ks])
    else:
        hw = np.maximum(np.asarray(halfwidths, float)[order], 0.5)
    hw = np.minimum(hw, 50.0)
    s0 = np.maximum(2 * np.pi * hw * df, 0.5 * np.pi * df)
    w = np.maximum(min_halfband_bins, np.ceil(halfband_widths * hw)).astype(int)
    clusters: list[list[int]] = []
    for i in range(len(ks)):
        if clusters and ks[i] - w[i] <= ks[clusters[-1][-1]] + w[clusters[-1][-1]]:
            clusters[-1].append(i)
        else:
            clusters.append([i])
    peaks: list[Peak] = []
    poles: list[tuple[complex, np.ndarray]] = []
    tau = spec.exp_tau_s
    for cl in clusters:
        k0 = max(1, min(ks[i] - w[i] for i in cl))
        k1 = min(len(f), max(ks[i] + w[i] for i in cl) + 1)
        deg = min(poly_deg + max(0, len(cl) - 1), 4)
        need = 4 * (len(cl) + deg + 1)  # enough bins for a meaningful residual
        if k1 - k0 < need:
            grow = (need - (k1 - k0) + 1) // 2
            k0, k1 = max(1, k0 - grow), min(len(f), k1 + grow)
        key = (tuple(f0[cl]), tuple(s0[cl]), k0, k1, deg)
        if cache is not None and key in cache:  # unchanged cluster of an earlier pass
            fd, sg, cov, C, snrs, at_bound = cache[key]
        else:
            fd, sg, cov, C, snrs, at_bound = _fit_cluster(spec, data, f0[cl], s0[cl], (k0, k1), deg)
            if cache is not None:
                cache[key] = (fd, sg, cov, C, snrs, at_bound)
        for q in range(len(cl)):
            sig = sg[q] - (1.0 / tau if tau is not None else 0.0)
            wd = 2 * np.pi * fd[q]
            wn = np.hypot(sig, wd)
            zeta = float(sig / wn)
            fn = float(wn / (2 * np.pi))
            snr = float(snrs[q])
            sf = float(np.sqrt(cov[q, q])) if np.isfinite(cov[q, q]) else float("nan")
            conf = 0.0 if at_bound[q] else _confidence(snr, zeta)
            peaks.append(Peak(fn, zeta, sf, snr, conf, _real_shape(C[q], spec), manual))
            poles.append((complex(np.exp((-sg[q] + 2j * np.pi * fd[q]) / spec.fs_hz)), C[q]))
    order = np.argsort([p.frequency_hz for p in peaks], kind="stable")
    return [peaks[i] for i in order], [poles[i] for i in order]


def fit_peaks(spec: Spectra, f_init: Sequence[float], *, poly_deg: int = 2,
              min_halfband_bins: int = 6, halfband_widths: float = 5.0,
              method: Literal["sum", "cmif"] = "sum", manual: bool = False) -> tuple[Peak, ...]:
    """Fit one pole near each frequency of ``f_init`` (Hz); close ones are fitted together.

    Each fit uses the bins within max(min_halfband_bins, halfband_widths x the
    -3 dB half width) of the peak. Returns peaks sorted by frequency.
    """
    if len(f_init) == 0:
        return ()
    peaks, _ = _fit_all(spec, f_init, indicator(spec, method), poly_deg=poly_deg,
                        min_halfband_bins=min_halfband_bins, halfband_widths=halfband_widths, manual=manual)
    return tuple(peaks)


def _pole_model(spec: Spectra, poles, k0: int, k1: int) -> np.ndarray:
    """(n_outputs, k1 - k0) sum of the fitted pole terms on bins k0..k1-1."""
    fk = spec.frequencies_hz[k0:k1]
    zeta = np.exp(-2j * np.pi * fk / spec.fs_hz)
    back = np.exp(2j * np.pi * fk * spec.onset / spec.fs_hz)
    m_after = spec.n_samples - spec.onset
    out = np.zeros((spec.fit_data().shape[0], k1 - k0), complex)
    for z, C in poles:
        out += C[:, None] * ((1.0 - z ** m_after * back) / (1.0 - z * zeta))[None, :]
        if spec.frf is None:  # real records: the conjugate pole carries the conjugate residue
            zc = np.conj(z)
            out += np.conj(C)[:, None] * ((1.0 - zc ** m_after * back) / (1.0 - zc * zeta))[None, :]
    return out


def _power_indicator(spec: Spectra, Y: np.ndarray, norm: np.ndarray) -> np.ndarray:
    """'sum' indicator of complex data Y (n_outputs, nk) with the channel normalisation ``norm``."""
    nc = len(spec.channels)
    P = np.abs(Y) ** 2
    if spec.frf is None:
        P = P.reshape(spec.n_hits, nc, -1).mean(axis=0) * 2.0  # as Spectra.magnitude
    return (P / norm[:, None]).sum(axis=0)


def _candidates(db: np.ndarray, prominence: float, rise_db: float, half: int = 128) -> np.ndarray:
    """Peaks of a dB curve with a prominence and a rise over the running 20th percentile (+-half bins)."""
    # imported here: scipy.signal (with scipy.stats, which it imports) costs ~0.8 s CPU and 37 MiB
    # at the start of every command that imports the services; only peak picking needs them
    from scipy import ndimage, signal  # noqa: PLC0415
    idx, _ = signal.find_peaks(db, prominence=prominence)
    floor = ndimage.percentile_filter(db, 20, size=2 * half + 1, mode="nearest")
    return idx[db[idx] - floor[idx] >= rise_db]


def pick_peaks(spec: Spectra, *, fmin: float | None = None, fmax: float | None = None,
               min_prominence_db: float = 3.0, min_rise_db: float | None = None,
               min_confidence: float = 0.25, method: Literal["sum", "cmif"] = "sum",
               max_peaks: int | None = None, residual_passes: int = 4, **fit_kw) -> tuple[Peak, ...]:
    """Find and fit the resonances in [fmin, fmax] (Hz) across all channels at once.

    Candidates are peaks of the indicator (``indicator``) with a prominence of
    at least ``min_prominence_db`` that rise ``min_rise_db`` above the running
    20th percentile of the indicator (default: the level a chi-square noise
    spectrum with 2 x hits x channels degrees of freedom reaches once in the
    band, at least 6 dB). All are fitted (``fit_peaks``); then the fitted
    modes are subtracted from the complex data and the residual indicator is
    searched again (``residual_passes`` times, 'sum' indicator only) for modes
    hidden under the skirts of stronger neighbours. The search extends 10 %
    beyond the band so that modes just outside it are modelled too. Kept:
    confidence >= ``min_confidence`` (default 0.25, i.e. snr_db >= 15 dB).
    """
    f = spec.frequencies_hz
    ind = indicator(spec, method)
    lo = 1 if fmin is None else max(1, int(np.searchsorted(f, fmin)))
    hi = len(f) - 1 if fmax is None else min(len(f) - 1, int(np.searchsorted(f, fmax, side="right")))
    if hi - lo < 3:
        raise ModalError(f"frequency band [{fmin}, {fmax}] Hz holds fewer than 3 bins")
    # search 10 % beyond the band: modes just outside it bias those just inside
    lo = max(1, int(lo - 0.1 * (hi - lo)) if fmin is not None else lo)
    hi = min(len(f) - 1, int(hi + 0.1 * (hi - lo)))
    if min_rise_db is None:
        dof = 2 * max(spec.n_hits, 1) * len(spec.channels)
        # chi^2 quantiles as scipy.stats.chi2.ppf computes them (2 gammaincinv(dof/2, q))
        top = 2.0 * special.gammaincinv(dof / 2.0, 1 - 1.0 / (hi - lo))
        min_rise_db = max(6.0, float(10 * np.log10(top / (2.0 * special.gammaincinv(dof / 2.0, 0.2)))))
    tiny = np.finfo(float).tiny
    db = 10 * np.log10(np.maximum(ind[lo:hi], tiny))
    idx = _candidates(db, min_prominence_db, min_rise_db)
    if max_peaks is not None and len(idx) > max_peaks:
        idx = np.sort(idx[np.argsort(db[idx])[::-1][:max_peaks]])
    if len(idx) == 0:
        return ()
    cand = list((idx + lo) * spec.df)
    hws = [_halfwidth_bins(ind, k) for k in idx + lo]
    snaps = [True] * len(cand)
    data = spec.fit_data()
    P0 = spec.magnitude ** 2 if spec.kind == "frf" else spec.magnitude
    norm = np.maximum(np.median(P0[:, 1:], axis=1), tiny)
    cache: dict = {}
    peaks, poles = _fit_all(spec, cand, ind, halfwidths=hws, snap=snaps, cache=cache, **fit_kw)
    for _ in range(residual_passes if method == "sum" else 0):
        good = [(p, z) for p, z in zip(peaks, poles) if p.confidence >= min_confidence]
        R = data[:, lo:hi] - _pole_model(spec, [z for _, z in good], lo, hi)
        ir = _power_indicator(spec, R, norm)
        dbr = 10 * np.log10(np.maximum(ir, tiny))
        new = []
        # residual peaks are noisy: assume at least the typical half width of the modes found
        zeta_typ = float(np.median([p.damping_ratio for p, _ in good])) if good else 0.0
        js = _candidates(dbr, min_prominence_db, min_rise_db)
        for j in js[np.argsort(dbr[js])[::-1]][:10]:  # the 10 strongest per pass
            fj = (j + lo) * spec.df
            hwj = max(_halfwidth_bins(ir, j), zeta_typ * fj / spec.df)
            near = any(abs(p.frequency_hz - fj) < max(2 * spec.df, 0.5 * p.damping_ratio * p.frequency_hz)
                       for p, _ in good) or any(abs(c - fj) < 2 * spec.df for c, sn in zip(cand, snaps) if not sn)
            if not near:
                fnew = (j + _parabolic(dbr, j)) * spec.df + lo * spec.df
                if any(abs(c - fnew) < 2 * spec.df for c in cand):
                    # a candidate here did not fit as one mode: start a second pole half a
                    # half-width below, so that the pair can split
                    fnew -= 0.5 * hwj * spec.df
                new.append((fnew, hwj))
        if not new:
            break
        cand += [c for c, _ in new]
        hws += [h for _, h in new]
        snaps += [False] * len(new)
        peaks, poles = _fit_all(spec, cand, ind, halfwidths=hws, snap=snaps, cache=cache, **fit_kw)
    out = [p for p in peaks if p.confidence >= min_confidence
           and (fmin is None or p.frequency_hz >= fmin) and (fmax is None or p.frequency_hz <= fmax)]
    # candidates that converged on the same pole: keep the more confident one
    dedup: list[Peak] = []
    for p in out:
        if dedup and abs(p.frequency_hz - dedup[-1].frequency_hz) < max(
                spec.df / 4, 3 * p.sigma_hz if np.isfinite(p.sigma_hz) else 0.0):
            if p.confidence > dedup[-1].confidence:
                dedup[-1] = p
            continue
        dedup.append(p)
    return tuple(dedup)


def add_peak(peaks: Sequence[Peak], spec: Spectra, f_hz: float, **fit_kw) -> tuple[Peak, ...]:
    """Peaks with one more, fitted near ``f_hz`` (Hz) and marked manual; sorted by frequency.

    A new peak that lands on an existing one (closer than a quarter bin) replaces it.
    """
    if not spec.frequencies_hz[1] <= f_hz <= spec.frequencies_hz[-2]:
        raise ModalError(f"frequency {f_hz!r} Hz is outside the spectrum "
                         f"({spec.frequencies_hz[1]:g}..{spec.frequencies_hz[-2]:g} Hz)")
    (new,) = fit_peaks(spec, [f_hz], manual=True, **fit_kw)
    kept = [p for p in peaks if abs(p.frequency_hz - new.frequency_hz) >= spec.df / 4]
    return tuple(sorted([*kept, new], key=lambda p: p.frequency_hz))


def remove_peak(peaks: Sequence[Peak], f_hz: float, tol_hz: float | None = None) -> tuple[Peak, ...]:
    """Peaks without the one nearest ``f_hz`` (Hz); unchanged if none lies within ``tol_hz``."""
    if not peaks:
        return ()
    i = int(np.argmin([abs(p.frequency_hz - f_hz) for p in peaks]))
    if tol_hz is not None and abs(peaks[i].frequency_hz - f_hz) > tol_hz:
        return tuple(peaks)
    return tuple(p for j, p in enumerate(peaks) if j != i)
