"""The data blocks of the identification, built once from ``engine.features.Features``.

:func:`feature_blocks` is the one place the measured features become the estimators'
``DataBlock``\\ s: natural frequencies -> the plate FE (``engine.forward.modal_block``: the
rig's accelerometer masses on the plate, the discretisation correction and error of
``engine.plate.convergence`` (:func:`engine.identify.stages.discretisation`), pairing by MAC
with enough shape points, else the likelihood pairing with missing and spurious peaks),
group velocities -> SAFE (``engine.forward.wave_block``; points without a velocity
dropped). The workflow (``labid.workflows.identification.estimation.problem_from_features``)
checks the document first and names the key of what is wrong.

Units SI (Hz, m/s, m, kg).
"""
from __future__ import annotations

from typing import Any, Mapping, NamedTuple

import numpy as np

from ..features import Features
from ..fit import DataBlock
from ..forward.modal import MIN_MAC_POINTS, extra_modes, modal_block
from ..forward.waves import wave_block
from ..plate import PlateModel
from .stages import N_EXTRA_MODES, discretisation

__all__ = ["Blocks", "feature_blocks", "COVER"]

#: the likelihood-paired modal model holds every mode up to this factor above the highest peak
COVER = 1.05


def _covering_extra(model, f: np.ndarray, n_extra: int, material: str | None,
                    params: Mapping[str, float] | None) -> int:
    """``n_extra`` grown so that the model's modes (at ``params``; None: nominal) reach COVER x
    the highest peak, plus ``n_extra`` spare above it. A peak list that skips modes (sensors or
    the tap near their nodal lines) spans more modes than peaks + extras: measured on the
    wood-like plate of bench/bench_plan.py, 22 peaks spanning 60 modes against 35 modelled set
    7 peaks aside and the fit was declared inconsistent in 29 of 60 cases. One solve of
    the default mesh (~0.1-0.3 s CPU) to check; more only when the band is not covered."""
    n = f.size + n_extra
    cap = int(0.4 * model.mesh.n_dof) - 20
    fmax = COVER * float(np.max(f))
    top = model.solve(n, params=dict(params or {}), material=material).frequencies_hz
    while top[-1] < fmax and n < cap:                # grow until the band is covered
        n = min(cap, int(1.6 * n))
        top = model.solve(n, params=dict(params or {}), material=material).frequencies_hz
        if top[-1] >= fmax:                          # every mode below COVER x the peak, 4 spare
            n = min(cap, int(np.searchsorted(top, fmax)) + N_EXTRA_MODES)
    return max(n_extra, n - f.size)


class Blocks(NamedTuple):
    """The blocks (modal first, then one per wave set), the notes on what was assumed or
    dropped, and the modal forward model (None without modal data)."""

    blocks: list[DataBlock]
    notes: list[str]
    modal_forward: Any


def feature_blocks(features: Features, *, plate_model=None, correct_discretisation: bool = True,
                   drive_points=None, correction_at: Mapping[str, float] | None = None) -> Blocks:
    """The data blocks of ``features`` (its ``material`` set). ``plate_model``: a prebuilt
    default-mesh ``PlateModel`` of the same specimen with the rig's masses (else built here,
    ``PhysicsError`` for an unphysical laminate); ``drive_points``: hammer points (m, (k, 2))
    for the modes' visibility; ``correction_at``: the constants the discretisation correction
    is solved at (None: the laminate's own). Raises ``IdentificationError`` from the modal block."""
    material = features.material
    blocks: list[DataBlock] = []
    notes: list[str] = []
    fwd = None
    md = features.modal
    if md is not None:
        f = np.asarray(md.frequency_hz, float)
        masses = features.rig.masses()
        model = plate_model
        if model is None:
            model = PlateModel.build(features.laminate, features.length, features.width)
            if masses:
                model = model.with_point_masses(masses)
                notes.append(f"modal model includes {len(masses)} accelerometer mass(es)")
        n_extra = extra_modes(f.size, N_EXTRA_MODES)
        if md.pairing != "order":
            n_extra = _covering_extra(model, f, n_extra, material, correction_at)
        corr = err = None
        if correct_discretisation:
            corr, err, note = discretisation(features.laminate, features.length, features.width, masses, model,
                                             material, f.size + n_extra, correction_at)
            notes.append(note if correction_at is None else
                         note.replace("corrected from", "corrected (again, at the estimate) from"))
        resp = features.rig.accelerometers or (md.points if md.points is not None else None)
        # MAC pairing needs enough shape points; with fewer (e.g. three accelerometers) the
        # likelihood pairing is more reliable
        use_mac = (md.shapes is not None and md.points is not None and len(md.points) >= MIN_MAC_POINTS
                   and md.pairing in ("auto", "mac"))
        blk, fwd = modal_block(model, f, md.sigma_hz, points=md.points if use_mac else None,
                               shapes=md.shapes if use_mac else None, material=material,
                               correction=corr, model_error_rel=err,
                               pairing="order" if md.pairing == "order" else "likelihood",
                               response_points=resp, drive_points=drive_points,
                               labels=features.mode_index, n_extra=n_extra)
        blocks.append(blk)
    for i, w in enumerate(features.waves):
        fr, cg, sig = (np.asarray(a, float) for a in (w.frequency_hz, w.group_velocity_m_s, w.sigma_m_s))
        ok = np.isfinite(fr) & np.isfinite(cg) & np.isfinite(sig)
        if not ok.all():
            notes.append(f"waves[{i}].: {int((~ok).sum())} point(s) without a velocity dropped")
        if ok.sum() == 0:
            continue
        blocks.append(wave_block(features.laminate, fr[ok], cg[ok], sig[ok], mode=w.mode,
                                 direction_deg=w.direction_deg, material=material,
                                 name=f"waves[{i}]:{w.mode}@{w.direction_deg:g}deg"))
    return Blocks(blocks, notes, fwd)
