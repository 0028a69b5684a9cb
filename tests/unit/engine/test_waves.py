"""engine.waves on records with exactly known group delays.

Reference: a thin-plate (Kirchhoff) flexural wave synthesised analytically,
u(w) = F(w) exp(-i k(w) d), k = sqrt(w) (rho h / D)^(1/4), whose exact group
velocity is c_g = 2 sqrt(w) (D / rho h)^(1/4); non-dispersive Gaussian packets
with a known centre; PyWavelets' own CWT.
"""
from __future__ import annotations

import numpy as np
import pytest
import pywt

from engine import safe, waves
from engine.waves import Wavelet, independent_points
from labid.inputs.specimen import load_specimen
from tests.wave_reference import independent_group_velocity

FS = 1e6
# the paper's aluminium plate, 3.175 mm, sensor 0.375 m from the hammer
E, NU, RHO, H = 71.04e9, 71.04 / (2 * 25.32) - 1, 2700.0, 3.175e-3
D = E * H ** 3 / (12 * (1 - NU ** 2))
MU = RHO * H
DIST = 0.375
T_C = 1e-4  # hammer pulse centre, s


def cg_kirchhoff(f):
    return 2 * np.sqrt(2 * np.pi * np.asarray(f)) * (D / MU) ** 0.25


def record(distances=(DIST,), amps=(1.0,), n=10_000, pulse_s=20e-6, extra=None, nfft=1 << 20, lowpass_hz=None):
    """Force (n,) and strain-like record (n,): flexural waves over each distance (summed)."""
    t = np.arange(nfft) / FS
    p = np.where(np.abs(t - T_C) < pulse_s / 2, np.cos(np.pi * (t - T_C) / pulse_s), 0.0)
    f = np.fft.rfftfreq(nfft, 1 / FS)
    w = 2 * np.pi * f
    P = np.fft.rfft(p) * (f / 500) ** 2 / (1 + (f / 500) ** 2)  # no slow DC content
    if lowpass_hz is not None:
        P = P * np.exp(-(f / lowpass_hz) ** 8)
    k = np.sqrt(w) * (MU / D) ** 0.25
    U = sum(a * P * np.exp(-1j * k * d) for d, a in zip(distances, amps))
    if extra is not None:
        U = U + extra(P, w)
    return p[:n], np.fft.irfft(U, nfft)[:n]


FREQS = np.linspace(3e3, 45e3, 43)


def velocities(u, force, wl, *, assign="instantaneous", correct=True, gate=None, **kw):
    au = waves.arrival_times(waves.cwt(u, FS, FREQS, wl), FS, FREQS, wl, gate_s=gate, **kw)
    if correct:
        au = waves.correct_dispersion_bias(au)
    af = waves.arrival_times(waves.cwt(force, FS, FREQS, wl), FS, FREQS, wl)
    return waves.group_velocity(au, DIST, af, assign=assign), au


def test_fft_cwt_matches_pywavelets():
    # a smooth packet: pywt's integrated-wavelet CWT agrees with the analytic
    # filter bank to within 1 % of the peak, half a sample later
    n = 4000
    t = np.arange(n) / FS
    x = np.exp(-((t - 2e-3) / 2e-4) ** 2) * np.cos(2 * np.pi * 20e3 * t)
    f = np.array([10e3, 20e3, 30e3])
    for wl in (waves.PAPER_ALUMINIUM, waves.PAPER_CFRP):
        Wa = waves.cwt(x, FS, f, wl)
        Wp, fp = pywt.cwt(x, wl.scales(f, FS), wl.name, sampling_period=1 / FS, method="fft")
        np.testing.assert_allclose(fp, f, rtol=1e-9)  # scale <-> frequency as pywt
        Wp2 = waves.cwt(x, FS, f, wl, method="pywt")
        np.testing.assert_array_equal(Wp, Wp2)
        shifted = np.fft.ifft(np.fft.fft(Wa, axis=1) * np.exp(-1j * np.pi * np.fft.fftfreq(n)), axis=1)
        err = np.abs(np.abs(Wp) - np.abs(shifted))[:, 200:-200].max() / np.abs(Wa).max()
        assert err < 0.01


def test_decimated_cwt_holds_the_same_samples():
    # each row is band-limited: its samples every `step` are those of the full transform
    x = np.random.default_rng(3).normal(size=10_000)
    for wl, fmax in ((waves.PAPER_ALUMINIUM, 50e3), (waves.PAPER_CFRP, 200e3)):
        f = np.linspace(fmax / 100, fmax, 100)
        W = waves.cwt(x, FS, f, wl)
        Wd, step = waves.cwt_decimated(x, FS, f, wl)
        assert step >= 8 and Wd.shape == W[:, ::step].shape
        k = Wd.shape[1]
        mid = slice(int(0.3 * k), int(0.7 * k))  # away from the (differently padded) ends
        err = np.abs(Wd[:, mid] - W[:, ::step][:, mid]).max() / np.abs(W).max()
        assert err < 1e-4


def test_tone_and_packet_exact():
    n = 6000
    t = np.arange(n) / FS
    # a pure tone: instantaneous frequency exact, away from the ends
    W = waves.cwt(np.cos(2 * np.pi * 23.4e3 * t), FS, [23.4e3], waves.PAPER_ALUMINIUM, precision="double")
    fi = np.diff(np.unwrap(np.angle(W[0, 1000:5000]))) * FS / (2 * np.pi)
    np.testing.assert_allclose(fi, 23.4e3, rtol=1e-6)
    W32 = waves.cwt(np.cos(2 * np.pi * 23.4e3 * t), FS, [23.4e3], waves.PAPER_ALUMINIUM)  # single precision
    np.testing.assert_allclose(np.abs(W32[0, 1000:5000]), np.abs(W[0, 1000:5000]), rtol=1e-4)
    # a non-dispersive Gaussian packet centred between samples: every frequency arrives at its centre
    tc = 3.0004321e-3
    x = np.exp(-((t - tc) / 3e-5) ** 2) * np.cos(2 * np.pi * 20e3 * (t - tc))
    f = np.linspace(10e3, 30e3, 9)
    a = waves.arrival_times(waves.cwt(x, FS, f, waves.PAPER_ALUMINIUM), FS, f, waves.PAPER_ALUMINIUM,
                            min_rel_db=-60)
    assert a.valid.all()
    np.testing.assert_allclose(a.times_s, tc, atol=2e-9)  # 1/500 of a sample


@pytest.mark.parametrize("wl", [waves.PAPER_ALUMINIUM, waves.Wavelet(2, 2), waves.PAPER_CFRP],
                         ids=lambda w: w.name)
def test_kirchhoff_group_velocity(wl):
    force, u = record()
    g, _ = velocities(u, force, wl)
    ok = g.valid
    assert ok.sum() >= 0.9 * FREQS.size
    err = g.velocity_m_s[ok] / cg_kirchhoff(FREQS[ok]) - 1
    assert np.abs(err).max() < 2e-3  # 0.2 % with reassignment and curvature correction


def test_centre_frequency_sweep_exposes_the_wavelet_bias():
    """docs/wavelet-bias.md: the paper's nominal assignment is biased by an
    amount that depends on the wavelet (about (3/8)(2/B)/(2 pi C)^2 + slope
    terms for c_g ~ sqrt(f)); sweeping C moves the nominal curve, the
    corrected one does not move."""
    force, u = record()
    sel = (FREQS >= 5e3) & (FREQS <= 40e3)
    nominal, fixed = {}, {}
    for c in (1.0, 2.0, 5.0):
        wl = waves.Wavelet(2.0, c)
        nominal[c] = velocities(u, force, wl, assign="nominal", correct=False)[0].velocity_m_s[sel]
        fixed[c] = velocities(u, force, wl)[0].velocity_m_s[sel]
    exact = cg_kirchhoff(FREQS[sel])
    # the nominal curve moves with C by more than 0.5 %, towards the exact curve as C grows
    spread_nom = (nominal[5.0] - nominal[1.0]) / exact
    assert spread_nom.min() > 0.005
    assert np.abs(nominal[5.0] / exact - 1).max() < np.abs(nominal[1.0] / exact - 1).max()
    # the leading curvature term predicts the C = 1 offset at low frequency (pulse spectrum flat there)
    pred = 3 / 8 * (2 / 2.0) / (2 * np.pi * 1.0) ** 2
    assert nominal[1.0][0] / exact[0] - 1 == pytest.approx(-pred, abs=0.3 * pred)
    # corrected curves agree across C within 0.1 %
    spread_fix = np.nanmax([np.abs(fixed[c] / fixed[5.0] - 1).max() for c in (1.0, 2.0)])
    assert spread_fix < 1e-3


def test_gate_keeps_the_direct_wave_against_a_stronger_echo():
    # an edge echo over 0.375 + 2 x 0.2 m, three times stronger (e.g. focused)
    force, u = record(distances=(DIST, DIST + 0.4), amps=(1.0, 3.0))
    wl = waves.PAPER_ALUMINIUM  # short enough in time to separate the two packets
    bad, _ = velocities(u, force, wl, correct=False)
    assert np.nanmedian(bad.velocity_m_s / cg_kirchhoff(FREQS)) < 0.8  # the echo captured the peak
    cg_guess = 1.1 * cg_kirchhoff(FREQS)  # a 10 % wrong model is good enough for gating
    gate = waves.expected_gate(DIST, cg_guess, margin=0.3, source_time_s=T_C, reflection_m=DIST + 0.4,
                               time_std_s=wl.time_std_s(FREQS))
    good, _ = velocities(u, force, wl, gate=gate)
    ok = good.valid
    # low frequencies, where the wavelet cannot separate the packets, are rejected, not biased
    assert ok.sum() >= 15
    assert np.abs(good.velocity_m_s[ok] / cg_kirchhoff(FREQS[ok]) - 1).max() < 3e-3


def test_a0_and_s0_separated_by_gates():
    c_s0 = 5300.0  # a non-dispersive S0 (low-frequency limit), weaker than A0 as under a normal force
    force, u = record(extra=lambda P, w: 0.3 * P * np.exp(-1j * w / c_s0 * DIST))
    wl = waves.PAPER_ALUMINIUM
    cg_a0 = cg_kirchhoff(FREQS)
    s0 = np.full(FREQS.size, c_s0)
    ts = wl.time_std_s(FREQS)
    # gates from 10 %-wrong expected curves
    g_a0 = waves.expected_gate(DIST, cg_a0 * 0.9, margin=0.3, source_time_s=T_C, faster_cg=s0, time_std_s=ts,
                               mode_clearance=3.0)
    g_s0 = waves.expected_gate(DIST, s0 * 1.1, margin=0.2, source_time_s=T_C, slower_cg=cg_a0 * 0.9,
                               time_std_s=ts, mode_clearance=3.0)
    a0, _ = velocities(u, force, wl, gate=g_a0)
    s0v, _ = velocities(u, force, wl, gate=g_s0, correct=False)
    ok = a0.valid
    assert ok[(FREQS >= 10e3) & (FREQS <= 40e3)].all()
    assert np.abs(a0.velocity_m_s[ok] / cg_a0[ok] - 1).max() < 0.01
    # the S0 gate picks S0, not A0 (the thin-plate A0 of this synthetic record
    # becomes unphysically fast above 50 kHz and blurs S0: no accuracy claim here)
    ok = s0v.valid
    assert ok.sum() >= 10
    assert abs(np.median(s0v.velocity_m_s[ok]) / c_s0 - 1) < 0.02


def test_weak_frequencies_are_rejected_and_noise_sets_the_uncertainty():
    rng = np.random.default_rng(0)
    force, u = record(lowpass_hz=25e3)  # no signal above ~30 kHz: noise only
    wl = waves.PAPER_CFRP
    noise_std = 0.002 * np.abs(u).max()
    errs, sig = [], []
    for _ in range(6):
        un = u + noise_std * rng.normal(size=u.size)
        nr = waves.white_noise_level(noise_std, FS, FREQS, wl)
        g, a = velocities(un, force, wl, noise_rms=nr)
        assert not g.valid[FREQS > 32e3].any()
        assert all(("SNR" in r or "energy" in r or "leakage" in r) for r, f in zip(a.reason, FREQS) if f > 32e3)
        ok = g.valid
        assert ok.sum() >= 10
        errs.append(g.velocity_m_s[ok] / cg_kirchhoff(FREQS[ok]) - 1)
        sig.append(g.sigma_m_s[ok] / g.velocity_m_s[ok])
    errs, sig = np.concatenate(errs), np.concatenate(sig)
    assert np.abs(errs).max() < 0.01
    # the stated uncertainty covers the scatter (within a factor 2 either way)
    ratio = np.std(errs) / np.sqrt(np.mean(sig ** 2))
    assert 0.5 < ratio < 2.0


def test_frequencies_at_a_zero_of_the_source_spectrum_are_rejected():
    # a 60 us half-sine has its first spectral zero at 25 kHz: the frequencies whose
    # window straddles it are rejected (notch / leakage), not returned biased
    force, u = record(pulse_s=60e-6)
    g, a = velocities(u, force, waves.PAPER_ALUMINIUM)
    near = np.abs(FREQS - 25e3) <= 1e3
    assert not g.valid[near].any()
    assert all(("notch" in r or "leakage" in r) for r, z in zip(a.reason, near) if z)
    # well below it the curve is right (docs/wavelet-bias.md: the band must stay below ~0.6 x the zero)
    low = g.valid & (FREQS <= 15e3)
    assert low.sum() >= 10
    assert np.abs(g.velocity_m_s[low] / cg_kirchhoff(FREQS[low]) - 1).max() < 3e-3


def test_two_sensor_velocity():
    force, u1 = record(distances=(0.2,))
    _, u2 = record(distances=(DIST,))
    wl = waves.Wavelet(2, 2)
    a1 = waves.correct_dispersion_bias(waves.arrival_times(waves.cwt(u1, FS, FREQS, wl), FS, FREQS, wl))
    a2 = waves.correct_dispersion_bias(waves.arrival_times(waves.cwt(u2, FS, FREQS, wl), FS, FREQS, wl))
    g = waves.group_velocity(a2, DIST, a1, near_distance_m=0.2)
    ok = g.valid
    assert ok.sum() >= 0.8 * FREQS.size
    assert np.abs(g.velocity_m_s[ok] / cg_kirchhoff(FREQS[ok]) - 1).max() < 3e-3


def test_bad_input():
    with pytest.raises(waves.WaveError):
        waves.cwt(np.zeros(100), FS, [0.6 * FS])
    with pytest.raises(waves.WaveError):
        waves.Wavelet(0, 1)
    with pytest.raises(waves.WaveError):
        waves.velocity_gate(0.3, 2000, 1000)


@pytest.mark.parametrize("name", ["cmor2-1", "cmor2-5", "cmor0.5-1", "cmor1.5-0.6667", "cmor2-2.5"])
def test_wavelet_from_name_reads_pywavelets_names(name):
    """B and C as PyWavelets itself reads them from the name, and the name round-trips."""
    wl = waves.Wavelet.from_name(name)
    ref = pywt.ContinuousWavelet(name)
    assert (wl.bandwidth, wl.center) == pytest.approx((ref.bandwidth_frequency, ref.center_frequency), rel=1e-7)
    assert wl.name == name


def test_wavelet_from_name_rejects_other_names():
    for bad in ("morl", "cmor2", "cmor-1", "cmor2-1-3", "cmor0-1", "", None, 2.0):
        with pytest.raises(waves.WaveError):
            waves.Wavelet.from_name(bad)
        assert waves.Wavelet.from_name(bad, default=waves.PAPER_CFRP) == waves.PAPER_CFRP


# --------------------------------------------------------------------------- SAFE-synthesised records
def _safe_case(name, distance, force, fs, n, wl, fmax, noise_rel=1e-3, seed=0):
    lam = load_specimen(name).laminate
    u = safe.transient_response(lam, distance, force, fs, n, quantity="strain")
    u = u + noise_rel * np.abs(u).max() * np.random.default_rng(seed).normal(size=n)
    freqs = np.linspace(fmax / 20, fmax, 60)
    cg = np.asarray(safe.group_velocity(lam, freqs, "A0"), float)
    cs0 = np.asarray(safe.group_velocity(lam, freqs, "S0"), float)
    # gates from curves 5 % off (the nominal model is never exact)
    gate = waves.expected_gate(distance, cg * 1.05, margin=0.3, faster_cg=cs0, time_std_s=wl.time_std_s(freqs))
    nr = waves.white_noise_level(noise_rel * np.abs(u).max(), fs, freqs, wl)
    a = waves.arrival_times(waves.cwt(u, fs, freqs, wl), fs, freqs, wl, gate_s=gate, noise_rms=nr)
    # the reference the picks are judged by: an independent model, not the SAFE that made
    # the record and the gates (issue 24; tests/wave_reference.py)
    return lam, freqs, independent_group_velocity(lam, freqs, "A0"), a


@pytest.mark.slow
def test_safe_aluminium_hammer_a0_within_1_percent():
    """Paper section 3: aluminium 3.175 mm, hammer, strain 0.375 m away, cmor2-1 to
    50 kHz; source times from the force record's scalogram."""
    fs, n = 1e6, 4096
    force = safe.hammer_force(20e-6)
    wl = waves.PAPER_ALUMINIUM
    lam, freqs, cg, a = _safe_case("aluminium", DIST, force, fs, n, wl, 50e3)
    fw = force(np.arange(n) / fs)
    af = waves.arrival_times(waves.cwt(fw, fs, freqs, wl), fs, freqs, wl)
    g = waves.group_velocity(waves.correct_dispersion_bias(a), DIST, af)
    ok = g.valid
    assert ok[(freqs >= 5e3) & (freqs <= 45e3)].all()
    assert np.abs(g.velocity_m_s[ok] / cg[ok] - 1).max() < 0.01
    # the paper's nominal assignment with this wavelet is off by more than 1 % (docs/wavelet-bias.md)
    gn = waves.group_velocity(a, DIST, af, assign="nominal")
    assert np.nanmax(np.abs(gn.velocity_m_s / cg - 1)) > 0.01


@pytest.mark.slow
def test_safe_cfrp_pencil_lead_a0_within_1_percent():
    """Paper Fig. 8-9: CFRP [0/+-45]2s, pencil-lead break, cmor2-5 to 200 kHz;
    source to sensor (source time: middle of the 1 us rise) and between two sensors."""
    fs, n = 2e6, 4096
    plb = safe.pencil_lead_break(1e-6)
    wl = waves.PAPER_CFRP
    lam, freqs, cg, a2 = _safe_case("cfrp", 0.20, plb, fs, n, wl, 200e3)
    band = freqs >= 20e3
    g = waves.group_velocity(waves.correct_dispersion_bias(a2), 0.20, source_time_s=0.5e-6)
    ok = g.valid & band
    assert ok.sum() >= 0.8 * band.sum()
    assert np.abs(g.velocity_m_s[ok] / cg[ok] - 1).max() < 0.01
    # two sensors, 0.05 and 0.20 m (the default rig): at 5 cm A0 and S0 overlap within a
    # cmor2-5 wavelet, so this geometry needs the shorter cmor2-1
    wl = waves.PAPER_ALUMINIUM
    _, _, _, a2 = _safe_case("cfrp", 0.20, plb, fs, n, wl, 200e3)
    _, _, _, a1 = _safe_case("cfrp", 0.05, plb, fs, n, wl, 200e3, seed=1)
    g2 = waves.group_velocity(waves.correct_dispersion_bias(a2), 0.20, waves.correct_dispersion_bias(a1),
                              near_distance_m=0.05)
    ok = g2.valid & band
    assert ok.sum() >= 0.8 * band.sum()
    assert np.abs(g2.velocity_m_s[ok] / cg[ok] - 1).max() < 0.01


def test_white_noise_level_matches_the_transform_of_noise():
    x = np.random.default_rng(0).normal(scale=2.0, size=200_000)
    f = np.array([50e3, 200e3])
    for wl in (waves.PAPER_ALUMINIUM, waves.PAPER_CFRP):
        W = waves.cwt(x, FS, f, wl, precision="double")
        emp = np.sqrt((np.abs(W[:, 20_000:-20_000]) ** 2).mean(axis=1))
        np.testing.assert_allclose(emp, waves.white_noise_level(2.0, FS, f, wl), rtol=0.03)


def test_independent_points_are_a_wavelet_resolution_apart():
    """White-noise CWT coefficients at neighbouring kept frequencies correlate by at
    most 1/e (the normalised overlap of the two wavelet spectra), and the kept set
    is not needlessly sparse: the gap between neighbours stays below twice that."""
    wl = Wavelet(2.0, 2.0)
    f = np.linspace(10e3, 200e3, 100)
    keep = independent_points(f, np.ones(f.size, bool), wl)
    fk = f[keep]
    grid = np.linspace(0, 400e3, 40001)

    def spectrum(fc):   # |Psi(f)| of the scaled Morlet: its square has std freq_std_hz
        return np.exp(-0.25 * ((grid - fc) / wl.freq_std_hz(fc)) ** 2)

    def overlap(a, b):   # correlation of the two coefficients for white noise
        pa, pb = spectrum(a), spectrum(b)
        return np.sum(pa * pb) / np.sqrt(np.sum(pa * pa) * np.sum(pb * pb))

    assert keep[0] and 5 <= keep.sum() < 40
    assert all(overlap(a, b) <= np.exp(-1) + 0.02 for a, b in zip(fk[:-1], fk[1:]))
    # a point halfway between two kept neighbours would correlate more than 1/e with both
    assert all(overlap(a, (a + b) / 2) > np.exp(-1) for a, b in zip(fk[:-1], fk[1:]))


def test_noise_sigma_follows_a_packet_longer_than_the_wavelet():
    """A Gaussian-envelope tone burst 4 x longer than a short wavelet (cmor0.5-1), in white
    noise: the scatter of the picked times over 200 noise draws matches the stated sigma
    (Monte Carlo), which must then follow the packet's width, not the wavelet's."""
    fs, f0, n, t0 = 1e6, 40e3, 1000, 400e-6
    wl = waves.Wavelet(0.5, 1.0)
    t = np.arange(n) / fs
    s_env = 4 * np.sqrt(2) * float(wl.time_std_s(f0))  # amplitude std of the burst, s
    x0 = np.exp(-((t - t0) / s_env) ** 2 / 2) * np.cos(2 * np.pi * f0 * (t - t0))
    std = 0.02
    rng = np.random.default_rng(3)
    nr = waves.white_noise_level(std, fs, [f0], wl)
    tt, ss = [], []
    for _ in range(200):
        W = waves.cwt(x0 + std * rng.normal(size=n), fs, [f0], wl)
        a = waves.arrival_times(W, fs, [f0], wl, noise_rms=nr, min_snr_db=0.0)
        tt.append(a.times_s[0])
        ss.append(a.sigma_s[0])
    ratio = np.std(tt) / np.sqrt(np.mean(np.square(ss)))
    assert 0.7 < ratio < 1.4


def test_instantaneous_frequency_across_phase_wraps():
    # a Gaussian packet at 0.05-0.45 fs: the phase turns 0.1-0.9 pi per sample, so the three samples
    # around each pick straddle the +-pi cut at random places; the phase slope must still give the
    # packet's own frequency (the unwrap is skipped only where no step reaches pi)
    n, fs = 2000, FS
    t = (np.arange(n) - 1000) / fs
    f0 = fs * np.array([0.05, 0.17, 0.29, 0.333, 0.41, 0.45, 0.4999])
    W = np.exp(-0.5 * (t / 40e-6) ** 2)[None, :] * np.exp(2j * np.pi * f0[:, None] * (t + 0.37e-6))
    arr = waves.arrival_times(W.astype(np.complex64), fs, f0, waves.Wavelet(2.0, 1.0), t0_index=1000,
                              min_rel_db=-300.0)
    np.testing.assert_allclose(arr.inst_freq_hz, f0, rtol=1e-5)
    np.testing.assert_allclose(arr.times_s, 0.0, atol=1e-9)
