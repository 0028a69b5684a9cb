"""The diagnoser's library effect models against the independent Ritz plate (issue 28).

Run:  OMP_NUM_THREADS=1 nice .venv/bin/python bench/gap_effect_models.py

For each specimen of the independent bench and each plate effect at a realistic size: the
relative frequency shift of the 20 lowest modes that the effect causes, by the Ritz plate
(bench/independent/ritz_plate.py: masses, springs, rotated plies, thickness and density
fields by quadrature) and by the diagnoser's model (engine.gap.GapForward on a 16-element
mesh, the same constants); the largest difference of the two shifts. A model error there is a
systematic residual the diagnosis would attribute to something else.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine  # noqa: E402
from bench.blind_independent import SPECIMENS, draw, recipe, ritz_for  # noqa: E402
from engine.gap import GapForward  # noqa: E402
from engine.plate import Mesh  # noqa: E402
from labid.workflows.diagnosis import gap_features  # noqa: E402

EFFECTS = (("sensor_mass", 0.004), ("support_stiffness", 500.0), ("thickness_taper", 0.06), ("misalignment", 4.0),
           ("ply_angle_error", -6.0), ("density_gradient", 0.05))


def shifts(spec: str, kind: str, mag: float, n: int = 20, seed: int = 21, order: int = 12,
           elements: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """(Ritz shift, engine shift) relative, per mode, of effect ``kind`` at ``mag`` (Ritz
    ``order``, engine mesh of ``elements`` along the longer side)."""
    force = dict(specimen=spec, n_modes=n, noise=0.001, magnitude=mag, data="modal")
    r = recipe(seed, kind, **force)
    r0 = dict(r, kind="clean", magnitude=0.0)
    table = SPECIMENS[spec][0]()
    y = ritz_for(r, table, order).solve(n).frequencies_hz
    y0 = ritz_for(r0, table, order).solve(n).frequencies_hz
    pr = gap_features(draw(seed, kind, **force).features)
    fw = GapForward(pr, mesh=Mesh.default(pr.length, pr.width, pr.laminate.thickness, n=elements),
                    pairing="order")
    f = fw.predict_modal(r["truth"], {kind: mag})
    f0 = fw.predict_modal(r["truth"], {})
    return y / y0 - 1.0, f / f0 - 1.0


def main() -> int:
    print(machine())
    print("| specimen | effect | size | largest shift (Ritz) | largest |engine - Ritz| shift |")
    print("|---|---|---|---|---|")
    for spec in SPECIMENS:
        for kind, mag in EFFECTS:
            if (spec == "aluminium" and kind in ("misalignment", "ply_angle_error")) or \
                    (spec == "wood" and kind == "ply_angle_error"):
                continue
            a, b = shifts(spec, kind, mag)
            print(f"| {spec} | {kind} | {mag:g} | {np.abs(a).max() * 1e3:.2f} per mille | "
                  f"{np.abs(b - a).max() * 1e3:.3f} per mille |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
