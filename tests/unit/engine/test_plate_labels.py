"""Mode family labels (engine.plate.labels) against beam theory and Leissa's free plate."""
from __future__ import annotations

import numpy as np
import pytest

from engine.laminate import Laminate, Material, Ply
from engine.plate import PlateModel
from engine.plate.labels import beam_function, mode_families

AL = Material.isotropic_from(70e9, 2700.0, nu=0.33, name="Al")


def test_free_free_beam_functions_are_orthogonal_with_m_nodes():
    s = np.linspace(0.0, 1.0, 20001)
    B = np.array([beam_function(m, s) for m in range(8)])
    G = np.trapezoid(B[:, None, :] * B[None, :, :], s, axis=2)
    G = G / np.sqrt(np.outer(np.diag(G), np.diag(G)))
    assert np.max(np.abs(G - np.eye(8))) < 1e-6
    for m, b in enumerate(B):
        sg = np.sign(b[b != 0.0])
        assert int(np.sum(sg[1:] != sg[:-1])) == m


def test_narrow_strip_bending_modes_follow_the_free_free_beam():
    """A 10:1 strip: the (m,0) modes are beam modes, f ~ (beta_m L)^2 with beta_m L =
    4.7300, 7.8532, 10.9956 (roots of cos b cosh b = 1)."""
    model = PlateModel.build(Laminate((Ply(AL, 0.0, 0.002),)), 0.5, 0.05)
    modes = model.solve(8)
    labels = mode_families(model, modes, 0.5, 0.05)
    f = dict(zip(labels, modes.frequencies_hz))
    assert {"(2,0)", "(3,0)", "(4,0)", "(1,1) torsion"} <= set(labels)
    assert f["(3,0)"] / f["(2,0)"] == pytest.approx((7.8532046 / 4.7300408) ** 2, rel=0.01)
    assert f["(4,0)"] / f["(2,0)"] == pytest.approx((10.9956078 / 4.7300408) ** 2, rel=0.01)


def test_square_free_plate_mode_order_of_leissa():
    """Leissa's free square plate (ORACLES.md): the lowest mode (lambda 13.47) twists,
    the next two (19.60, 24.27) are the X and ring combinations of (2,0) and (0,2)."""
    lam = Laminate((Ply(Material.isotropic_from(200e9, 8000.0, nu=0.3), 0.0, 0.05),))
    model = PlateModel.build(lam, 10.0, 10.0)
    modes = model.solve(3)
    labels = mode_families(model, modes, 10.0, 10.0)
    assert labels[0] == "(1,1) torsion"
    assert all(set(lb.split("/")) == {"(2,0)", "(0,2)"} for lb in labels[1:3]), labels
