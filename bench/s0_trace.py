"""The per-shot S0 picks of a wave analysis, traced (one hook for the bench scripts that need it).

``s0_picks`` wraps ``engine.wavefeatures.pipeline._velocity`` inside a ``with`` block: every
stage-2 (strict) pick of S0 along ``direction_deg`` with a wavelet named ``wl_name`` ("all": any)
is logged per (wavelet name, record id) as a ``Pick`` (the last call for a record wins: the
measurement's own, after the first-shot candidates). With ``noise_part`` the sigma of each pick
before the foreign packets' shift bound joins it (``picks.arrivals_of``'s last ``replace``) is
kept too. Used by bench_sweep_shots.py, bench_wave_seeds.py (``shots``) and bench_s0_edge.py
(issue 24, sessions 27-29; they held near-copies of this hook). Units: s, Hz.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

from engine.wavefeatures import picks, pipeline


@dataclass(frozen=True)
class Pick:
    """One shot's S0 picks on the analysis grid: source-to-far-sensor delay and its sigma, validity,
    the far and source times and sigmas, the sigma's noise part (``noise_part``; else the sigma),
    the far pick's SNR (dB) and instantaneous frequency, and the shot's source channel record."""

    freqs: np.ndarray
    delay: np.ndarray
    sigma: np.ndarray
    valid: np.ndarray
    noise_sigma: np.ndarray
    far_t: np.ndarray
    far_s: np.ndarray
    src_t: np.ndarray
    src_s: np.ndarray
    snr_db: np.ndarray
    finst: np.ndarray
    source_record: np.ndarray | None


@contextlib.contextmanager
def s0_picks(wl_name: str = "all", direction_deg: float = 0.0, noise_part: bool = False):
    """Yields the log {(wavelet name, id(record)): Pick} filled while the block analyses."""
    log: dict = {}
    noise: dict = {}
    orig_v, orig_replace = pipeline._velocity, picks.replace

    def traced(d, mode, wl, rec, cache):
        g, out = orig_v(d, mode, wl, rec, cache)
        if mode == "S0" and d.direction == direction_deg and d.strict and wl_name in (wl.name, "all"):
            far, src = out["far"], out["source"]
            nf, ns = (noise.get(id(a), (a, a.sigma_s))[1] for a in (far, src))
            force = d.setup.force_channel
            log[(wl.name, id(rec))] = Pick(d.freqs.copy(), far.times_s - src.times_s, np.hypot(far.sigma_s, src.sigma_s),
                                           far.valid & src.valid, np.hypot(nf, ns), far.times_s, far.sigma_s,
                                           src.times_s, src.sigma_s, far.snr_db, far.inst_freq_hz,
                                           None if force is None else rec[force])
        return g, out

    def replace_traced(obj, **kw):
        new = orig_replace(obj, **kw)
        if "sigma_s" in kw and "reason" in kw:
            noise[id(new)] = (new, obj.sigma_s.copy())
        return new
    pipeline._velocity = traced
    if noise_part:
        picks.replace = replace_traced
    try:
        yield log
    finally:
        pipeline._velocity = orig_v
        picks.replace = orig_replace


def by_wavelet(log: dict) -> dict[str, list[Pick]]:
    """The log's picks grouped by wavelet name (sorted)."""
    out: dict = {}
    for (name, _), p in sorted(log.items(), key=lambda kv: kv[0][0]):
        out.setdefault(name, []).append(p)
    return out
