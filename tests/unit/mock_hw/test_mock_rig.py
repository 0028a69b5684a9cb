"""The simulated rig: exact modal response, plate FE peaks, ADC/trigger/filter laws, effects."""
from __future__ import annotations


import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import find_peaks

from drivers.protocol import Device, NoTrigger
from engine.plate import natural_frequencies
from labid.workflows.acquisition import double_hit
from labid.inputs.rig import load_rig, read_rig_text, rig_from_text
from labid.inputs.specimen import load_specimen
from mock_hw.rig import ALPHA_ISOTROPIC, Effects, SimulatedDevice, effective_laminate
from mock_hw.vibration import half_sine, modal_acceleration


@pytest.fixture(scope="module")
def cfrp():
    return load_specimen("cfrp")


def rig_with(*edits: tuple[str, str]):
    text, _ = read_rig_text("default")
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    return rig_from_text(text, "test-rig")


def shot(rig, spec, role="hammer", seed=0, effects=None, **kw):
    dev = SimulatedDevice(rig, spec, role, effects, seed, **kw)
    d = rig.device(role)
    dev.configure(d.channels, d.timing, d.trigger)
    dev.arm()
    return dev.read()


def test_modal_closed_form_matches_numerical_integration():
    """q'' of a damped oscillator under a half-sine force equals an ODE solution."""
    w, z, T = 2 * np.pi * 180.0, 0.02, 3e-4
    t = np.linspace(-1e-3, 0.02, 3001)
    a = modal_acceleration(t, np.array([w]), np.array([z]), T)[0]

    def rhs(tt, y):
        return [y[1], half_sine(np.array(tt), T) - 2 * z * w * y[1] - w * w * y[0]]

    tp = t[t >= 0]
    sol = solve_ivp(rhs, (0, tp[-1]), [0, 0], t_eval=tp, rtol=1e-10, atol=1e-16, max_step=T / 50)
    acc = half_sine(tp, T) - 2 * z * w * sol.y[1] - w * w * sol.y[0]
    assert np.max(np.abs(a[t >= 0] - acc)) < 1e-6 * np.max(np.abs(acc))
    assert np.all(a[t < 0] == 0)


def test_simulated_device_speaks_the_protocol(cfrp):
    assert isinstance(SimulatedDevice(load_rig(), cfrp, "hammer"), Device)


@pytest.mark.slow
def test_accelerometer_spectrum_peaks_at_plate_fe_frequencies(cfrp):
    """The strongest spectral peaks of an accelerometer record sit on the plate FE
    natural frequencies (computed here independently by engine.plate)."""
    from engine.plate import PlateModel
    rig = load_rig()
    model = PlateModel.build(cfrp.laminate, cfrp.length, cfrp.width).with_point_masses(
        [(c.x, c.y, c.mass_kg) for c in rig.accelerometers])     # the declared sensor masses
    fe = model.solve(12).frequencies_hz
    rec = shot(rig, cfrp)
    fs, df = rec.timing.rate_hz, rec.timing.rate_hz / rec.timing.samples
    total = 0
    for name in ("acc1", "acc2", "acc3"):
        x = rec.scaled(name)[rec.t0_index:]
        X = np.abs(np.fft.rfft(x, 8 * x.size))
        f = np.fft.rfftfreq(8 * x.size, 1 / fs)
        band = f < fe[-1] + 5
        pk, _ = find_peaks(X[band], prominence=0.05 * X[band].max())
        for fp in f[pk]:
            assert np.min(np.abs(fe - fp)) < 2 * df, (name, fp, fe)
        total += len(pk)
    assert total >= 12


def test_trigger_pretrigger_and_quantisation(cfrp):
    """Sample ``pretrigger`` is the first sample at/above the level; every sample is an
    integer number of ADC steps; pre-trigger noise has the rig's rms."""
    rig = load_rig()
    dev = rig.device("hammer")
    rec = shot(rig, cfrp, seed=3)
    f = rec.data["force"]
    pre, lv = rec.t0_index, dev.trigger.level_v
    assert f[pre] >= lv and np.all(f[pre - 20:pre] < lv)
    for c in rec.channels:
        lsb = 2 * c.range_v / 2**dev.adc_bits
        codes = rec.data[c.name] / lsb
        np.testing.assert_allclose(codes, np.rint(codes), atol=1e-6)
    noise = rec.data["acc1"][:pre - 20]
    assert abs(np.std(noise) / dev.noise_v - 1) < 0.25


def test_clipping_sets_overload_and_limits_to_range(cfrp):
    rig = rig_with(('sensitivity = 1.02e-3    # V/(m/s^2), 10 mV/g\nrange_v = 5.0',
                    'sensitivity = 1.02e-3\nrange_v = 0.05'))
    rec = shot(rig, cfrp)
    assert rec.overload["acc1"] and not rec.overload["force"]
    assert np.max(np.abs(rec.data["acc1"])) <= 0.05


def test_antialias_delay_is_the_filter_group_delay(cfrp):
    """A causal LTI filter shifts a pulse's centroid by its DC group delay (exact)."""
    rig = rig_with(("rate_hz = 10000.0", "rate_hz = 51200.0"),
                   ("noise_v = 2.0e-5", "noise_v = 0.0"))
    rec = shot(rig, cfrp)
    t = rec.time()
    x = rec.data["force"]
    win = (t > -1e-3) & (t < 5e-3)
    centroid = np.sum(t[win] * x[win]) / np.sum(x[win])
    expected = rec.meta["sim_onset_s"] + rig.hammer.contact_s / 2 + rec.meta["antialias_group_delay_s"]
    assert rec.meta["antialias_group_delay_s"] > 1 / 51200
    assert abs(centroid - expected) < 0.02 / 51200


def test_same_seed_same_records_other_seed_other_noise(cfrp):
    rig = load_rig()
    a, b, c = shot(rig, cfrp, seed=7), shot(rig, cfrp, seed=7), shot(rig, cfrp, seed=8)
    np.testing.assert_array_equal(a.data["acc2"], b.data["acc2"])
    assert not np.array_equal(a.data["acc2"], c.data["acc2"])


def test_double_hit_on_request_and_its_detection(cfrp):
    rig = load_rig()
    one, two = shot(rig, cfrp, double_hit=False), shot(rig, cfrp, double_hit=True)
    fs = one.timing.rate_hz
    assert two.meta["sim_double_hit"] and not double_hit(one.scaled("force"), fs)
    assert double_hit(two.scaled("force"), fs)


def test_missed_trigger_raises_notrigger(cfrp):
    rig = rig_with(("miss_probability = 0.0", "miss_probability = 1.0"))
    with pytest.raises(NoTrigger):
        shot(rig, cfrp)
    rig = rig_with(('channel = "force", level_v = 0.02', 'channel = "force", level_v = 4.9'))
    with pytest.raises(NoTrigger, match="never crossed"):
        shot(rig, cfrp)


def test_effects_parse_and_reject():
    e = Effects.parse("sensor_mass=0.003, temperature=10")
    assert e.active() == {"sensor_mass": 0.003, "temperature": 10.0}
    for bad in ("mass=1", "temperature=hot", "viscoelastic=-0.1", "thickness"):
        with pytest.raises(ValueError):
            Effects.parse(bad)


def test_temperature_and_thickness_scale_frequencies_exactly():
    """Isotropic plate: all moduli x (1 + a dT) -> every frequency x sqrt(1 + a dT);
    thickness x (1 + e) -> thin-plate frequencies x (1 + e) (Kirchhoff: f ~ h)."""
    al = load_specimen("aluminium")
    L, W = al.length, al.width
    f0 = natural_frequencies(al.laminate, L, W, n=6)
    fT = natural_frequencies(effective_laminate(al.laminate, Effects(temperature=20.0)), L, W, n=6)
    np.testing.assert_allclose(fT / f0, np.sqrt(1 + ALPHA_ISOTROPIC * 20.0), rtol=1e-6)
    fh = natural_frequencies(effective_laminate(al.laminate, Effects(thickness=0.02)), L, W, n=6)
    np.testing.assert_allclose(fh / f0, 1.02, rtol=2e-3)


@pytest.mark.slow
def test_sensor_mass_and_springs_put_the_peaks_on_the_modified_plate(cfrp):
    """With extra accelerometer mass (springs at the supports) the record's peaks
    follow the FE frequencies of the plate carrying them, not the nominal ones
    (the nominal plate carries the masses the rig file declares)."""
    from engine.plate import PlateModel
    rig = load_rig()
    bare = PlateModel.build(cfrp.laminate, cfrp.length, cfrp.width)
    accs = [(c.x, c.y, c.mass_kg) for c in rig.accelerometers]
    assert all(m > 0 for *_, m in accs)             # the rig declares its sensor masses
    model = bare.with_point_masses(accs)             # ... which are always on the plate
    cases = [(Effects(sensor_mass=0.02), bare.with_point_masses([(x, y, m + 0.02) for x, y, m in accs])),
             (Effects(support_stiffness=3e4), model.with_springs([(x, y, 3e4) for x, y in rig.supports]))]
    nominal = model.solve(4).frequencies_hz
    for eff, m in cases:
        fe = m.solve(4).frequencies_hz
        rec = shot(rig, cfrp, effects=eff)
        df = rec.timing.rate_hz / rec.timing.samples
        assert np.max(np.abs(fe - nominal)) > 4 * df            # the effect is visible
        spec = 0
        for name in ("acc1", "acc2", "acc3"):
            x = rec.scaled(name)[rec.t0_index:]
            spec = spec + np.abs(np.fft.rfft(x, 8 * x.size))
        f = np.fft.rfftfreq(8 * x.size, 1 / rec.timing.rate_hz)
        band = f < fe[-1] + 3
        pk, _ = find_peaks(spec[band], prominence=0.05 * spec[band].max())
        assert len(pk) >= 3
        for fp in f[pk]:
            assert np.min(np.abs(fe - fp)) < 2 * df, (eff, fp, fe)


def narrowband_envelope(x: np.ndarray, fs: float, f0: float, rel_bw: float) -> np.ndarray:
    """Envelope of x filtered by a Gaussian at f0 (std rel_bw f0), on 4x zero padding; the
    straight line through the end samples is removed first (no step at the record ends)."""
    x = x - np.linspace(x[0], x[-1], x.size)
    n = 4 * x.size
    X = np.fft.fft(x, n)
    f = np.fft.fftfreq(n, 1 / fs)
    G = np.where(f > 0, 2 * np.exp(-0.5 * ((f - f0) / (rel_bw * f0)) ** 2), 0)
    return np.abs(np.fft.ifft(X * G))


def envelope_peak_s(x: np.ndarray, fs: float, f0: float, rel_bw: float = 0.1) -> float:
    """Time (s from the first sample) of the narrow-band envelope peak of x at f0."""
    return float(np.argmax(narrowband_envelope(x, fs, f0, rel_bw)[:x.size])) / fs


def direct_only():
    """The default rig without edge reflections: the direct-path physics of the waves."""
    return rig_with(("wave_fmax_hz = 400.0e3", "wave_fmax_hz = 400.0e3\nreflections = 0"))


@pytest.fixture(scope="module")
def wave_shot(cfrp):
    return shot(direct_only(), cfrp, "wave", seed=5)


@pytest.mark.parametrize("f0", [30e3, 50e3, 100e3])
def test_mfc_arrivals_travel_at_the_safe_group_velocity(cfrp, wave_shot, f0):
    """Between the two MFCs (d = 0.05 and 0.20 m) the A0 packet at f0 takes
    (d2 - d1) / c_g(A0, f0); from the source (simulator onset) to mfc2 it takes
    d2 / c_g plus the anti-alias group delay."""
    from engine.safe import group_velocity
    rig, rec = direct_only(), wave_shot
    d1, d2 = rig.wave_sensor("mfc1").distance_m, rig.wave_sensor("mfc2").distance_m
    fs = rec.timing.rate_hz
    cg = float(group_velocity(cfrp.laminate, [f0], "A0")[0])
    t1 = envelope_peak_s(rec.data["mfc1"], fs, f0)
    t2 = envelope_peak_s(rec.data["mfc2"], fs, f0)
    assert abs((d2 - d1) / (t2 - t1) / cg - 1) < 0.02
    t_src = rec.t0_index / fs + rec.meta["sim_onset_s"]
    travel = t2 - t_src - rec.meta["antialias_group_delay_s"]
    assert abs(d2 / travel / cg - 1) < 0.02
    assert not any(rec.overload.values())


def test_timing_offset_and_path_length_effects_shift_the_wave(cfrp, wave_shot):
    """timing_offset delays the wave channels by exactly that time; path_length adds
    dL / c_g(f0) to the travel time."""
    from engine.safe import group_velocity
    rig, fs, f0 = direct_only(), wave_shot.timing.rate_hz, 50e3
    base = envelope_peak_s(wave_shot.data["mfc2"], fs, f0) - envelope_peak_s(wave_shot.data["mfc1"], fs, f0)
    late = shot(rig, cfrp, "wave", seed=5, effects=Effects(timing_offset=20e-6))
    # the trigger is on mfc1, which is delayed too: the shift shows against the source onset
    assert abs((late.meta["sim_onset_s"] - wave_shot.meta["sim_onset_s"]) + 20e-6) < 1.5 / fs
    far = shot(rig, cfrp, "wave", seed=5, effects=Effects(path_length=0.02))
    dt = envelope_peak_s(far.data["mfc2"], fs, f0) - envelope_peak_s(far.data["mfc1"], fs, f0)
    cg = float(group_velocity(cfrp.laminate, [f0], "A0")[0])
    assert dt == pytest.approx(base, abs=2 / fs)         # both sensors moved by 0.02 m
    t_src = lambda r: r.t0_index / fs + r.meta["sim_onset_s"]
    shift = (envelope_peak_s(far.data["mfc2"], fs, f0) - t_src(far)) - \
        (envelope_peak_s(wave_shot.data["mfc2"], fs, f0) - t_src(wave_shot))
    assert shift == pytest.approx(0.02 / cg, rel=0.1)


def test_viscoelastic_loss_attenuates_waves_by_exp_minus_eta_k_x_over_2(cfrp, wave_shot):
    """Narrow-band amplitude ratio at f0 between the lossy and the elastic plate at
    mfc2: exp(-eta k (d2) / 2) with k = 2 pi f0 / c_phase(A0)."""
    from engine.safe import dispersion
    rig, fs, f0, eta = direct_only(), wave_shot.timing.rate_hz, 50e3, 0.02
    lossy = shot(rig, cfrp, "wave", seed=5, effects=Effects(viscoelastic=eta))

    def amp(x):
        return narrowband_envelope(x, fs, f0, 0.05).max()

    cp = float(dispersion(cfrp.laminate, [f0]).mode("A0").phase_velocity_m_s[0])
    d2 = rig.wave_sensor("mfc2").distance_m
    expected = np.exp(-eta * 2 * np.pi * f0 / cp * d2 / 2)
    # the trigger (and so the window) may move; the amplitude ratio does not depend on it
    ratio = amp(lossy.data["mfc2"]) / amp(wave_shot.data["mfc2"])
    ratio *= wave_shot.meta["sim_force_peak_n"] / lossy.meta["sim_force_peak_n"]
    assert ratio == pytest.approx(expected, rel=0.05)


def test_sensor_aperture_averages_strain_like_sinc_k_l_over_2(cfrp, wave_shot):
    """A sensor of length L averages the A0 strain at wavenumber k over L: amplitude
    x sin(k L / 2) / (k L / 2) (exact for a plane wave)."""
    from engine.safe import dispersion
    rig, fs, f0, L = direct_only(), wave_shot.timing.rate_hz, 50e3, 0.008
    wide = shot(rig, cfrp, "wave", seed=5, effects=Effects(sensor_aperture=L))

    def amp(x):
        return narrowband_envelope(x, fs, f0, 0.05).max()

    k = 2 * np.pi * f0 / float(dispersion(cfrp.laminate, [f0]).mode("A0").phase_velocity_m_s[0])
    expected = np.sin(k * L / 2) / (k * L / 2)
    ratio = amp(wide.data["mfc2"]) / amp(wave_shot.data["mfc2"])
    ratio *= wave_shot.meta["sim_force_peak_n"] / wide.meta["sim_force_peak_n"]
    assert expected < 0.9 and ratio == pytest.approx(expected, rel=0.03)
