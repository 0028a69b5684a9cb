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


def test_model_maxima_equal_the_slices_they_replace():
    """``predict.model_maxima`` against the per-frequency slices of ``arrivals_of`` (the old
    path): windows inside the model, cut at both ends, reaching the last sample of the last
    row, empty, and a non-finite input (left to the caller)."""
    from engine.wavefeatures.predict import Packet, model_maxima
    rng = np.random.default_rng(3)
    nf, m, step = 6, 40, 1e-6
    w = rng.random((nf, m)).astype(np.float32)
    dw = rng.random((nf, m)).astype(np.float32)
    nan = np.full(nf, np.nan)
    p = Packet("S0", "x=0", 0.3, nan, nan, nan, step, w, dw)
    rows = np.array([0, 1, 2, 3, 5])
    tau = np.array([10.2, -5.0, 30.0, 200.0, 38.7]) * step
    lo = np.array([-2.0, -1.0, -3.0, -1.0, -2.0]) * step
    hi = np.array([3.0, 2.0, 25.0, 1.0, 4.0]) * step
    mid = np.array([0.0, 0.0, np.nan, 0.0, 0.0]) * step
    ok, empty, amax, damax = model_maxima(p, rows, tau, lo, hi, mid)
    for j, i in enumerate(rows):
        k0 = np.floor((tau[j] - (hi[j] - mid[j])) / step)
        k1 = np.ceil((tau[j] - (lo[j] - mid[j])) / step)
        if not (np.isfinite(k0) and np.isfinite(k1)):
            assert not ok[j]
            continue
        k0, k1 = max(int(k0) - 1, 0), min(int(k1) + 1 + 1, m)
        assert ok[j] and empty[j] == (k1 - k0 < 1)
        if k1 - k0 >= 1:
            assert amax[j] == w[i, k0:k1].max() and damax[j] == dw[i, k0:k1].max()
    # inside; before the model starts; not finite; after it ends; to the last sample of the last row
    assert ok.tolist() == [True, True, False, True, True]
    assert empty[ok].tolist() == [False, True, True, False]
