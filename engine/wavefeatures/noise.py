"""One estimate of a wave record's noise std, for the picks' SNR test and sigmas
(``picks.noise_rms``) and the crosstalk bound (``crosstalk.noise_std``).

The record's wave-free parts are its pre-trigger samples (the first 0.8 x ``pre``) and its
last quarter (a record triggered on a sensor holds a packet, or the source, before its
trigger; one whose source is recorded ends quiet). Each is cut in 64-sample blocks; a part's
level is the MEDIAN of its blocks' std (a packet or a coda swell in fewer than half the blocks
does not move it), and the noise is the quieter part's. The smallest block's std, used before,
reads 17-22 % under white noise's std for 38-150 blocks (issue 24, session 27; the extreme of
many chi-distributed estimates), so every pick's sigma and every crosstalk bound was as much
too small. Units: those of the record.
"""
from __future__ import annotations

import numpy as np

__all__ = ["BLOCK", "noise_level"]

BLOCK = 64    # samples per block: the std of one block of white noise is good to ~9 %


def noise_level(x: np.ndarray, pre: int) -> tuple[float, float | None] | None:
    """(std, baseline) of record ``x`` whose first ``pre`` samples precede the trigger: the
    std is the quieter of the two parts' median block std (module docstring); the baseline is
    the median of the pre-trigger blocks' means when that part is the quieter (wave-free), else
    None (the caller's choice: a tail holds the coda, a slow swing off the baseline). None when
    neither part holds a 64-sample block."""
    x = np.asarray(x, float)
    m = int(0.8 * pre)
    levels = []
    for seg, head in ((x[:m], True), (x[-(len(x) // 4):], False)):
        blocks = [b for b in np.array_split(seg, max(len(seg) // BLOCK, 1)) if b.size >= BLOCK]
        if blocks:
            levels.append((float(np.median([np.std(b - b.mean()) for b in blocks])), head, blocks))
    if not levels:
        return None
    std, head, blocks = min(levels, key=lambda lv: lv[0])
    return std, (float(np.median([np.mean(b) for b in blocks])) if head else None)
