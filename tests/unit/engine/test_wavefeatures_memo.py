"""The shot memo of the wave pipeline (issue 29): a remembered shot is returned only for the
same wavelet, shot, stage and predictions; the first shot's scalograms pass between the stages
of one wavelet only, without the onset-dependent crosstalk terms."""
import numpy as np

from engine import waves
from engine.wavefeatures import memo
from engine.wavefeatures.picks import Direction, WaveSettings


def _direction() -> Direction:
    d = Direction(None, WaveSettings(), np.linspace(1e5, 2e5, 5), 0.0, [])
    d.scale, d.margin = {"A0": np.linspace(0.9, 1.1, 5)}, {"A0": 0.05}
    return d


def test_key_follows_every_input_of_a_shot():
    d, wl = _direction(), waves.Wavelet(2.0, 3.0)
    k = memo.key(d, wl, 0)
    assert memo.key(d, wl, 0) == k
    assert memo.key(d, wl, 1) != k
    assert memo.key(d, waves.Wavelet(2.0, 2.0), 0) != k
    d.strict = False
    assert memo.key(d, wl, 0) != k
    d.strict = True
    d.scale["A0"] = d.scale["A0"] * (1 + 1e-12)        # the last bit of one ratio
    assert memo.key(d, wl, 0) != k
    d.scale["A0"] = np.linspace(0.9, 1.1, 5)
    assert memo.key(d, wl, 0) == k
    d.margin["A0"] = 0.04
    assert memo.key(d, wl, 0) != k
    d.margin["A0"] = 0.05
    d.t0 = (-1e-5, 0.0)
    assert memo.key(d, wl, 0) != k


def test_first_shot_scalograms_pass_for_one_wavelet_without_crosstalk_terms():
    d, wl, other = _direction(), waves.Wavelet(2.0, 3.0), waves.Wavelet(2.0, 2.0)
    cache = {("ch1", wl): "W1", ("src", "force", wl): "S", ("drive", wl): "D", ("xt", "ch1", wl): "X"}
    memo.keep(d, memo.key(d, wl, 0), ("picks",), cache)
    assert d.memo[memo.key(d, wl, 0)] == ("picks",)
    got = memo.shot_cache(d, wl, 0)
    assert got == {("ch1", wl): "W1", ("src", "force", wl): "S"}
    got["new"] = 1                                   # a copy: the memo is not changed by the shot
    assert "new" not in memo.shot_cache(d, wl, 0)
    assert memo.shot_cache(d, wl, 1) == {}
    assert memo.shot_cache(d, other, 0) == {}
    memo.keep(d, memo.key(d, other, 0), ("picks",), {("ch1", other): "W2"})
    assert memo.shot_cache(d, wl, 0) == {}           # one wavelet's scalograms kept at a time
