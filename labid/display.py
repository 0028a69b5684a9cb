"""Display-only transforms for the panel and the report (through ``labid.services``).

Computed from raw records and stored results, never written back: the
averaged hammer spectrum, the scalogram of a wave record with the analysis'
wavelet and band, SAFE group-velocity curves for nominal or identified
constants, the model frequencies of an identification. Picks, velocities and
constants themselves always come from the workflows' results.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from drivers.protocol import Record
from engine import modal, safe, waves
from engine.laminate import Laminate


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
