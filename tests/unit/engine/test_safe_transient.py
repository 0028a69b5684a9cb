"""Forced SAFE transient response: thin-plate limits, kinematics, group delay, no wrap-around."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import hilbert
from scipy.special import hankel1, k0, k1, sici

from engine.laminate import Laminate, Material, Ply, abdh
from engine.safe import (ForceHistory, SafeError, dispersion, group_velocity, hammer_force, mode_transfer,
                         pencil_lead_break, tone_burst, transient_response)
from labid.inputs.specimen import load_specimen

AL = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="Al")
H = 1e-3
AL_PLATE = Laminate((Ply(AL, 0.0, H),))
D_PLATE = 70e9 * H ** 3 / (12 * (1 - 0.33 ** 2))
T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")
CFRP = Laminate(tuple(Ply(T300, float(a), 1.3333e-4)
                      for a in [0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0]))


def test_kirchhoff_limit_line_and_point_source():
    """A0 far field of a unit force tends to the Kirchhoff plate Green's functions as kh -> 0:
    line iF/(4 D k^3) e^{ikx}, point iF/(8 D k^2) H0(kr); surface strain/w = k^2 h/2."""
    f = np.array([500.0, 2e3, 8e3])
    x = 0.3
    k = dispersion(AL_PLATE, f).mode("A0").wavenumber_rad_m
    kh2 = (k * H) ** 2
    line = mode_transfer(AL_PLATE, x, f, quantity="displacement", source="line", modes=("A0",))["A0"]
    point = mode_transfer(AL_PLATE, x, f, quantity="displacement", source="point", modes=("A0",))["A0"]
    strain = mode_transfer(AL_PLATE, x, f, quantity="strain", source="line", modes=("A0",))["A0"]
    e_line = np.abs(line / (1j / (4 * D_PLATE * k ** 3) * np.exp(1j * k * x)) - 1)
    e_point = np.abs(point / (1j / (8 * D_PLATE * k ** 2) * hankel1(0, k * x)) - 1)
    e_kin = np.abs(strain / line / (k ** 2 * H / 2) - 1)
    for e in (e_line, e_point, e_kin):
        assert np.all(e < kh2), (e, kh2)               # O((kh)^2) shear/rotary corrections
        assert e[0] < e[1] < e[2]                       # and they vanish as kh -> 0


def test_sensor_averaging_is_sinc_for_a_plane_wave():
    f = np.array([50e3, 150e3])
    L = 0.01
    h0 = mode_transfer(AL_PLATE, 0.3, f, quantity="strain", source="line", modes=("S0",))["S0"]
    hl = mode_transfer(AL_PLATE, 0.3, f, quantity="strain", source="line", modes=("S0",),
                       sensor_length_m=L)["S0"]
    k = dispersion(AL_PLATE, f).mode("S0").wavenumber_rad_m
    np.testing.assert_allclose(hl / h0, np.sinc(k * L / 2 / np.pi), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("quantity", ["strain", "acceleration"])
def test_tone_burst_envelope_travels_at_group_velocity(quantity):
    fc, fs = 100e3, 10e6
    burst = tone_burst(fc, 5)
    d = (0.10, 0.30)
    ys = [transient_response(CFRP, x, burst, fs, 6000, quantity=quantity, source="point",
                             fmax_hz=3 * fc) for x in d]
    tpk = [np.argmax(np.abs(hilbert(y))) / fs for y in ys]
    cg_env = (d[1] - d[0]) / (tpk[1] - tpk[0])
    cg = group_velocity(CFRP, [fc], "A0")[0]
    assert abs(cg_env / cg - 1) < 0.01, (cg_env, cg)


def test_causal_no_wraparound_and_velocity_is_dw_dt():
    fs, n, x = 10e6, 20000, 0.2          # oversampled: finite-difference error ~ (w dt)^2/6 < 3e-4
    force = hammer_force(20e-6)
    kw = dict(source="point", fmax_hz=200e3)
    w = transient_response(AL_PLATE, x, force, fs, n, quantity="displacement", **kw)
    v = transient_response(AL_PLATE, x, force, fs, n, quantity="velocity", **kw)
    a = transient_response(AL_PLATE, x, force, fs, n, quantity="acceleration", **kw)
    # nothing can arrive before the fastest mode (S0 plate speed) has crossed x
    c_max = 5500.0
    early = np.arange(n) / fs < 0.8 * x / c_max
    assert np.max(np.abs(a[early])) < 2e-3 * np.max(np.abs(a))
    for y in (w, v):      # the DC-drop offset is removed before the first arrival
        assert np.max(np.abs(y[early])) < 1e-2 * np.max(np.abs(y))
    # time derivatives (spectral differentiation in the record interior)
    dw = np.gradient(w, 1 / fs)
    dv = np.gradient(v, 1 / fs)
    sl = slice(50, n - 50)
    assert np.max(np.abs(dw[sl] - v[sl])) < 1e-3 * np.max(np.abs(v))
    assert np.max(np.abs(dv[sl] - a[sl])) < 3e-3 * np.max(np.abs(a))


def test_mode_restriction_superposes():
    fs, n = 2e6, 2000
    f = pencil_lead_break(2e-6)
    kw = dict(quantity="strain", source="line", fmax_hz=200e3)
    total = transient_response(CFRP, 0.2, f, fs, n, **kw)
    parts = sum(transient_response(CFRP, 0.2, f, fs, n, modes=(m,), **kw) for m in ("A0", "S0", "SH0"))
    np.testing.assert_allclose(parts, total, atol=1e-6 * np.max(np.abs(total)))
    a0 = transient_response(CFRP, 0.2, f, fs, n, modes=("A0",), **kw)
    assert np.max(np.abs(a0)) > 0.1 * np.max(np.abs(total))


def test_force_spectra_match_numerical_fourier_transform():
    for F in (hammer_force(50e-6, 3.0), pencil_lead_break(1e-6, 2.0), tone_burst(2e5, 3)):
        T = F.duration_s
        t = np.linspace(0.0, T, 200001)
        g = np.gradient(F(t), t)
        freqs = np.array([0.2, 0.5, 1.3, 2.7]) / T
        num = np.array([np.trapezoid(g * np.exp(-2j * np.pi * fr * t), t) for fr in freqs])
        got = F.derivative_spectrum(freqs)
        np.testing.assert_allclose(got, num, atol=1e-6 * np.max(np.abs(num)))
        # F = G / (i w), and the step keeps its final value
        np.testing.assert_allclose(F.spectrum(freqs), got / (2j * np.pi * freqs))
    assert pencil_lead_break(1e-6, 2.0)(1.0) == 2.0 and hammer_force(1e-4)(1.0) == 0.0
    s = ForceHistory.from_samples([0.0, 1e-6, 2e-6], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(s.derivative_spectrum(np.array([0.0])), [0.0], atol=1e-15)


def test_bad_arguments():
    f = hammer_force(1e-4)
    with pytest.raises(SafeError):
        transient_response(AL_PLATE, 0.2, f, 1e6, 100, quantity="stress")
    with pytest.raises(SafeError):
        transient_response(AL_PLATE, -0.2, f, 1e6, 100)
    with pytest.raises(SafeError):
        transient_response(AL_PLATE, 0.2, f, 1e6, 100, source="ring")
    with pytest.raises(SafeError):
        transient_response(AL_PLATE, 0.2, f, 1e6, 100, fmax_hz=2e6)
    with pytest.raises(SafeError):
        transient_response(AL_PLATE, 0.2, f, 1e6, 100, modes=("A9",))
    with pytest.raises(SafeError):
        hammer_force(0.0)


def test_point_source_strain_is_du_dr():
    """Averaging over a short sensor converges to the point strain as L^2 (exact d/dr of u_r)."""
    f = np.array([100e3, 800e3])
    h0 = mode_transfer(AL_PLATE, 0.05, f, quantity="strain", source="point", modes=("A0",))["A0"]
    e = [np.max(np.abs(mode_transfer(AL_PLATE, 0.05, f, quantity="strain", source="point", modes=("A0",),
                                     sensor_length_m=L)["A0"] / h0 - 1)) for L in (1e-3, 1e-4)]
    assert e[1] < 2e-2 * e[0] and e[1] < 1e-2      # ratio 100 for a 10x shorter sensor


def test_pencil_lead_strain_is_causal():
    """A step (the hardest case: its static part is not represented) still gives a record
    that stays ~0 until the fastest mode (S0) can have arrived."""
    fs, n, x = 5e6, 5000, 0.3
    y = transient_response(CFRP, x, pencil_lead_break(), fs, n, quantity="strain",
                           sensor_length_m=0.01, fmax_hz=1e6)
    c_s0 = dispersion(CFRP, np.array([1e3])).mode("S0").group_velocity_m_s[0]
    early = np.arange(n) / fs < 0.85 * (x - 0.005) / c_s0
    assert np.max(np.abs(y[early])) < 1e-2 * np.max(np.abs(y))
    late = np.arange(n) / fs > 1.05 * x / c_s0
    assert np.max(np.abs(y[late])) > 0.5 * np.max(np.abs(y))


# --- the quasi-static (low-frequency) part: near field and DC --------------------------
BETA_AL = np.sqrt(D_PLATE / (2700.0 * H))          # Kirchhoff sqrt(D / rho h), m^2/s
C_AL = H / (16 * np.pi * D_PLATE)                   # strain per newton per e-fold of t


def _kirchhoff_step_strain(t, r):
    """Surface radial strain eps_rr = -(h/2) w_rr at r of an infinite Kirchhoff plate under a
    unit point step force (closed form: w_r = -(r / 8 pi D) E(s), s = r^2 / 4 beta t,
    E(s) = int_s^inf sin(u)/u^2 du = sin(s)/s - Ci(s)); grows like ln t at late times."""
    s = r ** 2 / (4 * BETA_AL * t)
    return C_AL * (np.sin(s) / s - sici(s)[1] - 2 * np.sin(s) / s)


def _kirchhoff_impulse_strain(t, r):
    """The same for a unit impulse (d/dt of the above): decays like H / (16 pi D t)."""
    s = r ** 2 / (4 * BETA_AL * t)
    return H / (4 * np.pi * BETA_AL * 2700.0 * H * r ** 2) * (2 * s * np.cos(s) - np.sin(s))


def test_near_field_completes_the_kirchhoff_greens_function():
    """With near_field, A0 tends to the FULL Kirchhoff Green's functions, evanescent part
    included: point (i / 8 D k^2)[H0(kr) + (2i/pi) K0(kr)], line (i / 4 D k^3)[e^{ikx} + i e^{-kx}],
    down to k r < 1; the propagating term alone is wrong there (spurious 1/r^2 strain)."""
    f = np.array([20.0, 100.0, 500.0, 2e3, 8e3])
    r = 0.05
    k = dispersion(AL_PLATE, f).mode("A0").wavenumber_rad_m
    kr = k * r
    assert kr[0] < 0.5 and kr[1] < 1.1
    G = {"point": 1j / (8 * D_PLATE * k ** 2) * (hankel1(0, kr) + 2j / np.pi * k0(kr)),
         "line": 1j / (4 * D_PLATE * k ** 3) * (np.exp(1j * kr) + 1j * np.exp(-kr))}
    # eps = -(h/2) w_rr: (H0(kr))'' = -k^2 (H0 - H1/kr), (K0(kr))'' = k^2 (K0 + K1/kr)
    E = {"point": -(H / 2) * 1j / (8 * D_PLATE) * (-(hankel1(0, kr) - hankel1(1, kr) / kr)
                                                 + 2j / np.pi * (k0(kr) + k1(kr) / kr)),
         "line": -(H / 2) * 1j / (4 * D_PLATE * k) * (-np.exp(1j * kr) + 1j * np.exp(-kr))}
    for src in ("point", "line"):
        for q, ref in (("displacement", G[src]), ("strain", E[src])):
            got = mode_transfer(AL_PLATE, r, f, quantity=q, source=src, modes=("A0",), near_field=True)["A0"]
            e = np.abs(got / ref - 1)
            assert np.all(e < (k * H) ** 2), (src, q, e)
    far = mode_transfer(AL_PLATE, r, f, quantity="strain", source="point", modes=("A0",))["A0"]
    assert abs(far[0] / E["point"][0] - 1) > 0.5


@pytest.mark.parametrize("r", [0.07, 0.2])
def test_pencil_lead_strain_late_record_follows_kirchhoff(r):
    """A step force on an infinite plate: the strain at r tends to the closed-form Kirchhoff
    step response (log growth, no linear ramp) through the whole late record."""
    fs, n = 2e6, 8000
    y = transient_response(AL_PLATE, r, pencil_lead_break(), fs, n, quantity="strain")
    t = np.arange(n) / fs
    late = t >= 5e-4
    ref = _kirchhoff_step_strain(t[late], r)
    assert np.max(np.abs(y[late] - ref)) < 0.01 * np.max(np.abs(y)), np.max(np.abs(y[late] - ref))


def test_hammer_strain_tail_is_the_kirchhoff_impulse_response():
    """A half-sine tap (net impulse 2 F T / pi): after the waves the record decays like the
    Kirchhoff impulse response ~ 1/t (delayed by T/2), to the end of the record."""
    fs, n, Tc = 2e6, 8000, 50e-6
    t = np.arange(n) / fs
    for r in (0.1, 0.2):
        y = transient_response(AL_PLATE, r, hammer_force(Tc), fs, n, quantity="strain")
        late = t > 1e-3
        ref = 2 * Tc / np.pi * _kirchhoff_impulse_strain(t[late] - Tc / 2, r)
        assert np.max(np.abs(y[late] - ref)) < 5e-3 * np.max(np.abs(y))


def test_tone_burst_record_returns_to_zero():
    """Zero net impulse, narrow band: once the modes have passed, the record is ~0 to the end."""
    fs, n = 2e6, 8000
    y = transient_response(CFRP, 0.1, tone_burst(100e3, 5), fs, n, quantity="strain")
    t = np.arange(n) / fs
    assert np.max(np.abs(y[t > 1e-3])) < 1e-3 * np.max(np.abs(y))


def test_cfrp_pencil_lead_strain_has_no_ramp():
    """The reported case (specimen 'cfrp', 2 MHz, 8208 samples): the last quarter of the
    record sets no new maximum and has no trend (it was a linear ramp, 5.7e-6 at the end for
    a 1.2e-6 wave peak at 0.07 m); at 0.07 m it is quasi-static and grows like ln t with the
    Kirchhoff slope h / (16 pi D11) per e-fold (D11 from laminate theory, +-20 %: the point
    response of an anisotropic plate is not the isotropic one), not linearly."""
    lam = load_specimen("cfrp").laminate
    fs, n = 2e6, 8208
    h = sum(p.thickness for p in lam.plies)
    c = h / (16 * np.pi * abdh(lam).D[0, 0])
    for d in (0.07, 0.22):
        y = transient_response(lam, d, pencil_lead_break(), fs, n, quantity="strain")
        q = 3 * n // 4          # the last quarter: no new maximum, no trend
        assert np.max(np.abs(y[q:])) <= 1.2 * np.max(np.abs(y[:q]))
        assert abs(y[-1] - y[q]) < 0.35 * np.max(np.abs(y))
        if d == 0.07:
            d1, d2 = y[3 * n // 4] - y[n // 2], y[-1] - y[3 * n // 4]
            assert 0.8 < d2 / (c * np.log(n / (0.75 * n))) < 1.2, d2
            assert 0.8 < d1 / (c * np.log(1.5)) < 1.2, d1


def test_low_frequency_bands_follow_the_kirchhoff_flexural_law():
    """Below ~1 kHz (the lowest frequency band of transient_response, or dispersion with a
    low fmax) A0 along a symmetry axis of the symmetric CFRP follows D11 k^4 = rho h w^2
    (D11 from laminate theory); it used to come out NaN (wavenumber search started at
    eigenvalues below their round-off)."""
    lam = load_specimen("cfrp").laminate
    f = np.array([3.0, 30.0, 300.0, 999.0])
    rho_h = sum(p.thickness * p.material.density for p in lam.plies)
    k_kir = (rho_h * (2 * np.pi * f) ** 2 / abdh(lam).D[0, 0]) ** 0.25
    k = dispersion(lam, f).mode("A0").wavenumber_rad_m
    h = sum(p.thickness for p in lam.plies)
    assert np.all(np.abs(k / k_kir - 1) < 2e-3 + (k * h) ** 2)     # + shear/rotary O((kh)^2)
    # so the late (low-frequency) record does not depend on where the bands split
    fs, n = 2e6, 8208
    y = [transient_response(lam, 0.07, pencil_lead_break(), fs, n, fmax_hz=fm) for fm in (4e5, 9e5)]
    late = slice(n // 2, None)
    assert np.max(np.abs(y[0][late] - y[1][late])) < 0.03 * np.max(np.abs(y[1]))


def test_loss_factor_attenuation_matches_the_complex_modulus_plate():
    """Moduli E (1 + i eta): Kirchhoff A0 has k = (rho h w^2 / D (1 + i eta))^(1/4) and S0
    k = w sqrt(rho (1 - nu^2) / E (1 + i eta)); the amplitude ratio over x is exp(-|Im k| x)
    (eta k / 4 and eta k / 2: the attenuation follows the group, not the phase, velocity)."""
    eta, x = 0.02, 0.3
    f = np.array([2e3, 5e3])
    w = 2 * np.pi * f
    for mode, k in (("A0", (2700.0 * H * w ** 2 / (D_PLATE * (1 + 1j * eta))) ** 0.25),
                    ("S0", w * np.sqrt(2700.0 * (1 - 0.33 ** 2) / (70e9 * (1 + 1j * eta))))):
        h = [mode_transfer(AL_PLATE, x, f, quantity="strain", source="line", modes=(mode,),
                           loss_factor=e)[mode] for e in (0.0, eta)]
        np.testing.assert_allclose(np.abs(h[1] / h[0]), np.exp(-np.abs(k.imag) * x), rtol=3e-3)
    with pytest.raises(SafeError):
        transient_response(AL_PLATE, 0.2, hammer_force(1e-4), 1e6, 100, loss_factor=-0.1)


@pytest.mark.parametrize("r", [0.1, 0.2])
def test_displacement_follows_kirchhoff_plateau_and_drift(r):
    """w of an infinite plate: a tap (impulse I) leaves it displaced by ~I / (8 sqrt(D rho h))
    (impulse response (1 / 4 pi beta rho h)(pi/2 - Si(r^2 / 4 beta t))); a step makes it drift,
    w = int_0^t of that (the point mobility is real). The record follows both to its end."""
    fs, n, Tc = 2e6, 8000, 50e-6
    t = np.arange(n) / fs
    g = lambda tt: (np.pi / 2 - sici(r ** 2 / (4 * BETA_AL * tt))[0]) / (4 * np.pi * BETA_AL * 2700.0 * H)
    ts = np.linspace(1e-9, t[-1], 400001)
    gs = g(ts)
    drift = np.interp(t, ts, np.concatenate([[0.0], np.cumsum(0.5 * (gs[1:] + gs[:-1]) * np.diff(ts))]))
    late = t > 1e-3
    for force, ref in ((hammer_force(Tc), 2 * Tc / np.pi * g(np.maximum(t - Tc / 2, 1e-9))),
                       (pencil_lead_break(), drift)):
        w = transient_response(AL_PLATE, r, force, fs, n, quantity="displacement")
        assert np.max(np.abs(w[late] - ref[late])) < 2e-2 * np.max(np.abs(w))
        assert np.max(np.abs(w[t < 0.8 * r / 5500.0])) < 1e-3 * np.max(np.abs(w))     # causal


def test_line_step_strain_follows_kirchhoff_beam_response():
    """Line step force: strain grows like sqrt(t) (R ~ f^-1/2 at DC). Reference: the full
    Kirchhoff line-load strain (h / 8 D k)(i e^{ikx} + e^{-kx}) (near field included) inverted
    by direct quadrature, y(t) = (1/pi) Re int i (e^{-iwt} - 1) eps(w) / w dw, w = u^2."""
    fs, n, x = 2e6, 8000, 0.1
    y = transient_response(AL_PLATE, x, pencil_lead_break(), fs, n, quantity="strain", source="line")
    u = np.linspace(1e-7, np.sqrt(2 * np.pi * 5e4), 400001)
    om = u * u
    k = np.sqrt(om / BETA_AL)
    eps = H / (8 * D_PLATE * k) * (1j * np.exp(1j * k * x) + np.exp(-k * x))
    idx = np.array([1000, 2000, 3000, 4000, 6000, n - 1])
    ref = [np.trapezoid((2j * u * eps * (np.exp(-1j * om * i / fs) - 1) / om).real, u) / np.pi for i in idx]
    assert np.max(np.abs(y[idx] - ref)) < 1e-2 * np.max(np.abs(y)), (y[idx], ref)


# --------------------------------------------------------------------------- issue 14: piezo disc, faces
def test_pin_force_s0_is_the_membrane_wave_of_a_ring_of_radial_traction():
    """A bonded disc of radius a as its pin force: a ring of radial traction tau at r = a.
    At low frequency S0 is the membrane wave (plate speed c_p = sqrt(E / rho (1 - nu^2)))
    whose exact radial displacement outside the ring is
    u_r = (i pi / 2) tau a J1(k a) H1(k r) / (rho h c_p^2) (Helmholtz potential of the
    disc of body force); its strain is d u_r / dr. mode_transfer(load='pin') is per newton
    of total ring force 2 pi a tau. The relative error is O((k h)^2)."""
    from scipy.special import j1
    E, nu, rho, h = 70e9, 0.33, 2700.0, 3e-3
    plate = Laminate((Ply(Material.isotropic_from(E, rho, nu=nu, name="Al"), 0.0, h),))
    cp = np.sqrt(E / (rho * (1 - nu ** 2)))
    f = np.array([2e3, 5e3, 10e3])
    a, r = 5e-3, 0.3
    got = mode_transfer(plate, r, f, quantity="strain", load="pin", actuator_radius_m=a, modes=("S0",))["S0"]
    k = 2 * np.pi * f / cp
    tau = 1.0 / (2 * np.pi * a)
    ref = (1j * np.pi / 2 * tau * a * j1(k * a) * (k * hankel1(0, k * r) - hankel1(1, k * r) / r)
           / (rho * h * cp ** 2))
    err = np.abs(got / ref - 1)
    assert np.all(err < 2 * (k * h) ** 2) and err[0] < 1e-4, err


def test_bottom_face_mirrors_the_top_for_a_homogeneous_plate():
    """Mirror symmetry of a one-ply plate: in-plane strain on the bottom face is that on the
    top for the symmetric modes and its opposite for the antisymmetric ones (exact)."""
    f = np.array([20e3, 80e3, 150e3])
    kw = dict(quantity="strain", load="pin", actuator_radius_m=4e-3)
    top = mode_transfer(AL_PLATE, 0.2, f, **kw)
    bot = mode_transfer(AL_PLATE, 0.2, f, sensor_face="bottom", **kw)
    np.testing.assert_allclose(bot["S0"], top["S0"], rtol=1e-9)
    np.testing.assert_allclose(bot["A0"], -top["A0"], rtol=1e-9)
    # a top/bottom actuator pair driven in phase excites no A0 (and in anti-phase no S0)
    src_bot = mode_transfer(AL_PLATE, 0.2, f, source_face="bottom", **kw)
    assert np.max(np.abs(top["A0"] + src_bot["A0"])) < 1e-9 * np.max(np.abs(top["A0"]))
    assert np.max(np.abs(top["S0"] - src_bot["S0"])) < 1e-9 * np.max(np.abs(top["S0"]))
    with pytest.raises(SafeError):
        mode_transfer(AL_PLATE, 0.2, f, quantity="strain", load="pin")          # no radius


def test_mode_velocities_are_the_group_velocities():
    from engine.safe import mode_velocities
    f = np.linspace(20e3, 200e3, 12)
    mv = mode_velocities(CFRP, f, direction_deg=30.0)
    for m in ("A0", "S0", "SH0"):
        np.testing.assert_allclose(mv[m][1], group_velocity(CFRP, f, m, 30.0), rtol=1e-4)


@pytest.mark.parametrize("window", ["hann", "hamming", "rect"])
def test_tone_burst_windows(window):
    """amplitude w(t / T) sin(2 pi fc t): at the crest 2.25 cycles in, w(2.25 / N); zero at
    t = 0 for every window (sin 0)."""
    fc, n = 100e3, 5
    b = tone_burst(fc, n, 2.0, window=window)
    t = 2.25 / fc
    x = 2.25 / n
    w = {"hann": np.sin(np.pi * x) ** 2, "hamming": 0.54 - 0.46 * np.cos(2 * np.pi * x), "rect": 1.0}[window]
    assert float(b(t)) == pytest.approx(2.0 * w, rel=1e-3)
    assert float(b(0.0)) == 0.0
    with pytest.raises(SafeError):
        tone_burst(fc, n, window="kaiser")
