"""A pencil lead broken on the plate's edge (issue 24, session 25): an in-plane point force at
mid-thickness. Its S0 against the exact far field of the 2D elastodynamic (membrane) Green's
function, in labid's SAFE and in the independent Legendre model; its directivity per ray; the
rig key, one line and exit 2 when wrong."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import special

from bench.independent.legendre_safe import LegendrePlate, layers_of, transfer
from engine import safe
from engine.laminate import Laminate, Material, Ply
from engine.waves import ray_paths
from labid.cli.main import main
from mock_hw.waves import edge_rays

# ORACLES.md aluminium, 1 mm; at 20 kHz (fh = 0.02 MHz mm) S0 is the membrane wave, c_p^2 = E / (rho (1 - nu^2))
E, NU, RHO, H = 70e9, 0.33, 2700.0, 1e-3
F_HZ, R_M = np.array([15e3, 20e3, 25e3]), 0.3


def membrane_strain(f):
    """Radial strain per newton at R_M along an in-plane point force: the P part of the 2D
    Green's function, far field u_r = i H0(k r) / (4 rho h c_p^2) (Achenbach; plane stress),
    eps_rr = d u_r / dr = -i k H1(k r) / (4 rho h c_p^2)."""
    cp2 = E / (RHO * (1 - NU ** 2))
    k = 2 * np.pi * f / np.sqrt(cp2)
    return -1j * k * special.hankel1(1, k * R_M) / (4 * RHO * H * cp2)


def test_labid_safe_inplane_s0_is_the_membrane_green_function():
    lam = Laminate((Ply(Material.isotropic_from(E, RHO, nu=NU, name="al"), 0.0, H),))
    got = sum(0.5 * safe.mode_transfer(lam, R_M, F_HZ, quantity="strain", load="inplane", source_face=face)["S0"]
              for face in ("top", "bottom"))
    want = membrane_strain(F_HZ)
    assert np.abs(got / want - 1).max() < 0.01      # dispersion at fh = 0.025: ~1e-3


def test_independent_inplane_s0_is_the_membrane_green_function():
    G = E / (2 * (1 + NU))
    al = dict(E1=E, E2=E, E3=E, nu12=NU, nu13=NU, nu23=NU, G12=G, G13=G, G23=G, density=RHO)
    plate = LegendrePlate(layers_of([(al, 0.0, H)]), 6)
    got = sum(0.5 * transfer(plate, R_M, F_HZ, load="inplane", source_face=face)["mode2"] for face in ("top", "bottom"))
    assert np.abs(got / membrane_strain(F_HZ) - 1).max() < 0.01
    # the two faces in phase: the antisymmetric A0 cancels (a force at mid-thickness)
    a0 = sum(0.5 * transfer(plate, R_M, F_HZ, load="inplane", source_face=face)["mode0"] for face in ("top", "bottom"))
    assert np.abs(a0).max() < 1e-6 * np.abs(got).max()


def test_directivity_per_ray_and_the_own_edge_image():
    """cos(theta) from the force: 1 along it, 0 across it; the image in the edge the lead is
    broken on lies on the source, the same ray (factor of the direct); a face break: 1."""
    src = SimpleNamespace(kind="pencil", break_on="edge", force_deg=None, x=0.0, y=0.5)
    along = ray_paths((0.0, 0.5), (0.2, 0.5), 1.0, 1.0)
    w = dict(zip((p.name for p in along), edge_rays(src, along, (1.0, 1.0))))
    assert w["direct"] == pytest.approx(1.0) and w["x=0"] == pytest.approx(1.0)
    assert w["x=L"] == pytest.approx(1.0)            # leaves along the force, returns from x = L
    assert w["y=0"] == pytest.approx(0.2 / np.hypot(0.2, 1.0))   # leaves towards y = 0 at atan(1 / 0.2) off the force
    across = ray_paths((0.0, 0.5), (0.0 + 1e-9, 0.8), 1.0, 1.0)
    assert edge_rays(src, across, (1.0, 1.0))[0] == pytest.approx(0.0, abs=1e-6)
    face = SimpleNamespace(kind="pencil", break_on="face", force_deg=None, x=0.3, y=0.5)
    assert edge_rays(face, along, (1.0, 1.0)) == [1.0] * len(along)


RIG = """
[wave_source]
kind = "pencil"
break_on = {value}
x = 0.0
y = 0.1
[devices.scope]
role = "wave"
rate_hz = 2.0e6
samples = 1024
pretrigger = 100
trigger = {{ channel = "s1", level_v = 0.01 }}
[[devices.scope.channels]]
name = "s1"
sensitivity = 1.0
distance_m = 0.1
"""


@pytest.mark.parametrize("value, key", [('"side"', "break_on"), ('"face"\nforce_deg = 0.0', "force_deg")])
def test_a_bad_break_on_is_one_line_and_exit_2(tmp_path, capsys, value, key):
    p = tmp_path / "rig.toml"
    p.write_text(RIG.format(value=value))
    code = main(["acquire", "--rig", str(p), "--specimen", "aluminium", "--out", str(tmp_path / "r.h5")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and f"wave_source.{key}" in err[0] and "rig.toml" in err[0]


def test_sh0_takes_no_s0_surface_u_along_the_fibres_of_a_balanced_laminate():
    """The built-in [0/+45/-45]2s CFRP is balanced (A16 = 0): in-plane loads excite SH0 along 0 deg
    only through the weak coupling that grows with fh. labid's SAFE leaked S0's surface u into
    SH0 through the degenerate k = 0 node (SH0 / S0 at -25 dB at 20 kHz, session 25); the
    independent Legendre model gives -143 dB there and the same coupling at 300 kHz."""
    from labid.inputs.specimen import load_specimen
    from bench.bench_unknown_plate import independent_transfer
    lam = load_specimen("cfrp").laminate
    f = np.array([20e3, 50e3, 300e3])
    kw = dict(direction_deg=0.0, quantity="strain", load="pin", actuator_radius_m=0.005)
    ours = safe.mode_transfer(lam, 0.25, f, **kw)
    ratio = 20 * np.log10(np.abs(ours["SH0"]) / np.abs(ours["S0"]))
    assert ratio[0] < -80 and ratio[1] < -70
    ind = independent_transfer(lam, 0.25, f[2:], **kw)
    assert ratio[2] == pytest.approx(20 * np.log10(abs(ind["SH0"][0]) / abs(ind["S0"][0])), abs=2.0)
