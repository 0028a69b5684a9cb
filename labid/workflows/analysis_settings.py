"""The analysis's processing choices and the shot filter both its halves use
(``labid.workflows.analysis``: resonances; ``labid.workflows.wave_analysis``: guided waves)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from drivers.protocol import Record
from engine.wavefeatures.pipeline import WaveSettings

__all__ = ["AnalysisSettings", "usable_shots"]


@dataclass(frozen=True)
class AnalysisSettings:
    """Processing choices (None: automatic).

    modal_fmax_hz: top of the resonance search band (default 0.4 x rate).
    exp_tau_s: exponential window on the hammer records (None: none).
    force_window_s: force window length after the trigger (H1 only).
    indicator: 'sum' or 'cmif'.
    wavelet, wave_band_hz, n_wave_freqs, assign, min_wave_snr_db, gate_margin,
        leak_db, max_bias, min_wave_points, report_s0: the wave choices, with the defaults and
        meaning of ``engine.wavefeatures.pipeline.WaveSettings`` (wavelet, band_hz, n_freqs,
        assign, min_snr_db, gate_margin, leak_db, max_bias, min_points, report_s0).
    pair_residue_run: the run of the other mode of a collocated actuator pair (the same
        sensors): its copy in this run's records is measured and removed (``engine.waves.pair``).
    """

    modal_fmax_hz: float | None = None
    modal_fmin_hz: float = 5.0
    exp_tau_s: float | None = None
    force_window_s: float = 0.005
    indicator: str = "sum"
    wavelet: tuple[float, float] | None = WaveSettings.wavelet
    wave_band_hz: tuple[float, float] | None = WaveSettings.band_hz
    n_wave_freqs: int = WaveSettings.n_freqs
    assign: str = WaveSettings.assign
    min_wave_snr_db: float = WaveSettings.min_snr_db
    gate_margin: float = WaveSettings.gate_margin
    leak_db: float = WaveSettings.leak_db
    max_bias: float = WaveSettings.max_bias
    min_wave_points: int = WaveSettings.min_points
    report_s0: bool = WaveSettings.report_s0
    pair_residue_run: str | None = None    # the other mode's run of a collocated actuator pair


def usable_shots(records: Sequence[Record], names: Sequence[str], notes: list[str], what: str) -> list[Record]:
    """The shots none of whose channels ``names`` overloaded; says in ``notes`` how many were left out."""
    ok = [r for r in records if not any(r.overload.get(n, False) for n in names)]
    if len(ok) < len(records):
        notes.append(f"{len(records) - len(ok)} overloaded {what} shot(s) left out")
    return ok
