"""``labid modes``: free-free natural frequencies of a specimen plate (Mindlin FE).

Result (``--json``): ``frequencies_hz``, the N lowest elastic modes, rigid-body
modes excluded, ascending (CONTRACT section 3); ``families``, the (m,n) nodal-line
label of each mode (``engine.plate.labels``: '(1,1) torsion', '(2,0)', 'in-plane'); also ``specimen``, ``mesh``
(``nx``, ``ny`` elements, ``n_dof``, ``graded``), ``rigid_max_omega_rad_s`` (largest
|omega| of the six excluded rigid-body modes, ~0). With ``--shapes``:
``mode_shapes`` = ``{"points": [[x, y], ...], "values": [[...], ...], "grid": [gx, gy],
"component": "w0", "scaling": "mass-normalised, 1/sqrt(kg)"}``, where
``values[i][j]`` is the transverse displacement of mode i at point j on a
gx x gy grid covering the plate edge to edge (x fastest), the same layout as
``modal.mode_shapes`` of a features file (CONTRACT section 2).
"""
from __future__ import annotations

import re

import numpy as np

from engine.laminate import PhysicsError
from engine.plate import FEError, PlateModel
from engine.plate.labels import mode_families

from .options import MAX_MODES, add_json_option, count
from ..base.errors import UserError
from ..inputs.specimen import load_specimen
from ..base.summary import modes_table, stream

_GRID_RE = re.compile(r"^\s*(\d+)\s*[xX*]\s*(\d+)\s*$")
MAX_ELEMENTS = 60  # per side, for --mesh


def register(sub) -> None:
    p = sub.add_parser("modes", help="free-free natural frequencies of the plate",
                       description=__doc__.splitlines()[0])
    p.add_argument("spec", metavar="SPEC.toml",
                   help="specimen file, or a built-in name ('cfrp', 'aluminium')")
    p.add_argument("--n", type=count(MAX_MODES, "a number of modes", 1), default=10, metavar="N",
                   help="number of elastic modes (default 10)")
    p.add_argument("--mesh", default=None, metavar="NxM",
                   help="uniform mesh of N x M 16-node elements (default: the converged graded mesh)")
    p.add_argument("--shapes", action="store_true", help="add mode shapes (w0) on a grid")
    p.add_argument("--grid", default="11x11", metavar="GXxGY",
                   help="points of the --shapes grid along x and y (default 11x11)")
    add_json_option(p)
    p.set_defaults(func=run)


def _pair(text: str, key: str, lo: int, hi: int) -> tuple[int, int]:
    m = _GRID_RE.match(text or "")
    if not m:
        raise UserError(f"value {text!r}: expected NxM with two positive integers, e.g. 8x8", key=key)
    a, b = int(m.group(1)), int(m.group(2))
    if not (lo <= a <= hi and lo <= b <= hi):
        raise UserError(f"value {text!r}: expected both numbers in {lo}..{hi}", key=key)
    return a, b


def run(args) -> dict:
    if args.n < 1 or args.n > 200:
        raise UserError(f"value {args.n}: expected a number of modes in 1..200", key="--n")
    mesh = None if args.mesh is None else _pair(args.mesh, "--mesh", 1, MAX_ELEMENTS)
    grid = _pair(args.grid, "--grid", 2, 200) if args.shapes else None
    spec = load_specimen(args.spec)
    try:
        model = PlateModel.build(spec.laminate, spec.length, spec.width, mesh)
        if args.n + 10 >= model.mesh.n_dof:
            raise UserError(f"value {args.n}: too many modes for the mesh", key="--n")
        modes = model.solve(args.n)
    except (FEError, PhysicsError) as e:
        raise UserError(str(e), file=spec.source) from None
    families = mode_families(model, modes, spec.length, spec.width)
    out = {
        "frequencies_hz": [float(f) for f in modes.frequencies_hz],
        "families": families,
        "specimen": spec.name,
        "mesh": {"nx": model.mesh.nx, "ny": model.mesh.ny, "n_dof": model.mesh.n_dof,
                 "graded": model.mesh.x_edges is not None},
        "rigid_max_omega_rad_s": modes.rigid_max_omega,
    }
    if grid is not None:
        gx, gy = grid
        X, Y = np.meshgrid(np.linspace(0, spec.length, gx), np.linspace(0, spec.width, gy))
        pts = np.column_stack([X.ravel(), Y.ravel()])
        out["mode_shapes"] = {"points": pts.tolist(),
                              "values": model.shapes_at(modes, pts).tolist(),
                              "grid": [gx, gy], "component": "w0",
                              "scaling": "mass-normalised, 1/sqrt(kg)"}
    w = stream(args)
    if w is not None:
        m = out["mesh"]
        w.write(f"{spec.name}: {args.n} lowest free-free modes ({spec.length * 1e3:g} x {spec.width * 1e3:g} mm; "
                f"{'graded' if m['graded'] else 'uniform'} mesh {m['nx']} x {m['ny']}, {m['n_dof']} dof; "
                f"family (m,n) = nodal lines along x and y)\n")
        w.write(modes_table(out["frequencies_hz"], families))
        if grid is not None:
            w.write(f"shapes: w0 on a {grid[0]} x {grid[1]} grid edge to edge, mass-normalised (1/sqrt(kg)); "
                    + (f"in {args.json} (mode_shapes)" if getattr(args, "json", None) else
                       "add --json FILE to save them") + "\n")
    return out
