"""Damping as a result (issue 16): modal loss factor per mode and per mode family.

The peak picker (``engine.modal``) fits each resonance's viscous damping ratio zeta
(the exponential window removed). At resonance a viscous and a hysteretic (structural)
oscillator dissipate the same energy per cycle when the loss factor is

    eta = 2 zeta

(e.g. Ewins, *Modal Testing*, 2.3; ASTM E756 quotes eta at the modes). Per family,
the median and the scatter (sample standard deviation, ``ddof=1``; None for one mode)
of eta are reported. Each peak is labelled (m, n) (nodal lines along x and y) by
``engine.plate.mode_families`` on the nominal plate model, and grouped in the families
bending x (m,0), bending y (0,n), twisting (m,n) (:func:`family_of`); each peak is paired
with a model mode by log-frequency (``engine.forward.pair_by_frequency``, plus MAC when
the peaks carry mode shapes at the accelerometers); a peak more than
:data:`MAX_LABEL_OFFSET` away from its model mode, or any peak when the model cannot be
built, stays ``unlabelled``. Units: Hz; zeta and eta dimensionless.
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from engine.forward import mac, pair_by_frequency
from engine.laminate import PhysicsError
from engine.plate import FEError, PlateModel, mode_families

from ..inputs.units import loss_factors

__all__ = ["damping_summary", "loss_factors", "family_labels", "family_of", "UNLABELLED", "MAX_LABEL_OFFSET"]

UNLABELLED = "unlabelled"
#: largest relative distance between a peak and the model mode that names its family
MAX_LABEL_OFFSET = 0.15


def family_labels(frequencies_hz: Sequence[float], specimen, *, points=None, shapes=None) -> list[str]:
    """The family label of every measured peak on ``specimen``'s nominal plate model
    (``labid.inputs.specimen.Specimen``); :data:`UNLABELLED` where no model mode is close."""
    f = np.asarray(frequencies_hz, float)
    if specimen is None or f.size == 0:
        return [UNLABELLED] * f.size
    try:
        model = PlateModel.build(specimen.laminate, specimen.length, specimen.width)
        modes = model.solve(f.size + 4)
    except (PhysicsError, FEError, ValueError):
        return [UNLABELLED] * f.size
    fp = modes.frequencies_hz
    macs = None
    if points is not None and shapes is not None and len(points) >= 3:
        macs = mac(np.asarray(shapes, float), model.shapes_at(modes, np.asarray(points, float)))
    idx = pair_by_frequency(f, fp, macs)
    labels = mode_families(model, modes, specimen.length, specimen.width)
    return [labels[j] if abs(math.log(fi / fp[j])) <= MAX_LABEL_OFFSET else UNLABELLED
            for fi, j in zip(f, idx)]


def family_of(label: str) -> str:
    """The family of a mode label: 'bending x (m,0)' (nodal lines across the length only),
    'bending y (0,n)', 'twisting (m,n)' (both directions), 'in-plane' or 'unlabelled'.
    A mixed label '(a,b)/(c,d)' counts by its dominant product, the first."""
    if label in (UNLABELLED, "in-plane"):
        return label
    m, n = (int(v) for v in label.split("/")[0].split(")")[0].strip("(").split(","))
    if n == 0:
        return "bending x (m,0)"
    if m == 0:
        return "bending y (0,n)"
    return "twisting (m,n)"


def _stats(eta: Sequence[float]) -> dict[str, Any]:
    v = np.asarray([e for e in eta if math.isfinite(e)], float)
    return {"n": int(v.size), "median_loss_factor": float(np.median(v)) if v.size else None,
            "scatter": float(np.std(v, ddof=1)) if v.size > 1 else None}


def damping_summary(modal: Mapping[str, Any] | None, specimen=None) -> dict | None:
    """The ``damping`` section of an analysis from its features ``modal`` table
    (frequencies_hz, damping_ratio, optional mode_shapes); None without damping.

    ``{"definition", "modes": [{frequency_hz, damping_ratio, loss_factor, label, family}],
    "families": {family: {n, median_loss_factor, scatter, modes}}, "all": {...},
    "labelled_by"}``.
    """
    if not modal or not modal.get("damping_ratio"):
        return None
    f = [float(x) for x in modal["frequencies_hz"]]
    z = [float(x) for x in modal["damping_ratio"]]
    eta = loss_factors(z)
    ms = modal.get("mode_shapes") or {}
    fam = family_labels(f, specimen, points=ms.get("points"), shapes=ms.get("values"))
    families: dict[str, dict] = {}
    for i, lab in enumerate(fam):
        families.setdefault(family_of(lab), {"modes": []})["modes"].append(i)
    for lab, d in families.items():
        d.update(_stats([eta[i] for i in d["modes"]]))
    labelled = specimen is not None and any(lab != UNLABELLED for lab in fam)
    return {"definition": "loss factor eta = 2 zeta (zeta: fitted viscous damping ratio of the peak); "
                          "scatter: sample standard deviation",
            "modes": [{"frequency_hz": fi, "damping_ratio": zi, "loss_factor": ei, "label": li,
                       "family": family_of(li)}
                      for fi, zi, ei, li in zip(f, z, eta, fam)],
            "families": families, "all": _stats(eta),
            "labelled_by": ("engine.plate.mode_families on the nominal plate model, paired by frequency"
                            + (" and MAC" if ms.get("points") else "")) if labelled else None}
