"""The per-frequency loops of ``waves.arrival_times`` done on all rows at once (issue 24, session 29):
against the plain per-row computation they replaced, written out here, on numpy-made scalograms
(Gaussian packets with a chirp, noise, and gates that are empty, cut, NaN, on a phase wrap or
without a peak): every output equal bit for bit."""
import numpy as np

from engine import waves


def _reference(W, fs_hz, freqs, wavelet, t0_index, gate, first_fraction):
    """The per-row loop of ``arrival_times`` before session 29: (times, peak, width, finst, reason)."""
    nf, n = W.shape
    t = (np.arange(n) - t0_index) / fs_hz
    lo, hi = gate
    A = np.abs(W)
    tiny = np.finfo(float).tiny
    times, finst, peak, width = np.full(nf, np.nan), np.full(nf, np.nan), np.zeros(nf), np.zeros(nf)
    reason = [""] * nf
    for i in range(nf):
        if not (np.isfinite(lo[i]) and np.isfinite(hi[i])):
            reason[i] = "empty gate"
            continue
        k0 = max(int(np.ceil((lo[i] - t[0]) * fs_hz)), 0)
        k1 = min(int(np.floor((hi[i] - t[0]) * fs_hz)) + 1, n)
        if k1 - k0 < 3:
            reason[i] = "empty gate"
            continue
        a = A[i, k0:k1]
        m = a.max()
        if m <= 0:
            reason[i] = "no signal"
            continue
        cand = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:]) & (a[1:-1] >= first_fraction * m)) + 1
        if cand.size == 0:
            reason[i] = "peak on the gate edge"
            continue
        k = k0 + int(cand[0])
        la, lb, lc = np.log(np.maximum(A[i, k - 1:k + 2], tiny))
        den = la - 2 * lb + lc
        d = 0.5 * (la - lc) / den if den < 0 else 0.0
        width[i] = 1.0 / (fs_hz * np.sqrt(-2.0 * den)) if den < 0 else 0.0
        d = float(np.clip(d, -0.5, 0.5))
        times[i] = t[k] + d / fs_hz
        peak[i] = np.exp(lb - 0.25 * (la - lc) * d)
        fi = np.diff(np.unwrap(np.angle(W[i, k - 1:k + 2]))) * fs_hz / (2 * np.pi)
        finst[i] = fi[0] + (fi[1] - fi[0]) * (d + 0.5)
    return times, peak, width, finst, reason


def _scalogram(seed):
    rng = np.random.default_rng(seed)
    fs, n = 5e6, 1200
    freqs = np.linspace(40e3, 400e3, 60)
    tt = np.arange(n) / fs
    W = np.zeros((freqs.size, n), np.complex64)
    for i, f in enumerate(freqs):
        for c, amp, s in ((80e-6 + 0.05 * i * 1e-6, 1.0, 8e-6), (150e-6, rng.uniform(0.2, 1.5), 5e-6)):
            # a packet near fs / 2 per sample somewhere: its 3 phases straddle the +-pi cut
            fr = f if i % 7 else 0.45 * fs
            W[i] += (amp * np.exp(-0.5 * ((tt - c) / s) ** 2) * np.exp(2j * np.pi * fr * (tt - c)
                                                                        + 1j * 3e8 * (tt - c) ** 2)).astype(np.complex64)
    W += (1e-3 * (rng.normal(size=W.shape) + 1j * rng.normal(size=W.shape))).astype(np.complex64)
    W[5] = 0                                                   # no signal
    lo = rng.uniform(-20e-6, 200e-6, freqs.size)
    hi = lo + rng.uniform(-1e-6, 120e-6, freqs.size)           # some empty, some past the record
    lo[3], hi[8] = np.nan, np.nan
    lo[10], hi[10] = 130e-6, 160e-6                            # holds a packet's maximum
    lo[11], hi[11] = 151e-6, 170e-6                            # falling: the peak on the gate edge
    return W, fs, freqs, (lo, hi), rng


def test_arrival_times_on_all_rows_equal_the_per_row_loop():
    for seed in range(6):
        W, fs, freqs, gate, rng = _scalogram(seed)
        wl = waves.Wavelet(2.0, 1.0 + seed % 3)
        ff = (0.5, 0.999)[seed % 2]
        pre = int(rng.integers(0, 200))
        got = waves.arrival_times(W, fs, freqs, wl, t0_index=pre, gate_s=gate, first_fraction=ff, noise_rms=1e-3,
                                  min_snr_db=-1e9, min_rel_db=-1e9, max_freq_offset=np.inf, max_notch_db=np.inf)
        times, peak, width, finst, reason = _reference(W, fs, freqs, wl, pre, gate, ff)
        assert np.array_equal(got.times_s, times, equal_nan=True)
        assert np.array_equal(got.inst_freq_hz, finst, equal_nan=True)
        assert got.reason == tuple(reason)
        assert {"empty gate", "no signal", "peak on the gate edge", ""} <= set(reason)
        ok = np.isfinite(times)
        assert ok.sum() > 20
        tiny = np.finfo(float).tiny
        assert np.array_equal(got.snr_db, 20 * np.log10(np.maximum(peak, tiny) / 1e-3))
        # sigma (the expression of ``arrival_times``) from the reference's width and SNR
        tstd, off = wl.time_std_s(freqs), np.where(ok, (finst - freqs) / wl.freq_std_hz(freqs), 0.0)
        teff = np.maximum(tstd, width) ** 2 / tstd * np.sqrt(1.0 + off ** 2)
        snr_lin = 10 ** (np.minimum(got.snr_db, 200) / 10)
        with np.errstate(divide="ignore"):
            sigma = np.sqrt((teff / np.sqrt(2 * snr_lin)) ** 2 + (1.0 / (fs * np.sqrt(12)) / 10) ** 2)
        assert np.array_equal(got.sigma_s, sigma, equal_nan=True)
        # the phase-wrap rows took np.unwrap's path
        assert np.isfinite(finst[::7]).any() and (np.abs(finst[::7] - 0.45 * fs) < 0.05 * fs).any()


def _reference_peaks(A, t, fs, a_lo, a_hi, sig, claim, o_mid, o_half, predicted):
    """The per-frequency loop of ``arrivals_of`` before session 29: (best sample, reason)."""
    nf = A.shape[0]
    best, why = np.zeros(nf, int), [""] * nf
    for i in range(nf):
        if not predicted[i]:
            why[i] = "no prediction"
            continue
        k0 = max(int(np.ceil((a_lo[i] - 2 * sig[i] - t[0]) * fs)), 1)
        k1 = min(int(np.floor((a_hi[i] + 2 * sig[i] - t[0]) * fs)) + 1, A.shape[1] - 1)
        if k1 - k0 < 3:
            why[i] = "window outside the record"
            continue
        a = A[i, k0 - 1:k1 + 1]
        peaks = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:])) + k0
        if peaks.size:
            peaks = peaks[A[i, peaks] >= 0.05 * A[i, peaks].max()]
        b = None
        if peaks.size:
            tc = t[peaks]
            z_t = np.abs(tc - 0.5 * (a_lo[i] + a_hi[i])) / (0.5 * (a_hi[i] - a_lo[i]) + sig[i])
            rows = claim[:, i]
            with np.errstate(invalid="ignore", divide="ignore"):
                z_o = np.abs(tc[None, :] - o_mid[rows, i][:, None]) / o_half[rows, i][:, None]
            mine = ~(z_o < z_t[None, :]).any(axis=0)
            if mine.any():
                ks = peaks[mine]
                b = int(ks[int(np.argmax(A[i, ks]))])
        if b is None:
            why[i] = "no packet at the predicted time" if peaks.size else "peak on the window edge"
            continue
        best[i] = b
    return best, why


def test_target_peaks_equal_the_per_frequency_loop():
    from engine.wavefeatures.peaks import target_peaks
    for seed in range(6):
        W, fs, freqs, (lo, hi), rng = _scalogram(seed)
        A = np.abs(W)
        nf, n = A.shape
        t = (np.arange(n) - 100) / fs
        sig = rng.uniform(2e-6, 10e-6, nf)
        predicted = np.isfinite(lo) & np.isfinite(hi) & (rng.random(nf) > 0.05)
        a_lo, a_hi = np.where(predicted, lo, 0.0), np.where(predicted, np.maximum(hi, lo), 0.0)
        a_hi[:4] = a_lo[:4] = -1.0                          # before the record
        a_lo[4] = a_hi[4] = 1.0                             # after it
        k = 6                                               # foreign packets: one between the two packets
        o_mid = np.vstack([rng.uniform(0, 250e-6, (k - 1, nf)), np.full((1, nf), 115e-6)])
        o_half = rng.uniform(0.0, 20e-6, (k, nf))
        o_half[0, ::9] = np.nan
        claim = rng.random((k, nf)) > 0.3
        o_mid[1, 20:26], o_half[1, 20:26], claim[1, 20:26] = 0.5 * (a_lo + a_hi)[20:26], 1.0, True   # claims all
        got = target_peaks(A, t, fs, a_lo, a_hi, sig, claim, o_mid, o_half, predicted)
        best, why = _reference_peaks(A, t, fs, a_lo, a_hi, sig, claim, o_mid, o_half, predicted)
        assert got[1] == why
        assert np.array_equal(got[0], best)
        assert {"no prediction", "window outside the record", "no packet at the predicted time", ""} <= set(why)
        assert sum(not r for r in why) > 10


def test_pick_widths_equal_the_per_row_loop():
    """``peaks.pick_widths`` against the per-row lines of ``arrivals_of`` it replaced: the widening
    from log|W|'s curvature at the pick and |W| there."""
    import math
    from engine.wavefeatures.peaks import pick_widths
    W, fs, freqs, _, rng = _scalogram(1)
    A = np.abs(W)
    nf, n = A.shape
    t = (np.arange(n) - 100) / fs
    rows = np.arange(nf)
    tc = np.concatenate([[t[0], t[-1], t[0] + 0.4 / fs], rng.uniform(t[1], t[-2], nf - 3)])   # both edges
    st = rng.uniform(0.2e-6, 4e-6, nf)
    widen, a_at = pick_widths(A, t, fs, tc, st, rows)
    with np.errstate(divide="ignore", invalid="ignore"):     # row 5: |W| = 0
        for i in rows:
            kc = int(round((tc[i] - t[0]) * fs))
            w = 1.0
            if 1 <= kc < n - 1:
                la, lb, lc = np.log(np.maximum(A[i, kc - 1:kc + 2], 1e-300))
                d2 = la - 2 * lb + lc
                if d2 < 0:
                    w = float(np.clip(1.0 / (fs * math.sqrt(-d2)) / st[i], 1.0, 3.0))
            assert float(widen[i]) == w
            kc = min(max(kc, 1), n - 2)
            assert a_at[i] == A[i, kc]
    assert 1.0 < widen.max() <= 3.0 and (widen == 1.0).any()
