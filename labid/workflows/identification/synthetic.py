"""Synthetic features documents computed by the forward models (tests, benchmarks, demo).

Units SI (Hz, m/s, Pa).
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from engine.plate import PlateModel
from engine.plate.convergence import reference_mesh
from engine.safe import group_velocity

from ...inputs.features import DEFAULT_MODAL_SIGMA_REL, DEFAULT_WAVE_SIGMA_REL
from ...inputs.specimen import Specimen, load_specimen

__all__ = ["synthetic_features"]


def synthetic_features(specimen: str | Specimen = "cfrp", *, n_modes: int | None = 10,
                       modal_sigma_rel: float = DEFAULT_MODAL_SIGMA_REL,
                       waves: Sequence[tuple[str, float, float, int]] = (("A0", 0.0, 200e3, 20),),
                       wave_sigma_rel: float = DEFAULT_WAVE_SIGMA_REL, noise: bool = False,
                       seed: int = 0, with_shapes: bool = False, params: Mapping[str, float] | None = None,
                       modal_model=None) -> dict:
    """A features document computed by the forward models (CONTRACT section 2).

    ``waves``: (mode, direction_deg, fmax_hz, n) records on the grid
    ``f_i = i fmax / n``. With ``noise``, Gaussian noise of the stated sigmas
    is added (seeded). ``params`` changes the true constants. The specimen is
    inlined as the built-in name when given by name.

    The modes come from the converged reference mesh
    (``engine.plate.convergence.reference_mesh``), as the simulated rig's do, unless
    ``modal_model`` is given (then from that model: same-mesh data, which hide the
    identification model's discretisation error -- only for tests of the estimator).
    """
    spec = load_specimen(specimen) if isinstance(specimen, str) else specimen
    lam = spec.laminate
    if params:
        lam = lam.with_params(dict(params))
    rng = np.random.default_rng(seed)
    doc: dict = {"specimen": specimen if isinstance(specimen, str) else None}
    if n_modes:
        model = modal_model or PlateModel.build(spec.laminate, spec.length, spec.width,
                                                reference_mesh(spec.length, spec.width, lam.thickness))
        modes = model.solve(n_modes, params=dict(params) if params else None)
        f = modes.frequencies_hz
        sig = modal_sigma_rel * f
        doc["modal"] = {"frequencies_hz": (f + (sig * rng.standard_normal(f.size) if noise else 0)).tolist(),
                        "sigma_hz": sig.tolist()}
        if with_shapes:
            pts = np.array([[x, y] for x in np.linspace(0.1, 0.9, 4) * spec.length
                            for y in np.linspace(0.1, 0.9, 4) * spec.width])
            doc["modal"]["mode_shapes"] = {"points": pts.tolist(),
                                           "values": model.shapes_at(modes, pts).tolist()}
    if waves:
        doc["waves"] = []
        for mode, d, fmax, n in waves:
            fr = np.arange(1, n + 1) * fmax / n
            cg = group_velocity(lam, fr, mode=mode, direction_deg=d)
            sig = wave_sigma_rel * cg
            doc["waves"].append({"mode": mode, "direction_deg": d, "frequency_hz": fr.tolist(),
                                 "group_velocity_m_s": (cg + (sig * rng.standard_normal(n) if noise else 0)).tolist(),
                                 "sigma_m_s": sig.tolist()})
    return doc
