"""Forced transient response of a plate from SAFE modes (paper Eqs. 23-26).

Units: SI (N, m, s, Hz); strain dimensionless.

A normal force F(t) acts at a point (or along a line) of the top surface
z = +h/2, positive along +z; a sensor on the same surface at distance d
along ``direction_deg`` reads w (displacement), its time derivatives, or the
in-plane surface strain along the path, averaged over the sensor length.

Modal sum (residue theorem on the SAFE wavenumber integral, propagating
modes only, far from the source). With the real symmetric SAFE form of
:mod:`engine.safe.model` (w = i w~), M-normalised eigenvectors phi and
D_m = phi^T K~'(k_m) phi = 2 w c_g, the line-source response in the physics
convention exp(i(k x - w t)) is::

    w(x)   = i F phi_w^2      exp(i k x) / D_m
    u(x)   =   F phi_u phi_w  exp(i k x) / D_m,     eps_xx = du/dx

(phi at the top surface node). For a point source the plane wave
exp(ikx) becomes the exact cylindrical wave (k/2) H0(kr) for w, and
(k/2) i H1(kr) for the radial displacement u_r (eps_rr = du_r/dr); far from
the source this is sqrt(k / 2 pi r) exp(i(kr - pi/4)). The point-source
option uses this isotropic (axisymmetric) spreading along the chosen
direction: for anisotropic plates it ignores beam steering / the curvature
of the wave surface. The strain averaged over a sensor of length L centred
at d is exactly [u(d + L/2) - u(d - L/2)] / L.

Other loads and faces (``mode_transfer``): by reciprocity a tangential line force
F_x gives u = i F_x phi_u^2 exp(ikx) / D, w = -F_x phi_u phi_w exp(ikx) / D: the source
factor is phi at the loaded face along the force (phi_w for a normal force, phi_u for
an in-plane one), the receiver factor phi_u (u, strain) or i phi_w (w) at the sensor's
face. A bonded piezo disc of radius a is modelled as its pin force: a ring of radial
traction tau at r = a (total P = 2 pi a tau). Its order-1 Hankel transform is
tau a J1(k a), and the residues give u_r = P J1(k a) phi_u^2 (k/2) i H1(kr) / D and
w = P J1(k a) i phi_u phi_w (k/2) H0(kr) / D, i.e. the point-force expressions with the
source factor phi_w replaced by J1(k a) phi_u. Check (tested): at low frequency S0 is
the membrane wave and u_r = (i pi / 2) tau a J1(ka) H1(kr) / (rho h c_p^2) exactly. The
bottom face (z = -h/2) reads the SAFE mode shapes at the bottom node; no symmetry of
the laminate is assumed.

Near field: the propagating-mode sum alone is a far-field (k r >> 1)
approximation. For a point source its strain has a spurious near-field term
~ -h / (8 pi D k^2 r^2) ~ 1/f (from H1(kr)/(kr)), which a step force (F ~ 1/f)
turns into a strain growing linearly in time forever. transient_response
therefore adds to A0 its evanescent partner (k -> i k; Kirchhoff structure:
H_n(kr) -> (2i/pi) K_n(kr) for a point source, exp(ikx) -> i exp(-kx) for w and
-exp(-kx) for u for a line), which cancels it and makes A0 tend to the full
Kirchhoff Green's function at low frequency (to O((kh)^2), tested). The
partner decays like exp(-k r), so only k r <~ 10 matters, i.e. kh << 1 where
this thin-plate form is accurate; higher evanescent modes (|k| ~ pi / h) are
neglected (d >> h). ``mode_transfer`` adds it only on request (near_field).
SAFE eigenvalues lambda = w^2 carry an absolute round-off (|lambda(0)|, ~1
rad^2/s^2), so below w_K = 100 sqrt(|lambda(0)|) (10-25 Hz) A0 is continued
by its thin-plate law from w_K (k ~ w^1/2, c_g ~ w^1/2): the DC handling
below integrates R down to f -> 0.

Time synthesis: y = int_0^t r dt', where r is the response to dF/dt, whose
spectrum R = H G is finite for steps (G = FT of dF/dt) and, with the near
field, integrable at f = 0 for v, a and strain (point strain R ~ ln f: the
strain of an infinite plate under a point step grows like
(F h / 16 pi D) ln t, a line step like sqrt(t); a free infinite plate has no
static state). The DFT of R / (i w) gives the antiderivative except for the
DC bin of r, which is restored as the mean of Re R over the DC bin's half
width (quadrature in ln f, asymptote below 3 % of it); the lowest
N_LOW_BINS bins use Gauss-Legendre bin averages of R instead of midpoint
values (R is singular at 0). The one
remaining constant of integration makes the record vanish before the first
possible arrival (t < 0.9 (d - L/2) / c_max, c_max = 1.2 x the fastest bulk
wave speed); nothing is extrapolated. Displacement (its R ~ 1/f for a
point source is not integrable: a net force makes an infinite plate drift,
w ~ t) is the time integral of v: a second antiderivative of the same
spectra plus R0 t^2 / 2 and the constant of v times t, and its own constant.
Two FFT grids, split by a complementary cos^2 crossover over
[8, 16] / t_rec (t_rec = record length): the low part, which holds the
singular DC behaviour and the slow ~1/t tails, uses a period of at least
PERIOD_RECORDS (32) records (few bins), so its wrap-around leaves
~ (pi^2 / 12)(t / T)^2 ~ 0.1 % of F h / (16 pi D) at the end of the record
(the pencil-lead strain follows the closed-form Kirchhoff step response to
0.2-0.7 % of its peak from 0.5 ms on, tested at 1 %); the high part uses the short period in
which its slowest component (A0 at the crossover) has passed. Each period
is extended until the slowest included component (smallest group velocity
over its band, usually A0 at its lowest bin) has crossed d before the period
ends; t = 0 is the force onset. The spectrum is tapered by a half cosine
over the top 10 % of the band below ``fmax_hz`` (default: the Nyquist
frequency or the force bandwidth, whichever is lower). No sensor high-pass
is applied: the record is the plate's strain (a real AC-coupled MFC/AE chain
would remove the slow ln t part; apply its filter to the record).
"""
from __future__ import annotations

import functools

import numpy as np

from ..laminate import Laminate
from .branches import dense_table, invert_table
from .forces import ForceHistory
from .model import TWO_PI, SafeError, ply_stiffness, safe_model
from .transfer import QUANTITIES, check_common, check_load, mode_data, transfer_from_data

__all__ = ["mode_transfer", "mode_velocities", "transient_response", "QUANTITIES"]

def _dc_bin_mean(R, half_width: float, log_tail: bool, n: int = 24, decades: float = 1.5) -> float:
    """(1 / a) int_0^a Re R(f) df, a = half_width, for R integrable but possibly singular
    at 0: trapezoid in ln f on [a 10^-decades, a] (SAFE eigenvalues lose relative accuracy
    towards f = 0, ~1 % in k at 1 Hz for a 1.6 mm CFRP), the rest [0, a 10^-decades] from
    the asymptote through the two lowest points: alpha + beta ln f (point source, the
    strain ~ ln f) or c f^p (line source, ~ f^-1/2)."""
    fq = half_width * np.logspace(-decades, 0.0, n)
    r = np.real(R(fq))
    s = np.sum(0.5 * (r[1:] * fq[1:] + r[:-1] * fq[:-1]) * np.diff(np.log(fq)))
    f0, f1 = fq[0], fq[1]
    if log_tail:
        beta = (r[1] - r[0]) / np.log(f1 / f0)
        tail = f0 * (r[0] - beta)                 # int_0^f0 (alpha + beta ln f) df
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.log(r[0] / r[1]) / np.log(f0 / f1) if r[0] * r[1] > 0 else 0.0
        p = p if np.isfinite(p) and p > -0.9 else 0.0
        tail = f0 * r[0] / (1.0 + p)
    return float((s + tail) / half_width)


BAND_RATIO = 400.0
N_LOW_BINS = 32       # bins integrated by Gauss-Legendre (singular spectra at f -> 0)
PERIOD_RECORDS = 32.0  # low-part FFT period, records: wrap-around of ~1/t tails ~ (pi^2/12)(1/32)^2


def _bands(laminate, direction_deg, fmax, f_floor, modes, order, elements_per_ply):
    """Frequency bands (f_lo, f_hi, data), top band first, each f_hi/f_lo = BAND_RATIO.

    Each band has its own discretisation and Chebyshev series on [0, k(f_hi)], so
    that low frequencies keep full relative accuracy (eigenvalue round-off is
    relative to the largest eigenvalue of the band).
    """
    out = []
    f_hi = fmax
    while True:
        f_lo = f_hi / BAND_RATIO
        if f_lo < f_floor:
            f_lo = 0.0
        model = safe_model(laminate, direction_deg, order=order, elements_per_ply=elements_per_ply,
                           fmax_hz=f_hi)
        out.append((f_lo, f_hi, mode_data(model, TWO_PI * f_hi, modes, strict=not out)))
        if f_lo == 0.0:
            return out
        f_hi = f_lo


def _transfer_bands(bands, f, distance_m, quantity, sensor_length_m, source,
                    near_field: bool = True, loss_factor: float = 0.0) -> np.ndarray:
    H = np.zeros(f.shape, complex)
    for f_lo, f_hi, data in bands:
        sel = (f > f_lo) & (f <= f_hi)
        if np.any(sel):
            H[sel] = sum(transfer_from_data(data, f[sel], distance_m, quantity, sensor_length_m,
                                             source, near_field, loss_factor).values(),
                         np.zeros(int(sel.sum()), complex))
    return H


def mode_transfer(laminate: Laminate, distance_m: float, frequency_hz, *, direction_deg: float = 0.0,
                  quantity: str = "displacement", sensor_length_m: float = 0.0, source: str = "point",
                  modes=None, order: int | None = None, elements_per_ply: int | None = None,
                  near_field: bool = False, loss_factor: float = 0.0, load: str = "normal",
                  actuator_radius_m: float = 0.0, source_face: str = "top",
                  sensor_face: str = "top", fmax_hz: float | None = None) -> dict:
    """Per-mode frequency response (per newton of force) at the sensor.

    Physics convention exp(i(k x - w t)); zero where a mode does not exist.
    ``load``: 'normal' (a point or line force along +z) or 'pin' (point source only: a
    bonded piezo disc of radius ``actuator_radius_m`` as a ring of radial surface traction,
    per newton of total ring force; module docstring). ``source_face`` / ``sensor_face``:
    'top' (z = +h/2) or 'bottom' (z = -h/2), read from the SAFE mode shapes at that face
    (exact for any laminate). The SAFE model of a direction is cached per top frequency
    (``fmax_hz``, default the grid's; rounded up to two significant digits so that nearby
    grids share it).
    Returns {label: complex array over frequency_hz}. Propagating modes only unless
    ``near_field``: then 'A0' also carries its evanescent partner (see the module
    docstring), needed wherever k r is not large (low frequencies, near the source).
    ``loss_factor`` eta: moduli C (1 + i eta), each mode attenuated by
    exp(-eta w x / (2 |c_g|)) (first order in eta; A0's near field too).
    """
    check_common(distance_m, quantity, sensor_length_m, source)
    check_load(load, actuator_radius_m, source_face, sensor_face, source, near_field)
    f = np.atleast_1d(np.asarray(frequency_hz, float))
    data = _cached_mode_data(laminate, float(direction_deg), order, elements_per_ply,
                             _model_top(max(float(f.max()), fmax_hz or 0.0)),
                             None if modes is None else tuple(sorted(modes)))
    return transfer_from_data(data, f, distance_m, quantity, sensor_length_m, source, near_field,
                               float(loss_factor), load, float(actuator_radius_m), source_face, sensor_face)


def mode_velocities(laminate: Laminate, frequency_hz, *, direction_deg: float = 0.0, modes=None,
                    fmax_hz: float | None = None) -> dict:
    """{label: (wavenumber rad/m, group velocity m/s)} over ``frequency_hz`` of every mode
    ``mode_transfer`` sums (NaN where a mode does not exist), from the same cached SAFE
    mode data (``fmax_hz``: its top, default the grid's): the wave packets' travel times
    at the cost of a table look-up. Group velocity d omega / dk from the Chebyshev series
    of lambda(k) (relative agreement with ``group_velocity`` ~1e-5)."""
    f = np.atleast_1d(np.asarray(frequency_hz, float))
    top = _model_top(max(float(f.max()), fmax_hz or 0.0))
    data = _cached_mode_data(laminate, float(direction_deg), None, None, top,
                             None if modes is None else tuple(sorted(modes)))
    w = TWO_PI * f
    out = {}
    for label, br, j, _cut in data:
        kt, lt, dt, _ = dense_table(br, j)
        k, i, t = invert_table(kt, lt, dt, w)
        cg = (dt[i] + t * (dt[i + 1] - dt[i])) / (2.0 * np.where(w > 0, w, 1.0))
        ok = np.isfinite(k) & (w > 0)
        out[label] = (np.where(ok, k, np.nan), np.where(ok, cg, np.nan))
    return out


def _model_top(fmax_hz: float) -> float:
    """``fmax_hz`` rounded up to two significant digits (the cache key of a SAFE model)."""
    e = 10.0 ** (np.floor(np.log10(fmax_hz)) - 1)
    return float(np.ceil(fmax_hz / e * (1 - 1e-12)) * e)


@functools.lru_cache(maxsize=32)
def _cached_mode_data(laminate: Laminate, direction_deg: float, order, elements_per_ply, fmax_hz: float,
                      modes):
    """``mode_data`` of the SAFE model along ``direction_deg`` up to ``fmax_hz`` (cached:
    every distance, face and load of one direction reuses it)."""
    model = safe_model(laminate, direction_deg, order=order, elements_per_ply=elements_per_ply,
                       fmax_hz=fmax_hz)
    return mode_data(model, TWO_PI * fmax_hz, modes)


def transient_response(laminate: Laminate, distance_m: float, force: ForceHistory, fs_hz: float,
                       n_samples: int, *, direction_deg: float = 0.0, quantity: str = "strain",
                       sensor_length_m: float = 0.0, source: str = "point",
                       fmax_hz: float | None = None, modes=None, order: int | None = None,
                       elements_per_ply: int | None = None, loss_factor: float = 0.0) -> np.ndarray:
    """Sensor record (n_samples at fs_hz, t = 0 at force onset) for a surface normal force.

    quantity: 'displacement' (w, m), 'velocity' (m/s), 'acceleration' (m/s^2) or
    'strain' (surface strain along the path averaged over sensor_length_m).
    ``modes`` restricts the sum to some labels (e.g. ("A0",)). ``loss_factor`` eta:
    viscoelastic moduli C (1 + i eta), mode m attenuated by exp(-eta w d / (2 |c_g,m|)).
    No sensor high-pass: apply the sensor chain's filter to the record. See the module
    docstring for conventions, near field, DC handling, padding and the point-source model.
    """
    from scipy.fft import irfft, next_fast_len  # here: the dispersion curves import no scipy
    check_common(distance_m, quantity, sensor_length_m, source)
    if not (np.isfinite(loss_factor) and 0.0 <= loss_factor < 1.0):
        raise SafeError(f"loss factor {loss_factor!r}: expected 0 <= eta < 1")
    if not (fs_hz > 0 and int(n_samples) >= 1):
        raise SafeError(f"fs={fs_hz!r} Hz, n_samples={n_samples!r}: expected positive values")
    if not isinstance(force, ForceHistory):
        raise SafeError("force: expected a ForceHistory (hammer_force, pencil_lead_break, ...)")
    n_samples = int(n_samples)
    fmax = min(fs_hz / 2.0, force.bandwidth_hz()) if fmax_hz is None else float(fmax_hz)
    if not 0 < fmax <= fs_hz / 2.0 * (1 + 1e-12):
        raise SafeError(f"fmax {fmax_hz!r} Hz: expected 0 < fmax <= fs/2 = {fs_hz / 2:g} Hz")
    t_rec = n_samples / fs_hz
    T_max = 64 * t_rec
    bands = _bands(laminate, direction_deg, fmax, 1.0 / (16 * t_rec), modes, order, elements_per_ply)
    # padding: the slowest broadband component (a fundamental mode, A0 at the
    # lowest bin) must arrive within the FFT period. Narrow-band slow parts of
    # higher modes (near a cut-off, a zero-group-velocity point or a veering)
    # ring there and are not counted; the period is capped at 64 records.
    fl = np.geomspace(1.0 / T_max, fmax, 160)
    cg_low = np.full(fl.shape, np.inf)          # slowest fundamental c_g at f
    for f_lo, f_hi, data in bands:
        sel = (fl > f_lo) & (fl <= f_hi)
        for label, br, j, cut in data:
            if cut > 0 or not np.any(sel):
                continue
            kt, lt, dt, _ = dense_table(br, j, 1024)
            k, i, t = invert_table(kt, lt, dt, TWO_PI * fl[sel])
            cg = (dt[i] + t * (dt[i + 1] - dt[i])) / (2 * TWO_PI * fl[sel])
            cg_low[sel] = np.minimum(cg_low[sel], np.where(np.isfinite(k) & (cg > 0), cg, np.inf))
    cg_low = np.minimum.accumulate(cg_low[::-1])[::-1]       # slowest at or above f
    # w is synthesised as the time integral of v (its own R ~ 1/f is not integrable at DC)
    disp = quantity == "displacement"
    args = (distance_m, "velocity" if disp else quantity, sensor_length_m, source, True,
            float(loss_factor))
    G = force.derivative_spectrum
    reach = distance_m + sensor_length_m

    def period(T, f_slow=None):
        """Smallest period >= T in which the slowest component at or above f_slow
        (default: the lowest bin, 1/T) crosses the sensor before the period ends."""
        for _ in range(50):
            cmin = float(np.interp(np.log(f_slow or 1.0 / T), np.log(fl), cg_low))
            if not np.isfinite(cmin):
                break
            need = min(t_rec + force.duration_s + reach / cmin * 1.05, T_max)
            if need <= T * (1 + 1e-3):
                break
            T = need
        return T

    # Two grids. Low part (f < f2, everything singular at f = 0, slow ~1/t tails): a long
    # period (>= PERIOD_RECORDS records), few bins. High part (f > f1): the short period
    # of the old synthesis, in which its slowest component (A0 at f1) has passed. The
    # complementary cos^2 crossover over [f1, f2] = [8, 16] / t_rec sums to 1.
    f1, f2 = 8.0 / t_rec, 16.0 / t_rec
    if f2 > 0.5 * fmax:
        f1 = f2 = np.inf                                      # one (long) grid

    def spectrum(fb):
        taper = np.where(fb <= 0.9 * fmax, 1.0, 0.5 * (1 + np.cos(np.pi * (fb - 0.9 * fmax) / (0.1 * fmax))))
        cross = np.clip((fb - f1) / (f2 - f1), 0.0, 1.0) if np.isfinite(f1) else np.zeros(fb.shape)
        low = 0.5 * (1.0 + np.cos(np.pi * cross))            # 1 below f1, 0 above f2
        return taper, low

    # -- low part: y = int_0^t r, r = response to dF/dt (spectrum R = H G: finite for
    # steps, and integrable at DC for v, a and strain)
    T = period(max(PERIOD_RECORDS * t_rec, t_rec + force.duration_s))
    n_fft = next_fast_len(int(np.ceil(T * fs_hz)), real=True)
    n_out = n_fft
    df = fs_hz / n_fft
    f = np.arange(n_fft // 2 + 1) * df
    band = (f > 0) & (f <= min(fmax, f2))
    fb = f[band]
    taper, low = spectrum(fb)
    R = np.conj(_transfer_bands(bands, fb, *args)) * G(fb) * taper * low
    # the lowest bins: R may be singular at 0 (~ln f), so the bin average of R (4-point
    # Gauss-Legendre) replaces its midpoint value (the kernel exp(iwt)/(iw) - 1/(iw) of
    # y = int_0^t r is smooth over a bin)
    nl = min(N_LOW_BINS, fb.size)
    if nl:
        xg, wg = np.polynomial.legendre.leggauss(4)
        fq = (fb[:nl, None] + 0.5 * df * xg[None, :]).ravel()
        Rq = (np.conj(_transfer_bands(bands, fq, *args)) * G(fq)).reshape(nl, 4)
        R[:nl] = 0.5 * Rq @ wg * taper[:nl] * low[:nl]
    Y = np.zeros(f.shape, complex)
    Y[band] = R / (1j * TWO_PI * fb)
    y = irfft(Y, n=n_fft) * fs_hz
    tt = np.arange(n_fft) / fs_hz
    # the DFT drops r's DC bin; restore it as the mean of Re R over the bin's
    # half-width [0, df/2] (quadrature in ln f: R may be ~ln f or f^-1/2)
    R0 = df * _dc_bin_mean(lambda fq: np.conj(_transfer_bands(bands, fq, *args)) * G(fq),
                           df / 2.0, log_tail=source == "point")
    y = y + R0 * tt
    if disp:         # w = int_0^t v: periodic antiderivative of the DFT part + R0 t^2 / 2
        Y[band] = Y[band] / (1j * TWO_PI * fb)
        yw = irfft(Y, n=n_fft) * fs_hz + 0.5 * R0 * tt * tt
    # -- high part (zero near DC: its antiderivative decays after the waves have passed)
    if np.isfinite(f1):
        Th = period(max(2.0 * t_rec, t_rec + force.duration_s + 2.0 / (f2 - f1)), f1)
        nh = next_fast_len(int(np.ceil(Th * fs_hz)), real=True)
        fh = np.arange(nh // 2 + 1) * fs_hz / nh
        bh = (fh > f1) & (fh <= fmax)
        taper, low = spectrum(fh[bh])
        Yh = np.zeros(fh.shape, complex)
        Yh[bh] = (np.conj(_transfer_bands(bands, fh[bh], *args)) * G(fh[bh]) * taper * (1.0 - low)
                  / (1j * TWO_PI * fh[bh]))
        n_out = min(n_fft, nh)
        y = y[:n_out] + (irfft(Yh, n=nh) * fs_hz)[:n_out]
        tt = tt[:n_out]
        if disp:
            Yh[bh] = Yh[bh] / (1j * TWO_PI * fh[bh])
            yw = yw[:n_out] + (irfft(Yh, n=nh) * fs_hz)[:n_out]
    # t = 0 is the force onset: the one remaining unknown, the constant of
    # integration, makes the record vanish before the first possible arrival
    # (bound: 1.2 x the fastest bulk plane-wave speed, mode independent, so responses of
    # separate modes still add up). Nothing is extrapolated.
    c_max = 1.2 * max(float(np.sqrt(np.max(np.diag(C)[:3]) / p.material.density))
                      for p, C in zip(laminate.plies, ply_stiffness(laminate, direction_deg)))
    m = int(0.9 * (distance_m - sensor_length_m / 2) / c_max * fs_hz) if c_max > 0 else 0
    pre = lambda v: np.mean(v[:m]) if m >= 2 else v[0]
    c_v = pre(y)
    y = y - c_v
    if disp:                 # w = int_0^t (v - c_v): the same constant of v, then w's own
        yw = yw - c_v * tt
        y = yw - pre(yw)
    return y[:n_samples]
