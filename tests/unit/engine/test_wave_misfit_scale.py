"""merge.misfit_scale: sigmas scaled by the Birge ratio of a curve's points about its smooth curve
(issue 24, session 29). The curves are analytic (numpy), not labid's models: a flat-ish S0-like
curve and an A0-like sqrt(f / (f + f0)) rise over 2.7 octaves (the wide merged A0 curve the
piecewise fit exists for)."""
import numpy as np
import pytest

from engine.wavefeatures import merge


def s0_like(f):
    return 5200.0 * (1.0 - 0.06 * (f / 300e3) ** 2)


def a0_like(f):
    return 2100.0 * np.sqrt(f / (f + 80e3))


F_S0 = np.geomspace(150e3, 290e3, 30)        # under one octave, 30 points: one cubic, 26 dof
F_A0 = np.geomspace(47e3, 306e3, 22)         # the merged A0 sweep's span and point count


@pytest.mark.parametrize("curve, f, rel", [(s0_like, F_S0, 5e-4), (a0_like, F_A0, 2e-4)])
def test_noise_only_inflates_about_five_percent_of_the_time(curve, f, rel):
    """Points scattered by exactly their sigmas: chi2 follows chi2(dof), so the 95 % quantile is passed
    5 % of the time (binomial s.e. 0.7 % over 1000 draws); the scale is never below 1."""
    rng = np.random.default_rng(24)
    v = curve(f)
    s = rel * v
    ks = np.array([merge.misfit_scale(f, v + s * rng.standard_normal(f.size), s)[0] for _ in range(1000)])
    assert ks.min() >= 1.0
    assert 0.025 <= np.mean(ks > 1.0) <= 0.075
    assert np.percentile(ks, 99) < 1.6            # and by little when it does


def test_the_smooth_model_is_not_the_misfit():
    """The noiseless A0-like curve with 0.02 % sigmas (the preamp rig's best A0 points): the
    piecewise cubic's own residual is well under the sigmas (one cubic over the whole span is not)."""
    v = a0_like(F_A0)
    s = 2e-4 * v
    chi2, dof, _ = merge.birge_chi2(F_A0, v, s)
    assert np.sqrt(chi2 / dof) < 0.1
    chi2, dof, _ = merge.birge_chi2(F_A0, v, s, octaves=10.0)     # one cubic over 2.7 octaves
    assert np.sqrt(chi2 / dof) > 1.0


def test_alternating_bias_scales_by_its_rms_over_sigma():
    """+-0.3 % alternating bias, 0.05 % sigmas (and noise): the scale is the bias's rms over the
    sigma, rms(bias) / sigma = 6, within 20 % (the Birge ratio sqrt(chi2 / dof) expects
    sqrt(36 x 30 / 26 + 1) = 6.5 here: the cubic absorbs almost none of an alternating bias)."""
    rng = np.random.default_rng(7)
    v0 = s0_like(F_S0)
    bias = 3e-3 * v0 * (-1.0) ** np.arange(F_S0.size)
    s = 5e-4 * v0
    ks = [merge.misfit_scale(F_S0, v0 + bias + s * rng.standard_normal(F_S0.size), s, "S0 along 0 deg")
          for _ in range(50)]
    analytic = float(np.sqrt(np.mean((bias / s) ** 2)))
    assert all(abs(k / analytic - 1.0) < 0.2 for k, _ in ks)
    note = ks[0][1]
    assert note.startswith("S0 along 0 deg: its 30 points scatter") and "sigmas scaled by" in note


def test_never_shrinks_and_short_curves_are_left_alone():
    v = s0_like(F_S0)
    s = 5e-3 * v                                     # sigmas 100 x the (1e-5 relative) scatter
    rng = np.random.default_rng(1)
    assert merge.misfit_scale(F_S0, v * (1 + 1e-5 * rng.standard_normal(v.size)), s) == (1.0, "")
    f4 = F_S0[::8]                                   # 4 points: a line is all they allow; not judged
    assert merge.misfit_scale(f4, s0_like(f4) * (1 + np.array([0.01, -0.01, 0.01, -0.01])),
                              1e-4 * s0_like(f4)) == (1.0, "")
