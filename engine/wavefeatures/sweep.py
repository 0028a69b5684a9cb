"""One plate, several bursts: the sweep's bursts must agree on each mode's velocity (issue 24).

A tone-burst sweep measures ONE plate, so each burst's survey (stage 0,
``engine.wavefeatures.survey``) of a mode and direction finds the same measured / nominal
group-velocity ratio to within the plate's dispersion against the nominal's: the nominal
model carries the curve's shape, so a wrong set of constants moves the ratio slowly with
frequency (``BOUND``). A burst whose ratio disagrees with the others (at least two, agreeing
among themselves) by more than ``BOUND`` took another packet for the mode: on the 1 m plate
with the file 40 % soft, the 60 kHz burst's direct S0 at 40 cm was weak and inside the 83 us
drive, and its survey found the S0 echo off the far edge (0.54 x the nominal where the other
four bursts said 1.29-1.34 x); its picks then gave a point 58 % slow with a 0.7 % sigma, and
its mismatch line ("S0 arrives 85 % later") is not the sweep's either. That burst's curve of
that mode and direction is not merged, its mismatch line is not used, and a note says so.

The ratios are the surveys' own (``WaveResult.survey``, carried per burst in the info of
``labid.workflows.wave_analysis._wave_features_one``). Pure: dicts in. Units: Hz.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

__all__ = ["BOUND", "AGREE", "survey_ratios", "odd_bursts", "odd_note"]

#: a burst's ratio farther than this factor from the other bursts' median is another packet.
#: Measured (sweep rig, files -40 % and +40 %, seeds 0-2, 5 bursts 60-250 kHz): the bursts'
#: S0 ratios span at most 1.04 x (max / min) per direction, A0's 1.10 x (it drifts with
#: frequency: 1.20 at 60 kHz to 1.31 at 150 kHz); the mislabels were 2.4 x (seed 2: the
#: far-edge echo, 0.54 x) and 1.23 x (seed 0, 60 kHz: 1.59 x, no points).
BOUND = 1.2
#: the other bursts must agree among themselves within this factor (max / min) to be a reference
AGREE = 1.15


def survey_ratios(parts: Sequence) -> dict:
    """{(burst Hz, mode, direction deg): measured / nominal ratio} from the sweep's parts
    [(burst Hz, (features, curves, arrivals, extra, info))], info["survey"] as
    ``WaveResult.survey`` gives it."""
    return {(f, s["mode"], float(s["direction_deg"])): float(s["velocity_ratio"])
            for f, part in parts if f for s in part[4].get("survey", ())}


def odd_bursts(ratios: Mapping[tuple, float], bound: float = BOUND, agree: float = AGREE) -> dict:
    """{(burst, mode, direction): (its ratio, the others' ratios)} for each burst whose ratio of a
    mode and direction is farther than ``bound`` (a factor) from the median of the other bursts'
    when at least 2 others exist and agree within ``agree`` (max / min)."""
    by: dict = {}
    for (f, mode, d), r in ratios.items():
        by.setdefault((mode, d), {})[f] = r
    out = {}
    for (mode, d), per in by.items():
        for f, r in per.items():
            others = np.array([x for g, x in per.items() if g != f])
            if others.size < 2 or others.max() > agree * others.min():
                continue
            if abs(math.log(r / float(np.median(others)))) > math.log(bound):
                out[(f, mode, d)] = (r, tuple(float(x) for x in others))
    return out


def odd_note(key: tuple, value: tuple, parts: Sequence = ()) -> str:
    """The console line for one burst left out of a mode's merged curve (``odd_bursts``);
    ``parts``: the sweep's [(burst, (features, ...))], to say whether the burst had points."""
    (f, mode, d), (r, others) = key, value
    had = not parts or any(g == f and w["mode"] == mode and w["direction_deg"] == d for g, p in parts for w in p[0])
    cons = float(np.median(others))
    path = (f"at the others' velocity its packet travelled {cons / r:.2f} x the direct path: a reflection"
            if r < cons else "faster than the others' direct packet: not a packet of this mode")
    return (f"burst {f / 1e3:.4g} kHz: {mode} along {d:g} deg at {r:.2f} x the nominal, the other "
            f"{len(others)} bursts {min(others):.2f}-{max(others):.2f} x: not the direct {mode} ({path}); "
            + ("its points are not used" if had else "it gave no points; its ratio is not the sweep's"))
