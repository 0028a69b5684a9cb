"""SAFE dispersion against exact Rayleigh-Lamb values (ORACLES.md) and laminate symmetries."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from engine import safe
from engine.laminate import Laminate, Material, Ply, rotate_z, stiffness_3d
from engine.safe import SafeError, dispersion, group_velocity, safe_model
from engine.safe.branches import solve_full
from engine.safe.labels import branch_table
from engine.safe.model import class_bases, coupling

# ---- ORACLES.md: exact Rayleigh-Lamb, aluminium E=70 GPa, nu=0.33, rho=2700, h=1 mm
AL = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="Al")
AL_PLATE = Laminate((Ply(AL, 0.0, 1e-3),))
FH = np.array([0.1, 0.5, 1.0, 2.0]) * 1e6          # Hz for h = 1 mm
TABLE = {
    "A0": ([954.234, 1878.339, 2326.643, 2675.330], [1783.696, 2908.787, 3137.051, 3126.912]),
    "S0": ([5393.172, 5374.785, 5308.589, 4759.445], [5391.689, 5335.510, 5118.634, 3066.727]),
}
# ORACLES.md: Lame lambda = 51.448 GPa, mu = 26.504 GPa, rho = 2680, f h = 5 MHz mm
LAME_L, LAME_M = 51.448e9, 26.504e9
AL2 = Material.isotropic_from(LAME_M * (3 * LAME_L + 2 * LAME_M) / (LAME_L + LAME_M), 2680.0, G=LAME_M)
AL2_PLATE = Laminate((Ply(AL2, 0.0, 1e-3),))
KH = {"S0": 10.5718690013, "S1": 5.5959390213, "S2": 3.8674031595,
      "A0": 10.8167804532, "A1": 7.8648173322, "A2": 3.6180018886}

T300 = Material(E1=136.7e9, E2=9.0e9, nu12=0.30, G12=5.0e9, G13=5.08e9, G23=3.16e9,
                density=1560.0, name="T300")


def layup(angles, t=0.2e-3, mat=T300):
    return Laminate(tuple(Ply(mat, float(a), t) for a in angles))


@pytest.mark.parametrize("mode", ["A0", "S0"])
def test_rayleigh_lamb_table(mode):
    d = dispersion(AL_PLATE, FH)
    m = d.mode(mode)
    cp, cg = map(np.array, TABLE[mode])
    # the table has 7 significant digits: 1e-5 relative is far above its rounding
    np.testing.assert_allclose(m.phase_velocity_m_s, cp, rtol=1e-5)
    np.testing.assert_allclose(m.group_velocity_m_s, cg, rtol=1e-5)


def test_kh_roots_5mhzmm():
    d = dispersion(AL2_PLATE, np.array([5e6]))
    for label, kh in KH.items():
        got = d.mode(label).wavenumber_rad_m[0] * 1e-3
        assert abs(got - kh) < 1e-6, (label, got, kh)
    # exactly three symmetric and three antisymmetric Lamb modes propagate at 5 MHz mm
    lamb = [l for l in d.labels if not l.startswith("SH")]
    assert sorted(lamb) == sorted(KH)


def test_convergence_in_element_order():
    errs = []
    for p in (8, 10, 12, 14):
        d = dispersion(AL2_PLATE, np.array([5e6]), order=p, elements_per_ply=1)
        errs.append(max(abs(d.mode(l).wavenumber_rad_m[0] * 1e-3 - kh) for l, kh in KH.items()))
    assert all(b < a for a, b in zip(errs, errs[1:])), errs    # monotone towards the exact roots
    assert errs[0] > 1e-4 and errs[-1] < 1e-8, errs                # spectral (exponential) rate


def _rayleigh_lamb(f_hz, k, h, cl, ct):
    """Normalised residuals of the symmetric and antisymmetric Rayleigh-Lamb equations."""
    w = 2 * np.pi * f_hz
    p = np.lib.scimath.sqrt(w ** 2 / cl ** 2 - k ** 2)
    q = np.lib.scimath.sqrt(w ** 2 / ct ** 2 - k ** 2)
    a, b = (k ** 2 - q ** 2) ** 2, 4 * k ** 2 * p * q
    cp, sp, cq, sq = np.cos(p * h / 2), np.sin(p * h / 2), np.cos(q * h / 2), np.sin(q * h / 2)
    scale = abs(a) + abs(b)
    return abs(a * cp * sq + b * sp * cq) / scale, abs(a * sp * cq + b * cp * sq) / scale


def test_labels_follow_symmetry_through_crossings():
    """Every S mode satisfies the symmetric Rayleigh-Lamb equation and every A mode the
    antisymmetric one, at all frequencies up to 6 MHz mm (many crossings); SH_n is exact."""
    lam, mu, rho = LAME_L, LAME_M, 2680.0
    cl, ct = np.sqrt((lam + 2 * mu) / rho), np.sqrt(mu / rho)
    f = np.linspace(0.05e6, 6e6, 120)
    d = dispersion(AL2_PLATE, f)
    assert {"A0", "S0", "SH0", "A1", "S1", "SH1", "A2", "S2", "SH2", "SH3"} <= set(d.labels)
    for m in d.modes:
        ok = np.isfinite(m.wavenumber_rad_m)
        if m.label.startswith("SH"):
            n = int(m.label[2:])
            kx = np.sqrt((2 * np.pi * f[ok] / ct) ** 2 - (n * np.pi / 1e-3) ** 2)
            np.testing.assert_allclose(m.wavenumber_rad_m[ok], kx, rtol=1e-7)
            np.testing.assert_allclose(m.group_velocity_m_s[ok], ct ** 2 * kx / (2 * np.pi * f[ok]), rtol=1e-7)
            continue
        rs, ra = _rayleigh_lamb(f[ok], m.wavenumber_rad_m[ok], 1e-3, cl, ct)
        good, other = (rs, ra) if m.label[0] == "S" else (ra, rs)
        assert np.max(good) < 1e-6, (m.label, np.max(good))
        # away from the few points where both equations vanish, the other family is not satisfied
        assert np.median(other) > 1e-3, m.label


def test_cutoff_frequencies_are_thickness_resonances():
    d = dispersion(AL2_PLATE, np.array([5e6]))
    ct = np.sqrt(LAME_M / 2680.0)
    np.testing.assert_allclose(d.mode("SH1").cutoff_hz, ct / (2 * 1e-3), rtol=1e-9)
    np.testing.assert_allclose(d.mode("A1").cutoff_hz, ct / (2 * 1e-3), rtol=1e-9)   # u thickness-shear
    cuts = [m.cutoff_hz for m in d.modes[3:]]
    assert cuts == sorted(cuts) and d.labels[:3] == ("A0", "S0", "SH0")


def _eigvecs_full(model, k):
    A = model.K0 + k * model.K1 + k * k * model.K2
    return sla.eigh(A, model.M)


def test_symmetric_layup_along_symmetry_axis_separates_lamb_and_sh():
    lam = layup([0, 90, 90, 0])
    m = safe_model(lam, 0.0, order=5, elements_per_ply=1)
    assert m.info == {"mirror_symmetric": True, "sh_decoupled": True}
    assert [c.kind for c in m.classes] == ["S", "A", "SHs", "SHa"]
    _, V = _eigvecs_full(m, 2000.0)            # the unsplit problem
    ev = np.sum(V[1::3] ** 2, axis=0) / np.sum(V ** 2, axis=0)
    euw = (np.sum(V[0::3] ** 2, axis=0) + np.sum(V[2::3] ** 2, axis=0)) / np.sum(V ** 2, axis=0)
    assert np.all((ev < 1e-20) | (euw < 1e-20))         # each mode is pure SH or pure Lamb
    # along 30 deg the same layup couples them
    m30 = safe_model(lam, 30.0, order=5, elements_per_ply=1)
    assert m30.info["sh_decoupled"] is False and m30.info["mirror_symmetric"] is True
    _, V = _eigvecs_full(m30, 2000.0)
    ev = np.sum(V[1::3] ** 2, axis=0) / np.sum(V ** 2, axis=0)
    assert np.sum((ev > 1e-3) & (ev < 1 - 1e-3)) >= 3


def test_cross_ply_a0_direction_and_ply_swap():
    f = np.linspace(5e3, 300e3, 30)
    a = group_velocity(layup([0, 90, 90, 0]), f, "A0", 90.0)
    b = group_velocity(layup([90, 0, 0, 90]), f, "A0", 0.0)
    c = group_velocity(layup([0, 90, 90, 0]), f, "A0", 0.0)
    np.testing.assert_allclose(a, b, rtol=1e-9)
    assert np.min(np.abs(c / a - 1)) > 0.01        # outer 0-plies make it stiffer along 0 deg
    assert np.all(c > a)


def test_independent_of_elements_per_ply():
    lam = layup([0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0], t=1.3333e-4)
    f = np.linspace(5e3, 200e3, 40)
    d1 = dispersion(lam, f, order=5, elements_per_ply=1)
    d3 = dispersion(lam, f, order=5, elements_per_ply=3)
    assert d1.labels == d3.labels == ("A0", "S0", "SH0")
    for lbl in d1.labels:
        np.testing.assert_allclose(d1.mode(lbl).group_velocity_m_s, d3.mode(lbl).group_velocity_m_s, rtol=1e-7)


def test_reduced_solver_matches_full_newton():
    lam = layup([0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0], t=1.3333e-4)
    m = safe_model(lam, 20.0, fmax_hz=2e5)
    f = np.array([20e3, 80e3, 200e3])
    d = safe.dispersion_from_model(m, f)
    rows = {r["label"]: r for r in branch_table(m, 2 * np.pi * f.max())}
    for lbl in ("A0", "S0", "SH0"):
        r = rows[lbl]
        for i, fi in enumerate(f):
            k, cg = solve_full(m.classes[r["ci"]], 2 * np.pi * fi, r["j"], d.mode(lbl).wavenumber_rad_m[i])
            # the Rayleigh-Ritz reduction costs far less than the 1e-6 discretisation target
            assert abs(d.mode(lbl).wavenumber_rad_m[i] / k - 1) < 1e-8
            assert abs(d.mode(lbl).group_velocity_m_s[i] / cg - 1) < 1e-7


def test_group_velocity_is_dw_dk():
    """Eigenvector group velocity equals the slope of the computed w(k) (independent check)."""
    lam = layup([0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0], t=1.3333e-4)
    f0, df = 100e3, 1.0
    d = dispersion(lam, np.array([f0 - df, f0, f0 + df]), order=5)
    for lbl in d.labels:
        k = d.mode(lbl).wavenumber_rad_m
        slope = 2 * np.pi * 2 * df / (k[2] - k[0])
        assert abs(d.mode(lbl).group_velocity_m_s[1] / slope - 1) < 1e-6


def test_group_velocity_fast_path_and_smoothness():
    lam = layup([0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0], t=1.3333e-4)
    f = np.linspace(2e3, 200e3, 50)
    full = dispersion(lam, f).mode("A0").group_velocity_m_s
    fast = group_velocity(lam, f, "A0")
    np.testing.assert_allclose(fast, full, rtol=1e-9)
    # smooth in the constants: the second difference (curvature + noise) is far below
    # the first difference wherever G13 matters, and below 1e-8 c_g everywhere
    cg = [group_velocity(lam.with_params({"G13": 5.08e9 * (1 + e)}), f) for e in (-1e-4, 0.0, 1e-4)]
    d1, d2 = cg[2] - cg[1], cg[1] - cg[0]
    assert np.all(d1 > 0)                               # stiffer shear, faster A0
    sens = np.abs(d1) > 1e-5 * cg[1]
    assert sens.sum() > 30
    assert np.max(np.abs(d1 - d2)[sens] / np.abs(d1[sens])) < 1e-3
    assert np.max(np.abs(d1 - d2) / cg[1]) < 1e-8


def test_rotation_matches_laminate_rotate_z():
    C = stiffness_3d(T300)
    for t in (15.0, -45.0, 90.0):
        B = safe.bond_matrix(t)
        np.testing.assert_allclose(B @ C @ B.T, rotate_z(C, t), atol=1e-6 * np.abs(C).max())


def test_bad_input():
    with pytest.raises(SafeError):
        dispersion(AL_PLATE, [-1.0, 0.0])
    with pytest.raises(SafeError):
        group_velocity(AL_PLATE, [1e5], "A7")
    with pytest.raises(KeyError):
        dispersion(AL_PLATE, [1e5]).mode("Z0")


def test_non_symmetric_layup_labels():
    """[0/90] is not mirror symmetric: along 0 deg Lamb and SH still separate (A0 and S0 share
    a class), along 30 deg everything couples; the three fundamental modes keep their names."""
    lam = layup([0, 90], t=0.5e-3)
    f = np.linspace(2e3, 400e3, 40)
    m0 = safe_model(lam, 0.0, fmax_hz=f.max())
    assert [c.kind for c in m0.classes] == ["lamb", "sh"]
    m30 = safe_model(lam, 30.0, fmax_hz=f.max())
    assert [c.kind for c in m30.classes] == ["all"]
    for direction in (0.0, 30.0):
        d = dispersion(lam, f, direction)
        assert d.labels[:3] == ("A0", "S0", "SH0")
        a0, s0, sh0 = (d.mode(x).phase_velocity_m_s for x in ("A0", "S0", "SH0"))
        assert np.all(a0 < sh0) and np.all(sh0 < s0)          # flexural < quasi-shear < quasi-longitudinal
        assert a0[0] < 0.2 * a0[-1]                            # A0 is dispersive (c_p ~ sqrt(f))
        assert abs(s0[0] / s0[1] - 1) < 1e-3                   # S0 is not, at low frequency


@pytest.mark.slow
def test_many_modes_with_veering_match_full_newton():
    """Coupled class, many higher modes with veerings (CFRP along 30 deg to 1.5 MHz): the
    reduced solver (Chebyshev series or per-frequency fallback) matches full Newton."""
    lam = layup([0, 45, -45, 0, 45, -45, -45, 45, 0, -45, 45, 0], t=1.3333e-4)
    f = np.linspace(20e3, 1.5e6, 60)
    m = safe_model(lam, 30.0, fmax_hz=f.max())
    d = safe.dispersion_from_model(m, f)
    assert len(d.modes) >= 8
    rows = {r["label"]: r for r in branch_table(m, 2 * np.pi * f.max())}
    n = 0
    for mode in d.modes:
        r = rows[mode.label]
        for i in range(0, len(f), 7):
            k = mode.wavenumber_rad_m[i]
            if not np.isfinite(k):
                continue
            kf, cg = solve_full(m.classes[r["ci"]], 2 * np.pi * f[i], r["j"], k)
            assert abs(k / kf - 1) < 1e-7, (mode.label, f[i])
            assert abs(mode.group_velocity_m_s[i] / cg - 1) < 1e-6, (mode.label, f[i])
            n += 1
    assert n > 40


@pytest.mark.parametrize("angles,direction", [([0, 90, 90, 0], 0.0), ([0, 90, 90, 0], 30.0),
                                              ([0, 45, -45, -45, 45, 0], 0.0), ([0, 90], 0.0),
                                              ([0, 90], 20.0), ([30, -30], 0.0)])
def test_class_split_is_exact(angles, direction):
    """The classes found from ply data leave no coupling in K0, K1, K2, M; and where the
    split is refused, the coupling really exists."""
    lam = layup(angles)
    m = safe_model(lam, direction, order=4, elements_per_ply=1)
    Qs = class_bases(m.z_nodes, m.info["mirror_symmetric"], m.info["sh_decoupled"])
    mats = (m.K0, m.K1, m.K2, m.M)
    for a in range(len(Qs)):
        for b in range(a + 1, len(Qs)):
            assert max(coupling(X, Qs[a][1], Qs[b][1]) for X in mats) < 1e-13
    # the finer splits that were not used would leave coupling
    both = class_bases(m.z_nodes, True, True) if np.allclose(m.z_nodes, -m.z_nodes[::-1]) else None
    if not m.info["sh_decoupled"]:
        lamb = [q for k, q, _ in class_bases(m.z_nodes, False, True) if k == "lamb"][0]
        shq = [q for k, q, _ in class_bases(m.z_nodes, False, True) if k == "sh"][0]
        assert max(coupling(X, lamb, shq) for X in mats) > 1e-6
    if not m.info["mirror_symmetric"] and both is not None:
        sym, anti = [q for k, q, _ in class_bases(m.z_nodes, True, False)]
        assert max(coupling(X, sym, anti) for X in mats) > 1e-6


def test_dct1_is_scipys_dct_type_1():
    """The branch series' DCT-I on numpy's FFT equals scipy.fft.dct(type=1) (what it replaced)."""
    from scipy.fft import dct

    from engine.safe.branches import dct1
    rng = np.random.default_rng(3)
    for shape in ((2,), (33,), (65, 4), (257, 3, 2)):
        v = rng.standard_normal(shape) * 10.0 ** rng.uniform(-3, 3, shape)
        np.testing.assert_allclose(dct1(v), dct(v, type=1, axis=0), rtol=0, atol=1e-14 * np.abs(v).sum())


def test_dispersion_imports_no_scipy():
    """``labid dispersion`` starts without scipy at all (numpy's eigh and solve on this path;
    the transient's and the transfer functions' scipy imports are where they are used): scipy.linalg
    alone cost ~0.25 s CPU of the command's start-up (issue 29, session 26)."""
    import subprocess
    import sys
    code = ("import sys, labid.cli.main, labid.cli.dispersion\n"
            "from engine.safe import dispersion\n"
            "d = dispersion(__import__('labid.inputs.specimen', fromlist=['x']).load_specimen('cfrp').laminate,"
            " [1e5, 5e5, 1e6])\n"
            "print(len(d.modes), sorted(m for m in sys.modules if m.split('.')[0] in ('scipy', 'numpy.ma')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    n_modes, loaded = out.stdout.split(maxsplit=1)
    assert int(n_modes) >= 5          # the veering S0/SH0 of the [0/45/-45/90] class went through the fallback
    assert loaded.strip() == "[]"
