"""`labid analyze --pair-residue OTHER.h5` (issue 24, session 27): the copy of the other mode that a
collocated actuator pair leaves in a mode-separated run, measured at the far sensor and removed.

Records made here with numpy only (as tests/unit/engine/test_wave_pair.py): a 5-cycle 180 kHz Hann
burst; S0 a flat copy at 5300 m/s, A0 a flexural packet (group velocity 2900 m/s at 180 kHz,
~sqrt(f)) by FFT phase; top / bottom actuators unequal (the bottom's A0 0.7 at 20 deg of the
top's, S0 0.95); sensors B 0.12 m and D 0.42 m on one ray, the layout of Yeum et al. (2011).
Each run goes through `labid import` (the rig: bench/import_real/yeum_rig.toml, with the pair
named) and `labid analyze`; the specimen file is 32 % off (bench/import_real/yeum_al_nominal_off.toml).
"""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from labid.cli.main import main as labid
from tests.wave_signals import burst_of

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT / "bench" / "import_real"
FS, F0, CYC, PRE, N = 5.0e6, 180e3, 5, 300, 2400
C_S, C_A = 5300.0, 2900.0
A_B = 0.7 * np.exp(1j * np.radians(20.0))
R_TRUE = (1 - A_B) / (1 + A_B)


_burst = burst_of(N, FS, F0, CYC, PRE)     # _burst(delay_s=0.0)


def _a0(r: float) -> np.ndarray:
    f = np.fft.rfftfreq(N, 1 / FS)
    cp = 0.5 * C_A * np.sqrt(np.maximum(f, 1.0) / F0)
    return np.fft.irfft(np.fft.rfft(_burst()) * np.exp(-2j * np.pi * f * r / cp), N)


def _records(r: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """(S, A) = ((top + bottom) / 2, (top - bottom) / 2) at distance r, with a little noise."""
    s0 = _burst(r / C_S) / np.sqrt(r)
    a0 = _a0(r) / np.sqrt(r)
    top = s0 + a0
    bot = 0.95 * s0 - np.real(A_B * signal.hilbert(a0))
    noise = 1e-4 * rng.standard_normal((2, N))
    return (top + bot) / 2 + noise[0], (top - bot) / 2 + noise[1]


def _cli(argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = labid(argv)
    return code, out.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    rng = np.random.default_rng(11)
    (sb, ab), (sd, ad) = _records(0.12, rng), _records(0.42, rng)
    rig = (REAL / "yeum_rig.toml").read_text().replace("samples = 50000", f"samples = {N}").replace(
        "pretrigger = 4931", f"pretrigger = {PRE}")
    out = {}
    for kind, (xb, xd) in (("symmetric", (sb, sd)), ("antisymmetric", (ab, ad))):
        (d / f"rig_{kind}.toml").write_text(rig.replace('diameter_m = 0.010\n', f'diameter_m = 0.010\npair = "{kind}"\n'))
        for ch, x in (("B", xb), ("D", xd)):
            (d / f"{kind}_{ch}.csv").write_text(f"{ch}\n" + "\n".join(f"{v:.8g}" for v in x) + "\n")
        code, text = _cli(["import", str(d / f"{kind}_B.csv"), str(d / f"{kind}_D.csv"), "--rig",
                           str(d / f"rig_{kind}.toml"), "--specimen", str(REAL / "yeum_al_nominal_off.toml"),
                           "--out", str(d / f"{kind}.h5"), "--rate", "5e6", "--pretrigger", str(PRE),
                           "--units", "B=V,D=V", "--quiet"])
        assert code == 0, text
        out[kind] = d / f"{kind}.h5"
    return d, out


def _s0(path: Path):
    doc = json.loads(path.read_text())
    w = [w for w in doc.get("waves", []) if w["mode"] == "S0"]
    return (np.array(w[0]["group_velocity_m_s"]) if w else np.zeros(0)), doc["analysis"]["notes"]


def test_the_other_modes_copy_is_measured_and_removed(runs):
    d, run = runs
    # one wavelet (the one the automatic choice takes here): the candidates' search is not under test
    code, text = _cli(["analyze", str(run["symmetric"]), "--out", str(d / "f_raw.json"), "--wavelet", "2,3"])
    assert code == 0, text
    code, text = _cli(["analyze", str(run["symmetric"]), "--out", str(d / "f_clean.json"), "--wavelet", "2,3",
                       "--pair-residue", str(run["antisymmetric"])])
    assert code == 0, text
    raw, _ = _s0(d / "f_raw.json")
    clean, notes = _s0(d / "f_clean.json")
    note = next(n for n in notes if n.startswith("pair residue: r = "))
    r = float(note.split("r = ")[1].split()[0])
    assert r == pytest.approx(abs(R_TRUE), rel=0.05)
    # the S0 points of the cleaned run: within 0.5 % of 5300 m/s (the raw run's, if any, are not)
    assert clean.size >= 3 and np.all(np.abs(clean / C_S - 1) < 0.005)
    assert raw.size == 0 or np.max(np.abs(raw / C_S - 1)) > np.max(np.abs(clean / C_S - 1))


def test_a_missing_other_run_is_one_line(runs, tmp_path):
    d, run = runs
    code, text = _cli(["analyze", str(run["symmetric"]), "--out", str(tmp_path / "f.json"),
                       "--pair-residue", str(tmp_path / "nothing.h5")])
    assert code == 2 and "Traceback" not in text and len(text.strip().splitlines()) == 1
