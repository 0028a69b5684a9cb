"""Why engine.plate keeps a hand-made sparse pattern: per-solve cost of K and M from new constants.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python bench/bench_plate_pattern.py``. Prints a markdown
section for bench/RESULTS.md. Plate: the built-in 12-ply CFRP, 0.33 x 0.33 m, default mesh.

Both routes start from the same 21 laminate coefficients and inertias of a new parameter set:

* pattern (engine.plate.sparse): one 80x80 element matrix per element size, scattered into the
  fixed CSR data by one sparse product; K and M as CSR from the fixed index arrays;
* plain scipy: every element's 80x80 matrices, ``scipy.sparse.coo_matrix((data, (rows, cols)))``
  with the element DOFs, ``.tocsr()`` (sums duplicates) -- the textbook assembly; and the same
  followed by slicing out the bending block, which the solve of a symmetric layup needs (the
  pattern has its block positions precomputed, ``sparse.Block``).

The two matrices are compared entry by entry (tests/test_plate_fe.py pins the equality).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine  # noqa: E402

from engine.plate import PlateModel  # noqa: E402
from engine.plate.element import combo_scales, reference_matrices  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402


def timed(fn, repeat: int) -> tuple[float, float, float, object]:
    """(min wall, median wall, median CPU) seconds and the last result."""
    ts, cs = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        ts.append(time.perf_counter() - t)
        cs.append(time.process_time() - c)
    return min(ts), float(np.median(ts)), float(np.median(cs)), out


def main() -> None:
    spec = load_specimen("cfrp")
    model = PlateModel.build(spec.laminate, spec.length, spec.width)
    mesh = model.mesh
    Kref, Mref = reference_matrices()
    scales = combo_scales(mesh.element_sizes)                     # (ne, 6)
    dofs = mesh.element_dofs
    rows = np.repeat(dofs, 80, axis=1).ravel()
    cols = np.tile(dofs, (1, 80)).ravel()
    n = mesh.n_dof
    rng = np.random.default_rng(1)
    params = lambda: {"E1": 136e9 * (1 + 0.05 * rng.standard_normal()),   # new density too: no mass memo
                       "density": 1560.0 * (1 + 0.01 * rng.standard_normal())}

    def pattern():
        return model.matrices(params())

    def plain():
        c, inert = model.coefficients(params())
        Kc = np.tensordot(c, Kref, axes=(0, 1)).reshape(6, 6400)   # per scale combo
        Ke = scales @ Kc                                            # (ne, 6400)
        Me = np.outer(scales[:, 0], np.tensordot(inert, Mref, 1).ravel())
        K = sp.coo_matrix((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()
        M = sp.coo_matrix((Me.ravel(), (rows, cols)), shape=(n, n)).tocsr()
        M.eliminate_zeros()
        return K, M

    bend = np.flatnonzero(np.isin(np.arange(n) % 5, (2, 3, 4)))

    def plain_blocks():
        K, M = plain()
        return K[bend][:, bend], M[bend][:, bend]

    reps = 40
    pat = timed(pattern, reps)
    pla = timed(plain, reps)
    plb = timed(plain_blocks, reps)
    rng = np.random.default_rng(1)
    Kp, Mp = model.matrices(params())
    rng = np.random.default_rng(1)
    Kq, Mq = plain()
    errk = abs(Kp - Kq).max() / abs(Kq).max()
    errm = abs(Mp - Mq).max() / abs(Mq).max()
    solve = timed(lambda: model.solve(10, params()), 5)
    lines = ["## engine.plate — the hand-made sparse pattern (bench/bench_plate_pattern.py)", "",
             f"Machine: {machine()}.", f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.",
             f"Plate: built-in CFRP 12-ply, {spec.length} x {spec.width} m, default mesh "
             f"{mesh.nx}x{mesh.ny} elements, {n} DOF, {Kp.nnz} stored entries of K.", "",
             "| K and M from new constants | wall min (ms) | wall median (ms) | CPU median (ms) |",
             "|---|---|---|---|",
             f"| fixed pattern (engine.plate.sparse) | {pat[0] * 1e3:.2f} | {pat[1] * 1e3:.2f} | {pat[2] * 1e3:.2f} |",
             f"| plain scipy COO -> CSR | {pla[0] * 1e3:.2f} | {pla[1] * 1e3:.2f} | {pla[2] * 1e3:.2f} |",
             f"| plain scipy COO -> CSR, then the bending block sliced out (symmetric layups) | "
             f"{plb[0] * 1e3:.2f} | {plb[1] * 1e3:.2f} | {plb[2] * 1e3:.2f} |",
             f"| (for scale) one full solve, 10 modes | {solve[0] * 1e3:.1f} | {solve[1] * 1e3:.1f} | {solve[2] * 1e3:.1f} |",
             "",
             f"Same matrices: max |K_pattern - K_coo| / max |K| = {errk:.1e}, M: {errm:.1e}. "
             f"Pattern / COO CPU: {pat[2] / pla[2]:.2f} ({pat[2] / plb[2]:.2f} with the block); the COO "
             f"route would add {(pla[2] - pat[2]) / solve[2] * 100:.0f} % ({(plb[2] - pat[2]) / solve[2] * 100:.0f} % "
             "with the block) to the CPU time of every solve.", ""]
    print("\n".join(lines))


if __name__ == "__main__":
    main()
