"""Issue 24, session 28 (h55): shots per burst in a tone-burst sweep, over noise seeds.

The rig of bench_unknown_plate.py ``sweep_far`` (bench/rigs/cfrp_pzt_sweep_2dir_far.toml; 5 bursts
60-250 kHz, MFC pairs 20 / 40 cm along 0 and 90 deg, 1 mV noise), INDEPENDENT records
(legendre_safe's transfer through the rig's chain), the specimen file +-40 % off the plate,
reference = the TRUE plate's group velocity from legendre_safe. Per noise seed and file, 80 shots
are made once (16 per burst: shot k is burst k mod 5 with its own seeded noise, so the first 10 /
30 shots ARE the 2- / 6-shot runs of the same seed); analysed:

- ``2``, ``6``: the first 10 / 30 shots (no averaging: <= MAX_CURVES shots per burst);
- ``16``: all 80 with the pipeline's ``stack_shots`` as it is in the tree;
- ``--variants`` (comma list) adds 80-shot analyses with another averaging: ``unequal12`` main's
  rule at 36bcf68 (12 groups of 1-2 shots), ``equal2`` / ``equal4`` 8 groups of 2 / 4 groups of 4.

Per curve and seed: points, within 1 %, max |err| / sigma, rms of err / sigma; each point's
(f, err, sigma) is written as a JSON line to OUT (default /tmp/h55_seeds/seeds.jsonl) for the
sigma-scaling check (does sigma fall as 1 / sqrt(shots)?).

Run: OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_sweep_seeds.py [--seeds 0,1,2] [--files soft,stiff]
     [--variants equal2,equal4] [--out FILE]
     .venv/bin/python bench/bench_sweep_seeds.py --summary FILE [FILE ...]   (tables from the JSON lines)
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from bench.bench_unknown_plate import HERE, records, run_case  # noqa: E402
from engine.wavefeatures import pipeline  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402

SCALES = {"soft": 1 / 0.6, "stiff": 1 / 1.4}


def grouped(size: int):
    """A ``stack_shots`` stand-in: consecutive groups of ``size`` shots (the rest of a burst's
    shots, fewer than ``size``, left out)."""
    def stack(shots, max_curves=pipeline.MAX_CURVES):
        n = len(shots) // size
        if len(shots) <= size or n < 2:
            return list(shots), ""
        return ([{ch: np.mean([shots[k][ch] for k in range(i * size, (i + 1) * size)], axis=0) for ch in shots[0]}
                 for i in range(n)], f"{n} groups of {size}")
    return stack


def unequal12(shots, max_curves=12):
    """Main's rule at 36bcf68: 12 consecutive groups of rounded linspace edges (1-2 shots for 16)."""
    n = len(shots)
    if n <= max_curves:
        return list(shots), ""
    edges = np.linspace(0, n, max_curves + 1).round().astype(int)
    return [{ch: np.mean([shots[k][ch] for k in range(a, b)], axis=0) for ch in shots[a]}
            for a, b in zip(edges[:-1], edges[1:])], "12 unequal groups"


def summary(paths) -> None:
    """Per file, curve and shot count: points and within 1 % per seed, max |err| / sigma, rms of
    err / sigma over all seeds' points; then how a point's sigma falls with the shots (points of
    one seed matched within 2 % in frequency): the median ratio against sqrt(n_before / n_after)."""
    rows = [json.loads(ln) for p in paths for ln in Path(p).read_text().splitlines() if ln.strip()]
    seen = {}
    for r in rows:                      # a later line of the same case replaces an earlier one
        seen[(r["file"], r["shots"], r["seed"], r["mode"], r["direction"])] = r
    rows = list(seen.values())
    key = lambda r: (r["file"], r["mode"], r["direction"])  # noqa: E731
    for k in sorted({key(r) for r in rows}):
        print(f"\n{k[0]}, {k[1]} {k[2]:g} deg")
        for label in sorted({r["shots"] for r in rows if key(r) == k}, key=lambda x: (int(x.split()[0]), x)):
            rs = sorted((r for r in rows if key(r) == k and r["shots"] == label), key=lambda r: r["seed"])
            e = np.concatenate([r["err"] for r in rs])
            z = np.abs(e) / np.concatenate([r["sigma"] for r in rs])
            worst = max(((abs(x), x, f, s, r["seed"]) for r in rs for x, f, s in zip(r["err"], r["f"], r["sigma"])))
            print(f"  {label:>14}: seeds {','.join(str(r['seed']) for r in rs)}; points / within 1 % "
                  + ", ".join(f"{len(r['err'])}/{int(np.sum(np.abs(r['err']) <= 0.01))}" for r in rs)
                  + f"; max |err| {100 * worst[0]:.2f} % ({worst[2] / 1e3:.0f} kHz, sigma {100 * worst[3]:.2f} %, "
                  f"seed {worst[4]}); max |err|/sigma {z.max():.1f}, rms {np.sqrt(np.mean(z ** 2)):.2f}; "
                  f"sigma median {100 * np.median(np.concatenate([r['sigma'] for r in rs])):.2f} %")
        for a, b, na, nb in (("2", "6", 2, 6), ("6", "16", 6, 16), ("2", "16", 2, 16), ("6", "16 equal2", 6, 16)):
            ratios = []
            for r in (r for r in rows if key(r) == k and r["shots"] == a):
                o = next((q for q in rows if key(q) == k and q["shots"] == b and q["seed"] == r["seed"]), None)
                if o is None or not o["f"]:
                    continue
                for f, s in zip(r["f"], r["sigma"]):
                    j = int(np.argmin(np.abs(np.array(o["f"]) - f)))
                    if abs(o["f"][j] / f - 1) < 0.02:
                        ratios.append(o["sigma"][j] / s)
            if ratios:
                q = np.percentile(ratios, [25, 50, 75])
                print(f"  sigma {b} shots / {a} shots: median {q[1]:.2f} (quartiles {q[0]:.2f}-{q[2]:.2f}, "
                      f"{len(ratios)} matched points); 1 / sqrt(shots) gives {np.sqrt(na / nb):.2f}")


def main(argv) -> None:
    if argv and argv[0] == "--summary":
        return summary(argv[1:])
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--files", default="soft,stiff")
    ap.add_argument("--variants", default="")
    ap.add_argument("--out", default="/tmp/h55_seeds/seeds.jsonl")
    a = ap.parse_args(argv)
    print(f"machine: {machine()}", flush=True)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    path = HERE / "rigs" / "cfrp_pzt_sweep_2dir_far.toml"
    rig = rig_from_text(path.read_text(), str(path))
    runs = [("2", 10, None), ("6", 30, None), ("16", 80, None)]
    known = {"unequal12": unequal12, "equal2": grouped(2), "equal4": grouped(4)}
    runs += [(f"16 {v}", 80, known[v]) for v in a.variants.split(",") if v]
    orig = pipeline.stack_shots
    for seed in (int(s) for s in a.seeds.split(",")):
        for file in a.files.split(","):
            scale = SCALES[file]
            c0 = time.process_time()
            recs = records(replace(rig, sim=replace(rig.sim, truth_scale=(("*", scale),))), large, 80, seed,
                           "independent")
            print(f"\n=== seed {seed}, file {file}: 80 records in {time.process_time() - c0:.1f} s CPU", flush=True)
            for label, n, stack in runs:
                pipeline.stack_shots = stack or orig
                try:
                    rows, cpu, notes = run_case(f"sweep_far, {label} shots per burst", rig, large, n, scale,
                                                "independent", seed=seed, recs=recs[:n], trace=False)
                finally:
                    pipeline.stack_shots = orig
                with out.open("a") as fh:
                    for mode, dd, k, _lo, _hi, e, s, z, f in rows:
                        fh.write(json.dumps({"seed": seed, "file": file, "shots": label, "mode": mode,
                                             "direction": dd, "f": list(map(float, f)), "err": list(map(float, e)),
                                             "sigma": list(map(float, s)), "cpu": cpu}) + "\n")
                sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:])
