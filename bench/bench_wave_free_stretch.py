"""Issue 24, session 30 (h70): is a sensor record's stretch before its first possible arrival a
usable noise estimate where the record has no pre-trigger?

The crosstalk bound (``engine.wavefeatures.crosstalk._bound``) knows, per sensor, the sample of the
drive's onset ``k_on`` and of the first possible wave arrival ``k_first`` (distance / 1.5 x the
fastest nominal group velocity). The stretch [0, k_first) minus the drive's span (where the drive
exceeds 2 % of its peak: the crosstalk itself sits there) is wave-free by that geometry. Each
``coupling_bound`` call is traced: that stretch's 64-sample blocks, their median std, the noise the
bound used (``noise.noise_level``) and, on the real records, the truth.

Inputs:
- real: eriknbd/Lamb_wave_analisis @ a137a37a041fd01d747478ae596fd5a2031f289e,
  all_data/test_Al_tren_2105.mat, through bench/bench_real_line_scan.py (positions 0 / 45 mm, 8
  analyses; no pre-trigger; source distance and trigger ASSUMED by its rig). Truth (h67's): the
  45 mm record's first 900 samples' median 64-sample block std (before any wave arrives there).
- independent (optional, ``--pre PKL``): a pickled record list of the preamp sweep rig
  (bench/rigs/cfrp_pzt_sweep_2dir_far_pre.toml, 200 pre-trigger samples), first 80 shots (16 per
  burst), soft file (-40 %); the reference is the pre-trigger estimate the bound uses.

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_wave_free_stretch.py [--pre /tmp/lead29/pre/recs_soft_0.pkl]
"""
from __future__ import annotations

import contextlib
import io
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._machine import machine  # noqa: E402
from engine.wavefeatures import crosstalk  # noqa: E402
from engine.wavefeatures.noise import BLOCK, white_level  # noqa: E402

LOG: list[dict] = []
_CUR: dict = {}


def _blocks(seg: np.ndarray) -> list[float]:
    """The std of each whole 64-sample block of ``seg``."""
    return [float(np.std(seg[i:i + BLOCK])) for i in range(0, len(seg) - BLOCK + 1, BLOCK)]


def _traced_coupling(real):
    def coupling(x, drive, k_on, k_first, noise, k=3.0):
        x, e = np.asarray(x, float), np.asarray(drive, float)
        peak = float(np.max(np.abs(e))) if e.size else 0.0
        on = np.nonzero(np.abs(e) > 0.02 * peak)[0] if peak > 0 else np.array([0])
        d0, d1 = int(on[0]), int(on[-1]) + 1
        kf = min(int(k_first), len(x))
        free = _blocks(x[:max(min(d0, kf), 0)]) + (_blocks(x[d1:kf]) if kf > d1 else [])
        c = real(x, drive, k_on, k_first, noise, k)
        LOG.append(dict(dist=_CUR.get("dist"), n=len(x), fs=_CUR.get("fs"), blocks=len(free),
                        stretch=float(np.median(free)) if free else None,
                        noise=None if noise is None else noise[0], white=white_level(x, _CUR["fs"]) if _CUR.get("fs") else None,
                        c=c))
        return c
    return coupling


def _traced_bound(real):
    def bound(d, x, s, *rest):
        _CUR.update(dist=round(s.distance_m, 4), fs=d.setup.fs_hz)
        return real(d, x, s, *rest)
    return bound


def _table(rows: list[dict], truth: dict | None, key) -> None:
    groups: dict = {}
    for r in rows:
        groups.setdefault(key(r), []).append(r)
    print("  group | calls | stretch blocks | stretch x ref (>= 1 block) | (>= 4 blocks) | noise used x ref | white x ref")
    for g, rs in sorted(groups.items()):
        ref = truth[g[0]] if truth else None

        def rng(v):
            v = [a for a in v if a is not None]
            return "-" if not v else f"{min(v):.2f}-{max(v):.2f}"
        x = (lambda a, r: None if a is None else a / (ref if ref else r["noise"]))
        print(f"  {g} | {len(rs)} | {min(r['blocks'] for r in rs)}-{max(r['blocks'] for r in rs)} | "
              f"{rng([x(r['stretch'], r) for r in rs])} | {rng([x(r['stretch'], r) for r in rs if r['blocks'] >= 4])} | "
              f"{rng([x(r['noise'], r) for r in rs])} | {rng([x(r['white'], r) for r in rs])}")


def eriknbd() -> None:
    from scipy.io import loadmat

    from bench import bench_real_line_scan as line
    raw = subprocess.run(["git", "--git-dir", str(line.MIRROR), "show", f"{line.COMMIT}:{line.FILE}"], check=True,
                         capture_output=True).stdout
    mats = loadmat(io.BytesIO(raw))
    truth, per_n = {}, {}
    print("real, eriknbd: truth = the 45 mm record's first 900 samples (14 blocks)")
    for key in ("fss_0250kHz", "fss_0340kHz", "fss_0500kHz", "fss_0640kHz"):
        b = np.array(_blocks(mats[key][:900, 35]))
        f0 = int(key[4:8])
        truth[f0] = float(np.median(b))
        per_n[mats[key].shape[0]] = f0
        r = float(b.std() / b.mean())
        print(f"  {f0} kHz: {truth[f0] * 1e3:.3f} mV; block std spread {r:.2f} (white noise 0.089: ~{0.5 / r ** 2:.0f} "
              f"independent samples per block); blocks for a median within 10 % (1 sd, 1.25 x / sqrt(N)): "
              f"{int(np.ceil((1.25 * r / 0.10) ** 2))}")
    LOG.clear()
    with contextlib.redirect_stdout(io.StringIO()):
        line.main()
    print("per burst | sensor distance (m), x the truth:")
    _table([dict(r, f0=per_n[r["n"]]) for r in LOG], truth, lambda r: (r["f0"], r["dist"]))


def preamp(path: str) -> None:
    import pickle

    from bench.bench_unknown_plate import HERE, run_case
    from labid.inputs.rig import rig_from_text
    from labid.inputs.specimen import load_specimen
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = rig_from_text((HERE / "rigs" / "cfrp_pzt_sweep_2dir_far_pre.toml").read_text(), "pre")
    with open(path, "rb") as fh:
        recs = pickle.load(fh)[:80]
    LOG.clear()
    with contextlib.redirect_stdout(io.StringIO()):
        run_case("pre", rig, large, 80, 1 / 0.6, "independent", seed=0, recs=recs, trace=False)
    print(f"\nindependent, preamp sweep ({path}, 80 shots), per sensor distance (m), x the noise the bound used "
          "(its pre-trigger's median block std):")
    _table(LOG, None, lambda r: (r["dist"],))


def main() -> None:
    print(f"machine: {machine()}")
    crosstalk.coupling_bound = _traced_coupling(crosstalk.coupling_bound)
    crosstalk._bound = _traced_bound(crosstalk._bound)
    eriknbd()
    if "--pre" in sys.argv:
        preamp(sys.argv[sys.argv.index("--pre") + 1])


if __name__ == "__main__":
    main()
