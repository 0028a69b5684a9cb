"""The measured features of one plate: the one in-memory form of a features document.

A features document (CONTRACT section 2; JSON <-> :class:`Features` in
``labid.inputs.features``) holds natural frequencies (:class:`ModalData`),
guided-wave group velocities per mode and direction (:class:`WaveData`) and
the nominal rig geometry (:class:`RigLayout`). :class:`Features` adds the
nominal specimen the engine needs to predict them: the laminate and the plate
length and width (the engine does not read specimen files). Identification
(``engine.fit`` blocks built by ``engine.forward``) and the gap diagnosis
(``engine.gap``) both take a :class:`Features`.

Arrays are as measured: a velocity that could not be measured is NaN; each
consumer decides what to drop. Units SI (Hz, m/s, m, kg); ``temperature_c`` in
degC.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .laminate import Laminate, Material

__all__ = ["ModalData", "WaveData", "RigLayout", "Features"]


@dataclass(frozen=True)
class ModalData:
    """Measured natural frequencies (Hz), their sigmas, optional mode shapes at points (m)."""

    frequency_hz: np.ndarray
    sigma_hz: np.ndarray
    points: np.ndarray | None = None
    shapes: np.ndarray | None = None
    pairing: str = "auto"   # 'mac', 'frequency', 'order' or 'auto' (MAC with >= 6 shape points)


@dataclass(frozen=True)
class WaveData:
    """Measured group velocities of one wave mode along one direction."""

    mode: str
    direction_deg: float
    frequency_hz: np.ndarray
    group_velocity_m_s: np.ndarray
    sigma_m_s: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.mode}@{self.direction_deg:g}deg"


@dataclass(frozen=True)
class RigLayout:
    """Nominal rig geometry (m): accelerometer and support points, wave path, sensor length."""

    accelerometers: tuple[tuple[float, float], ...] = ()
    supports: tuple[tuple[float, float], ...] = ()
    wave_path_m: float | None = None
    sensor_length_m: float = 0.0
    temperature_c: float | None = None
    wavelet_bandwidth: float = 2.0
    wavelet_center: float = 5.0
    accelerometer_masses: tuple[float, ...] = ()   # kg, declared (part of the nominal model)

    def masses(self, extra: float = 0.0) -> list[tuple[float, float, float]]:
        """(x, y, m) point masses: declared accelerometer masses plus ``extra`` kg each."""
        m0 = self.accelerometer_masses or (0.0,) * len(self.accelerometers)
        return [(x, y, m + extra) for (x, y), m in zip(self.accelerometers, m0) if m + extra != 0.0]


@dataclass(frozen=True)
class Features:
    """Measured features and the nominal specimen they belong to.

    ``laminate`` and ``length`` x ``width`` (m) describe the nominal plate;
    ``material`` names the laminate material the constants belong to (None:
    the first). ``specimen_name`` names the specimen, for reports.
    """

    laminate: Laminate
    length: float
    width: float
    rig: RigLayout = field(default_factory=RigLayout)
    modal: ModalData | None = None
    waves: tuple[WaveData, ...] = ()
    material: str | None = None
    specimen_name: str = ""
    #: predicted elastic-mode index (0-based) of each modal peak, None where unknown;
    #: None when the document gives none (features ``modal.mode_index``)
    mode_index: tuple[int | None, ...] | None = None

    @property
    def material_obj(self) -> Material:
        mats = self.laminate.materials
        return mats[self.material] if self.material else next(iter(mats.values()))

    def param_names(self) -> tuple[str, ...]:
        """Every modulus and Poisson ratio (density is weighed): what a diagnosis fits."""
        m = self.material_obj
        return ("E", "G") if m.isotropic else ("E1", "E2", "nu12", "G12", "G13", "G23")

    def nominal(self) -> dict[str, float]:
        """Nominal values of :meth:`param_names` (SI)."""
        p = self.material_obj.params()
        return {n: p[n] for n in self.param_names()}
