"""The wave band is judged on what is picked: the far sensor's first group of averaged shots
(``labid.workflows.wave_analysis``; issue 24, session 29). Numpy-made records on the built-in
rig's layout (pencil source, MFCs 5 / 20 cm, 2 MHz, 400 pre-trigger samples): a Gaussian
80 kHz packet in white noise of known std, so weak that one shot stands under the band
check's 20 dB and a group of 10 (+10 dB: the noise std falls as 1 / sqrt(10)) over it."""
from __future__ import annotations

import numpy as np
import pytest

from drivers.protocol import Record
from engine.wavefeatures import pipeline as waves_pipeline
from engine.wavefeatures.pipeline import WaveSettings, analysis_band
from engine.wavefeatures.predict import SourceModel
from labid.inputs.rig import read_rig_text, rig_from_text
from labid.inputs.specimen import load_specimen
from labid.workflows.wave_analysis import wave_features

F0, SIGMA_F = 80e3, 25e3          # the packet's centre and spectral std (Hz)
NOISE = 1e-3                       # V, white
AMP = 2.2e-3                       # V: ~14 dB over the noise per shot in the band check (cmor2-1 peak)
DELAY = 100e-6                     # s, far sensor after the near one (15 cm at 1500 m/s)


@pytest.fixture(scope="module")
def rig():
    return rig_from_text(read_rig_text("default")[0], "builtin:default")


def _shots(rig, n, seed=0):
    d = rig.device("wave")
    fs, ns, pre = d.timing.rate_hz, d.timing.samples, d.timing.pretrigger
    t = (np.arange(ns) - pre) / fs
    tau = 1 / (2 * np.pi * SIGMA_F)

    def packet(t0):
        u = t - t0 - 4 * tau
        return AMP * np.exp(-0.5 * (u / tau) ** 2) * np.cos(2 * np.pi * F0 * u)
    clean = {"mfc1": 10 * packet(0.0), "mfc2": packet(DELAY)}
    rng = np.random.default_rng(seed)
    return [Record(data={k: v + rng.normal(0, NOISE, ns) for k, v in clean.items()}, channels=tuple(d.channels),
                   timing=d.timing, trigger=d.trigger, overload={"mfc1": False, "mfc2": False}) for _ in range(n)]


def _grid(rig, recs, monkeypatch):
    """(the grid handed to the picks or None, notes): ``measure_waves`` replaced by a stub."""
    seen = []

    def stub(setup, shots, freqs, settings):
        seen.append(np.asarray(freqs))
        return waves_pipeline.WaveResult((), {}, {}, None, None, ())
    monkeypatch.setattr(waves_pipeline, "measure_waves", stub)
    notes: list[str] = []
    wave_features(recs, rig, load_specimen("cfrp"), notes=notes)
    return (seen[0] if seen else None), notes


def _band_of(x, pre, fs):
    """The band check on one far-sensor record ``x`` (pencil source, the cfrp file's band)."""
    return analysis_band(load_specimen("cfrp").laminate, fs, WaveSettings(), None, pre,
                         source=SourceModel("pencil", duration_s=1e-6), record=x[pre:], noise=x[:int(0.8 * pre)])


def test_a_hundred_shots_get_the_band_their_groups_hold(rig, monkeypatch):
    """100 shots: picked in 10 groups of 10; the band is found on a group's mean (it holds the
    packet's centre), where one raw shot's check finds none (the check before session 29)."""
    recs = _shots(rig, 100)
    grid, notes = _grid(rig, recs, monkeypatch)
    assert grid is not None and grid.size > 0, notes
    assert grid[0] < F0 < grid[-1]
    pre, fs = rig.device("wave").timing.pretrigger, rig.device("wave").timing.rate_hz
    assert _band_of(recs[0].scaled("mfc2"), pre, fs).empty.startswith("no velocity")
    group = np.mean([r.scaled("mfc2") for r in recs[:10]], axis=0)
    assert not _band_of(group, pre, fs).empty


def test_twelve_shots_are_picked_one_by_one_so_their_mean_does_not_set_the_band(rig, monkeypatch):
    """12 shots are not averaged (a curve per shot): the band is one shot's, empty here, though
    the mean of all 12 would pass (it would overstate the SNR the picks see)."""
    recs = _shots(rig, 12, seed=1)
    grid, notes = _grid(rig, recs, monkeypatch)
    assert grid is None and any(n.startswith("no velocity") for n in notes), notes
    pre, fs = rig.device("wave").timing.pretrigger, rig.device("wave").timing.rate_hz
    assert not _band_of(np.mean([r.scaled("mfc2") for r in recs], axis=0), pre, fs).empty
