"""Display-only transforms for the panel and the report (through ``labid.services``).

Computed from raw records and stored results, never written back: the
averaged hammer spectrum, the scalogram of a wave record with the analysis'
wavelet and band, SAFE group-velocity curves for nominal or identified
constants, the model frequencies of an identification. Picks, velocities and
constants themselves always come from the workflows' results. ``hammer_checks``: the force
of each hit with its double-hit and overload flags, per-channel H1 and coherence.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from drivers.protocol import Record
from engine import modal, safe, waves
from engine.laminate import Laminate

from .workflows.acquisition import double_hit


def average_spectrum(records: Sequence[Record]) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Display spectrum of hammer shots: the summed normalised indicator of ``engine.modal``
    over the accelerometer channels (H1 when a force is recorded): (f Hz, indicator, kind)."""
    if not records:
        return None
    r0 = records[0]
    acc = [c.name for c in r0.channels if c.kind == "accelerometer"] or [c.name for c in r0.channels]
    force = next((c.name for c in r0.channels if c.kind == "force"), None)
    x = np.array([[r.scaled(c) for c in acc] for r in records])
    F = np.array([r.scaled(force) for r in records]) if force else None
    spec = modal.spectra(x, r0.timing.rate_hz, F, pretrigger=r0.timing.pretrigger, channels=acc)
    return spec.frequencies_hz, modal.indicator(spec), spec.kind


@dataclass(frozen=True)
class Scalogram:
    """|CWT| of one channel of a record: ``magnitude`` (nf, n) on ``frequencies_hz`` x ``times_s``."""

    times_s: np.ndarray
    frequencies_hz: np.ndarray
    magnitude: np.ndarray
    wavelet: str


def scalogram(record: Record, channel: str, analysis: Mapping | None = None,
              n_freqs: int = 100) -> Scalogram:
    """The scalogram of ``channel`` with the wavelet and band of a stored analysis
    (``read_result(run, 'analysis')``); without one, cmor2-5 on fmax/20..fmax,
    fmax = min(200 kHz, 0.4 x rate)."""
    analysis = analysis or {}
    fs = record.timing.rate_hz
    wl = waves.Wavelet.from_name((analysis.get("arrivals") or {}).get("wavelet"), default=waves.PAPER_CFRP)
    band = (analysis.get("settings") or {}).get("wave_band_hz")
    if isinstance(band, (list, tuple, np.ndarray)) and len(band) == 2:
        fmin, fmax = float(band[0]), float(band[1])
    else:
        fmax = min(200e3, 0.4 * fs)
        fmin = fmax / 20
    freqs = np.linspace(fmin, fmax, n_freqs)
    W = np.abs(waves.cwt(record.scaled(channel), fs, freqs, wl))
    return Scalogram(record.time(), freqs, W, wl.name)


def model_group_velocity(laminate: Laminate, frequency_hz, mode: str = "A0", direction_deg: float = 0.0,
                         params: Mapping[str, float] | None = None) -> np.ndarray:
    """SAFE group velocity (m/s) of ``mode`` on ``frequency_hz`` for the nominal laminate,
    or with the constants ``params`` (e.g. identified) in place of its own."""
    lam = laminate.with_params(dict(params)) if params else laminate
    return np.asarray(safe.group_velocity(lam, frequency_hz, mode, direction_deg), float)


def model_frequencies(identification: Mapping | None) -> np.ndarray:
    """Natural frequencies (Hz) the identified model predicts for the modal data of an
    identification result (``read_result(run, 'identification')``)."""
    out: list[float] = []
    blocks = (identification or {}).get("blocks") if isinstance(identification, Mapping) else None
    if isinstance(blocks, Mapping):
        for b in blocks.values():
            if isinstance(b, Mapping) and b.get("kind") == "modal" and b.get("predicted") is not None:
                out.extend(np.atleast_1d(np.asarray(b["predicted"], float)))
    return np.asarray(out)


def parameters_of(identification: Mapping | None) -> dict[str, float]:
    """``{name: value}`` of an identification result ({} if none)."""
    params = (identification or {}).get("parameters") if isinstance(identification, Mapping) else None
    return {n: float(p["value"]) for n, p in (params or {}).items() if isinstance(p, Mapping) and "value" in p}


@dataclass(frozen=True)
class HammerChecks:
    """What a technician checks before trusting the hits of a run (issue 26).

    Per hit (in the run's order): its name, the force trace in N on ``times_s`` (s after the
    trigger), the peak force (N), a double-hit flag (two pulses above 10 % of the peak
    more than 0.5 ms apart, ``workflows.acquisition.double_hit``) and the channels that
    overloaded. Per response channel, over all the hits: |H1| in dB re 1 (unit)/N (``unit``:
    the channel's unit) and the ordinary coherence (None for a single hit), on
    ``frequencies_hz`` up to 0.4 x the rate (the anti-alias band)."""

    hits: tuple[str, ...]
    times_s: np.ndarray
    force_n: tuple[np.ndarray, ...]
    peak_n: tuple[float, ...]
    double_hit: tuple[bool, ...]
    overload: tuple[tuple[str, ...], ...]
    frequencies_hz: np.ndarray
    frf_db: dict
    coherence: dict | None
    units: dict


def hammer_checks(records: Sequence[Record], max_points: int = 4000) -> HammerChecks | None:
    """The checks of the hammer ``records`` (None without a record or a force channel)."""
    if not records:
        return None
    r0 = records[0]
    force = next((c.name for c in r0.channels if c.kind == "force"), None)
    if force is None:
        return None
    acc = [c.name for c in r0.channels if c.name != force]
    fs = r0.timing.rate_hz
    F = np.array([r.scaled(force) for r in records])
    x = np.array([[r.scaled(c) for c in acc] for r in records])
    spec = modal.spectra(x, fs, F, pretrigger=r0.timing.pretrigger, channels=acc)
    keep = spec.frequencies_hz <= 0.4 * fs
    step = max(1, int(keep.sum()) // max_points)
    f = spec.frequencies_hz[keep][::step]
    frf = {c: 20.0 * np.log10(np.maximum(np.abs(spec.frf[i][keep][::step]), 1e-300)) for i, c in enumerate(acc)}
    coh = None if spec.coherence is None or len(records) < 2 else {
        c: np.asarray(spec.coherence[i][keep][::step], float) for i, c in enumerate(acc)}
    return HammerChecks(tuple(str(r.meta.get("shot", i + 1)) for i, r in enumerate(records)), r0.time(),
                        tuple(F), tuple(float(np.max(np.abs(v))) for v in F),
                        tuple(double_hit(v, fs) for v in F),
                        tuple(tuple(n for n, ov in r.overload.items() if ov) for r in records),
                        f, frf, coh, {c: r0.channel(c).unit for c in acc})
