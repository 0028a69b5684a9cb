"""Forward-model work and CPU per workload of issue 29, with the floor each could reach.

    LABID_THREADS=1 .venv/bin/python bench/bench_solves.py FEATURES.json [--root TREE] [--skip-demo]

FEATURES.json: the features ``labid demo --out DIR`` writes (simulated rig, seed 0). Workloads:

* ``identify``  -- ``labid identify FEATURES`` (nominal start, 6 constants, global stage, budget);
* ``combined``  -- the demo's combined identification (datasheet start, GUM budget);
* ``modal``     -- the demo's modal-only identification (datasheet start);
* ``diagnose3`` -- ``labid diagnose --params E1,E2,G12`` on 10 modes without shapes (bench/blind.py
  seed 31, clean; bench_gap_cost.py's modal3-clean);
* ``dispersion`` -- ``labid dispersion cfrp --fmax 1e6 --n 10``;
* ``demo``      -- ``labid demo`` (child process: CPU of it and its worker, wall, peak RSS).

Per workload, in this process: plate eigen-solves (default and finer mesh), eigen-sensitivity
evaluations, model builds and SAFE calls (bench/_count.py), their CPU and the workload's CPU;
and in a child process (``python -m labid.cli.main``): CPU (user + sys), wall and peak RSS.
The floor: the solves the workload cannot do without, at this run's median CPU per default
solve (see bench/RESULTS.md, issue 29). Not a test.
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def child(args: list[str], root: Path, cwd: Path) -> dict:
    """One ``labid`` command in a child process under ``/usr/bin/time``: CPU (user + sys of it
    and the processes it waited for, s), wall (s), peak RSS of the largest (MiB)."""
    env = {**os.environ, "PYTHONPATH": str(root), "LABID_THREADS": os.environ.get("LABID_THREADS", "1"),
           "QT_QPA_PLATFORM": "offscreen", "MPLBACKEND": "Agg"}
    p = subprocess.run(["/usr/bin/time", "-f", "TIME %e %U %S %M", sys.executable, "-m", "labid.cli.main", *args,
                        "--quiet"], env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       text=True)
    wall, user, sys_, rss = next(ln for ln in p.stderr.splitlines() if ln.startswith("TIME ")).split()[1:]
    return {"cpu": float(user) + float(sys_), "wall": float(wall), "rss": float(rss) / 1024.0}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("features")
    ap.add_argument("--root", default=str(ROOT), help="labid tree to measure (default: this one)")
    ap.add_argument("--skip-demo", action="store_true")
    a = ap.parse_args()
    root = Path(a.root).resolve()
    sys.path.insert(0, str(root))
    sys.path.insert(1, str(ROOT))
    from bench._count import Counts
    from bench._machine import machine
    from bench.blind import draw_case
    from labid.base import threads
    threads.configure(None)
    import labid.services as services
    from labid.cli.demo import DATASHEET_START
    print(machine())
    print(f"tree: {root}")
    feats = json.loads(Path(a.features).read_text())
    tmp = Path(tempfile.mkdtemp(prefix="bench_solves_"))
    (tmp / "features.json").write_text(json.dumps(feats))
    d3 = copy.deepcopy(draw_case(31, "clean", wave_sets=()).features)
    d3["modal"].pop("mode_shapes", None)
    (tmp / "modal3.json").write_text(json.dumps(d3))

    def ident(ds: str, start, budget: bool):
        doc = services.select_data(feats, ds)
        return lambda: services.run_identification(doc, base_dir=str(tmp), start=start, budget=budget)

    def diag():
        from labid.workflows.diagnosis import run_diagnosis
        return run_diagnosis(d3, names=["E1", "E2", "G12"])

    work = [("identify", ident("combined", None, True), ["identify", str(tmp / "features.json")]),
            ("combined", ident("combined", DATASHEET_START, True), None),
            ("modal", ident("modal", DATASHEET_START, False), None),
            ("diagnose3", diag, ["diagnose", str(tmp / "modal3.json"), "--params", "E1,E2,G12"]),
            ("dispersion", None, ["dispersion", "cfrp", "--fmax", "1e6", "--n", "10"])]
    if not a.skip_demo:
        work.append(("demo", None, ["demo", "--out", str(tmp / "demo")]))
    rows = []
    solve_cpu: list[float] = []
    for name, fn, cli in work:
        row = {"name": name}
        if fn is not None:
            import engine.identify.stages as stages
            stages._DISC_MEMO.clear()       # every workload pays its own fine-mesh correction
            import engine.plate.model as plate_model
            if hasattr(plate_model, "mesh_parts"):     # and builds its own meshes' patterns
                plate_model.mesh_parts.cache_clear()
            with Counts() as c:
                t = time.process_time()
                fn()
                row["cpu_in"] = time.process_time() - t
            row["counts"] = c.snapshot()
            for lab, (n, cpu) in row["counts"].items():
                if lab.startswith("plate solve") and n:
                    solve_cpu.append(cpu / n)
        if cli is not None:
            row["child"] = child(cli, root, tmp)
        rows.append(row)
        print(name, json.dumps({k: v for k, v in row.items() if k != "name"}, default=str), flush=True)
    per_solve = statistics.median(solve_cpu) if solve_cpu else float("nan")
    print(f"\nmedian CPU per plate solve (any mesh, this run): {per_solve:.3f} s")
    print("| workload | plate solves (default / finer mesh) | sensitivities | SAFE calls | model builds "
          "| CPU in process (s) | process CPU (s) | wall (s) | peak RSS (MiB) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        c = r.get("counts", {})
        plate = [(lab, n) for lab, (n, _) in c.items() if lab.startswith("plate solve")]
        default = sum(n for lab, n in plate if "(3125" in lab or "(3410" in lab or "(3515" in lab)
        finer = sum(n for lab, n in plate) - default
        ch = r.get("child", {})
        print(f"| {r['name']} | {default} / {finer} | {c.get('eigen-sensitivities', (0,))[0]} | "
              f"{c.get('SAFE model (any SAFE call)', (0,))[0]} | {c.get('plate model build', (0,))[0]} | "
              f"{r.get('cpu_in', float('nan')):.2f} | {ch.get('cpu', float('nan')):.2f} | "
              f"{ch.get('wall', float('nan')):.1f} | {ch.get('rss', float('nan')):.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
