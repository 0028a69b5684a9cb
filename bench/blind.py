"""Blind cases for the gap diagnoser: features with a hidden effect, magnitude and noise.

``draw_case(seed)`` draws, from the seed alone, the true constants (nominal CFRP
+-5 %, nu12 +-3 %), one condition (clean, a library effect, or an effect outside
the library) with a physically typical magnitude (``RANGES``), and the noise,
and returns the features (CONTRACT section 2, specimen inline as the nominal
table) plus the hidden truth. The features are produced by the forward models
directly (``engine.forward.ForwardModel``); with ``outside=True`` by a
different discretisation than the diagnoser's (finer plate mesh, higher SAFE
order), so a diagnoser tuned to its own simulator shows it. A benchmark case
generator (bench/bench_gap.py, tests/test_gap.py), not part of the rig.

Library effects include the real-plate ones (``misalignment``, ``ply_angle_error``,
``density_gradient``, ``thickness_taper``), injected by ``engine.gap.GapForward``
(the diagnoser's model of them; with ``outside=True`` on the finer mesh).

Out-of-library conditions (still outside the enlarged library):
  soft_patch  a local stiffness loss of 30..60 % over a 60 mm x 60 mm square
              (the plate elements there lose that fraction of their stiffness;
              the wave path is assumed to avoid it);
  lump_mass   a 3..10 g point mass (glue, label, bolt) at a random point at
              least 60 mm from every accelerometer.

Noise: modal sigma = 3e-4 f, mode shapes 2 % of the largest value, group
velocities sigma = 0.2 % of c_g; Gaussian.
"""
from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass
from importlib import resources

import numpy as np

from engine.features import Features, ModalData, RigLayout, WaveData
from engine.forward import EFFECTS
from engine.gap import GapForward
from engine.laminate import Laminate
from engine.plate import Mesh, PlateModel
from engine.safe import default_discretisation
from labid.inputs.features import features_document
from labid.inputs.specimen import specimen_from_dict

LIBRARY = tuple(EFFECTS)
OUT_OF_LIBRARY = ("soft_patch", "lump_mass")
KINDS = ("clean",) + LIBRARY + OUT_OF_LIBRARY

#: physically typical magnitudes: (low, high, signed) in the effect's unit
RANGES = {
    "sensor_mass": (0.001, 0.006, False),        # kg beyond the declared 2 g (cables, wax, heavier unit)
    "support_stiffness": (100.0, 1000.0, False),  # N/m, wire/rubber suspension
    "temperature": (5.0, 15.0, True),            # K away from the constants' temperature
    "thickness": (0.01, 0.04, True),             # relative, 1-4 % nominal vs real
    "timing_offset": (0.5e-6, 3e-6, True),       # s, trigger / coupling delay
    "path_length": (0.003, 0.010, True),         # m, source/sensor placement
    "sensor_aperture": (0.015, 0.028, False),    # m, true length (nominal 5 mm): MFC M2814 active 28 mm
    "viscoelastic": (0.005, 0.03, False),        # loss factor of epoxy composites
    "misalignment": (2.0, 5.0, False),           # deg, whole layup (grain/fibre angle offset)
    "ply_angle_error": (3.0, 8.0, True),         # deg, the top ply
    "density_gradient": (0.08, 0.15, False),     # relative density change at each end (wood, resin flow)
    "thickness_taper": (0.03, 0.10, False),      # relative thickness change at each end (hand lay-up, wood)
    "soft_patch": (0.3, 0.6, False),             # fraction of stiffness lost locally
    "lump_mass": (0.003, 0.010, False),          # kg, glue/label/bolt at a random point off the sensors
}

ACCELEROMETERS = ((0.02, 0.02), (0.31, 0.02), (0.02, 0.31), (0.31, 0.31))
ACCEL_MASS_KG = 0.002      # declared mass of each accelerometer (in the nominal model too)
SUPPORTS = ((0.03, 0.33), (0.30, 0.33))
WAVE_PATH_M = 0.25
SENSOR_LENGTH_M = 0.005
MODAL_REL_SIGMA = 3e-4
WAVE_REL_SIGMA = 2e-3
N_MODES = 10
WAVE_SETS = (("A0", 0.0, 10), ("A0", 45.0, 10), ("A0", 90.0, 10), ("S0", 0.0, 8), ("S0", 90.0, 8))
F_WAVES = (20e3, 200e3)


@dataclass(frozen=True)
class BlindCase:
    """A generated case: the features the diagnoser sees and the hidden truth."""

    seed: int
    kind: str
    magnitude: float
    unit: str
    features: dict
    truth_constants: dict
    outside: bool
    noiseless: np.ndarray     # noise-free features (modal Hz then each wave set), for scoring


def nominal_specimen_table() -> dict:
    """The nominal CFRP specimen table (labid/data/cfrp_12ply.toml)."""
    text = resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text()
    return tomllib.loads(text)


def _laminate(table: dict) -> tuple[Laminate, float, float]:
    s = specimen_from_dict(table)
    return s.laminate, s.length, s.width


def _shape_points() -> np.ndarray:
    g = np.linspace(0.02, 0.31, 5)
    X, Y = np.meshgrid(g, g)
    return np.column_stack([X.ravel(), Y.ravel()])


def draw_case(seed: int, kind: str | None = None, outside: bool = False, *,
              wave_sets=WAVE_SETS, mesh=None) -> BlindCase:
    """Draw a case from ``seed`` (``kind`` forces the condition; see KINDS).

    ``wave_sets``: (mode, direction_deg, n_frequencies) of the measured wave
    sets (empty: modal only); ``mesh``: plate mesh of the generator (None:
    default; ``outside`` overrides it with a finer one).
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
    kind = kind or KINDS[int(rng.integers(len(KINDS)))]
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r}: expected one of {KINDS}")
    table = nominal_specimen_table()
    lam, length, width = _laminate(table)
    mat = next(iter(lam.materials.values()))
    nominal = {k: v for k, v in mat.params().items() if k != "density"}
    truth = {k: v * (1.0 + (0.03 if k == "nu12" else 0.05) * rng.standard_normal())
             for k, v in nominal.items()}
    mag = 0.0
    if kind != "clean":
        lo, hi, signed = RANGES[kind]
        mag = float(rng.uniform(lo, hi)) * (float(rng.choice([-1.0, 1.0])) if signed else 1.0)
    rig = RigLayout(ACCELEROMETERS, SUPPORTS, WAVE_PATH_M, SENSOR_LENGTH_M, 23.0,
                    accelerometer_masses=(ACCEL_MASS_KG,) * len(ACCELEROMETERS))
    waves = tuple(WaveData(m, d, np.geomspace(*F_WAVES, n), np.ones(n), np.ones(n))
                  for m, d, n in wave_sets)
    true_lam = lam
    problem = Features(true_lam, length, width, rig,
                       ModalData(np.ones(N_MODES), np.ones(N_MODES), pairing="order"), waves)
    if outside:
        mesh = Mesh.default(length, width, lam.thickness, n=9)
    plate_model = None
    if kind in OUT_OF_LIBRARY or outside:
        plate_model = PlateModel.build(true_lam, length, width, mesh)
        if kind == "soft_patch":
            x0, y0 = rng.uniform(0.08, 0.25, size=2)
            plate_model = plate_model.with_stiffness_loss(x0, y0, 0.06, mag, truth)
        if kind == "lump_mass":
            while True:
                x0, y0 = rng.uniform(0.02, 0.31, size=2)
                if min(np.hypot(x0 - ax, y0 - ay) for ax, ay in ACCELEROMETERS) > 0.06:
                    break
            plate_model = plate_model.with_point_masses([(x0, y0, mag)])
    safe_order = None
    if outside:
        safe_order = default_discretisation(lam, F_WAVES[1] * 1.5)[0] + 2
    fw = GapForward(problem, mesh=mesh, safe_order=safe_order, plate_model=plate_model)
    effects = {kind: mag} if kind in LIBRARY else {}
    y = fw.predict(truth, effects)
    # mode shapes of the true (perturbed) plate at the measurement points
    mf = fw.modal_forward_with(effects)
    modes, idx, _ = mf.solve(truth)
    pts = _shape_points()
    shapes = mf.model.shapes_at(modes, pts)[idx]
    shapes = shapes / np.max(np.abs(shapes), axis=1, keepdims=True)
    shapes = shapes + 0.02 * rng.standard_normal(shapes.shape)
    sig = np.concatenate([MODAL_REL_SIGMA * y[:N_MODES], WAVE_REL_SIGMA * y[N_MODES:]])
    obs = y + sig * rng.standard_normal(y.shape)
    n_w = [len(w.frequency_hz) for w in waves]
    ends = N_MODES + np.cumsum([0] + n_w)
    measured = Features(lam, length, width, rig, ModalData(obs[:N_MODES], sig[:N_MODES], pts, shapes),
                        tuple(WaveData(w.mode, w.direction_deg, w.frequency_hz, obs[a:b], sig[a:b])
                              for w, a, b in zip(waves, ends[:-1], ends[1:])))
    feats = features_document(measured, copy.deepcopy(table))
    unit = EFFECTS[kind].unit if kind in EFFECTS else ("kg" if kind == "lump_mass" else "1")
    return BlindCase(int(seed), kind, mag, unit, feats, truth, bool(outside), y)
