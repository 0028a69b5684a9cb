"""The simulated rig's wave records against the transfer they are made from (issue 24, session 26).

A lead broken on the edge of a 1 mm aluminium plate (ORACLES.md constants), the plate's S0
transfer from the INDEPENDENT Legendre model (bench/bench_unknown_plate.independent_transfer,
no engine.safe in the transfer), synthesised by the rig's own chain (``mock_hw.waves._wave_fine``:
FFT, causality cut) at 20 and 40 cm, no noise, no reflections. The pair delay read by a numpy
envelope (zero-phase Butterworth band-pass, Hilbert envelope peak) must be the transfer's own
group-delay difference d(arg H)/d omega. Session 25's records failed this (+1.6 .. +1.9 % on the
bench CFRP at 55-75 kHz): the independent transfer was 0 below the Legendre table's reach (S0 from
~5 kHz here), and the causality cut turned that spectral edge's ringing into a bias.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal, special

from bench.bench_unknown_plate import independent_transfer
from engine.laminate import Laminate, Material, Ply
from mock_hw import waves as mw

E, NU, RHO, H = 70e9, 0.33, 2700.0, 1e-3
CP = np.sqrt(E / (RHO * (1 - NU ** 2)))              # membrane (plate) velocity, m/s
FS, FMAX, N, PRE = 2e6, 400e3, 2048, 400              # the rigs' rate, band, record; pre-trigger samples
R1, R2 = 0.20, 0.40
LOAD = ("inplane", 0.0, (("top", 0.5), ("bottom", 0.5)))   # a lead broken on the edge (mock_hw.waves._load)


@pytest.fixture(scope="module")
def plate():
    return Laminate((Ply(Material.isotropic_from(E, RHO, nu=NU, name="al"), 0.0, H),))


@pytest.fixture(scope="module")
def records(plate):
    """Noise-free S0 strain records at R1, R2 (source at sample PRE), as the rig synthesises them."""
    out = []
    with mw.transfer_model("legendre_safe S0", lambda *a, **k: {"S0": independent_transfer(*a, **k)["S0"]}):
        for r in (R1, R2):
            y = mw._wave_fine(plate, ((r, 0.0, 1.0),), ("pencil", 1e-6), FS, mw.OVERSAMPLE * N, 0.0, FMAX, 0.0,
                              0.0, LOAD, "top", "legendre_safe S0")[::mw.OVERSAMPLE]
            out.append(np.concatenate([np.zeros(PRE), y]))
    return out


def envelope_peak(x, fc, lo, hi):
    """Time (s) of the Hilbert envelope's peak of x band-passed +-15 % around fc, within [lo, hi)
    samples, refined by a parabola through log."""
    sos = signal.butter(2, [0.85 * fc, 1.15 * fc], "bandpass", fs=FS, output="sos")
    e = np.abs(signal.hilbert(signal.sosfiltfilt(sos, x)))
    k = lo + int(np.argmax(e[lo:hi]))
    a, b, c = np.log(e[k - 1:k + 2])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) / FS


def group_delay(plate, r, fc):
    """The transfer's own group delay at fc (s): d arg H / d omega, central difference."""
    df = 1.0
    h = independent_transfer(plate, r, np.array([fc - df, fc + df]), load="inplane")["S0"]
    return np.angle(h[1] / h[0]) / (2 * np.pi * 2 * df)


def test_independent_transfer_reaches_down_to_the_static_limit(plate):
    """S0 of the in-plane force is the exact membrane strain -i k H1(kr) / (4 rho h c_p^2) also
    below the Legendre table's reach (S0 from ~5 kHz on a table to 400 kHz: it was 0 there)."""
    f = np.array([1e3, 3e3, 10e3, 25e3, FMAX])          # the table built to FMAX, as in the records
    got = sum(0.5 * independent_transfer(plate, R1, f, load="inplane", source_face=s)["S0"] for s in ("top", "bottom"))
    f, got = f[:-1], got[:-1]                           # fh <= 0.025 MHz mm: the membrane limit
    k = 2 * np.pi * f / CP
    want = -1j * k * special.hankel1(1, k * R1) / (4 * RHO * H * CP ** 2)
    assert np.abs(got / want - 1).max() < 0.01


@pytest.mark.parametrize("fc", [40e3, 70e3, 100e3, 150e3])
def test_record_pair_delay_is_the_transfers_group_delay(plate, records, fc):
    x1, x2 = records
    c = CP
    t1 = envelope_peak(x1, fc, PRE + int(0.5 * R1 / c * FS), PRE + int(2 * R1 / c * FS))
    t2 = envelope_peak(x2, fc, PRE + int(0.5 * R2 / c * FS), PRE + int(2 * R2 / c * FS))
    want = group_delay(plate, R2, fc) - group_delay(plate, R1, fc)
    assert (t2 - t1) / want - 1 == pytest.approx(0.0, abs=2e-3)
    # and causal: nothing before the plate velocity's arrival (0.9 r / c_p, minus the 400 kHz band's ringing)
    pk = np.abs(x1).max()
    assert np.abs(x1[:PRE + int((0.9 * R1 / c - 5e-6) * FS)]).max() < 1e-3 * pk
