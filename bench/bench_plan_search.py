"""Does the layout search find the best layout? (issue 25, session 24)

    OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_plan_search.py [--starts 2,40] [--grid 15]

For the CFRP, wood-like and aluminium plates of bench/bench_plan.py (E1, E2, G12 wanted, fitted
alone, aluminium E, G; the held constants known exactly, prior 0, then with their 10 % prior;
no waves): ``labid plan`` with the coordinate exchange started from the built-in layout, a
spread layout and N random layouts (N = 2 is the default of engine.design.search.optimise).
Printed per run: the worst predicted std of the built-in rig's layout and of the recommended
one, their ratio, the criterion at every start's end point (best, how many ended within 1 % of
it), the layout and the CPU. If more starts found a better layout, the default search would
be the limit of the gain; if they all end at the same value, the grid and the physics are.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import labid.workflows.plan as wp  # noqa: E402
from bench._machine import machine  # noqa: E402
from bench.bench_plan import specimen  # noqa: E402
from engine.design import search  # noqa: E402
from labid import services  # noqa: E402

_ORIG = search.optimise
_N = {"random": 2}
_ENDS: list = []


def _optimise(*a, **kw):
    """engine.design.search.optimise with the asked number of random starts (the waves'
    second search, which starts from the modal best only, is left as it is)."""
    if kw.get("n_random", 2) != 0:
        kw["n_random"] = _N["random"]
    best, ends = _ORIG(*a, **kw)
    _ENDS.append(sorted(e.value for e in ends))
    return best, ends


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", default="2,40")
    ap.add_argument("--grid", type=int, default=15)
    ap.add_argument("--specimens", default="cfrp,wood,aluminium")
    args = ap.parse_args(argv)
    print(machine(), flush=True)
    wp.optimise = _optimise
    for name in args.specimens.split(","):
        spec = specimen(name)
        iso = spec.laminate.plies[0].material.isotropic
        for prior in ("0", "10%"):
            for n in (int(x) for x in args.starts.split(",")):
                _N["random"] = n
                _ENDS.clear()
                t = time.process_time()
                d = services.plan_test(spec, None, want=None if iso else "E1,E2,G12", fit="wanted", waves="no",
                                       prior=prior, grid=args.grid).to_dict()
                cpu = time.process_time() - t
                rec, rig = d["recommended"], d["rigs"][0]
                v = np.array(_ENDS[0])
                print(f"{name} prior {prior} random starts {n}: built-in {100 * rig['worst_std_rel']:.3f} % -> "
                      f"recommended {100 * rec['worst_std_rel']:.3f} %, ratio {d['improvement_worst_std']:.3f}x; "
                      f"criterion at the {v.size} end points: best {v[0]:.4g}, {int(np.sum(v <= v[0] * 1.01))} within "
                      f"1 %, median {np.median(v):.4g}; sensors "
                      f"{[(round(a['x'], 3), round(a['y'], 3)) for a in rec['accelerometers']]} tap "
                      f"{(round(rec['hammer']['x'], 3), round(rec['hammer']['y'], 3))}; CPU {cpu:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
