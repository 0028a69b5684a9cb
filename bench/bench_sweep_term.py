"""Issue 24, session 29 (h61): the sweep's wavelet-bias term measured once per burst, over seeds.

The rig of bench_unknown_plate.py ``sweep_far`` (bench/rigs/cfrp_pzt_sweep_2dir_far.toml, 5 bursts
60-250 kHz, MFC pairs 20 / 40 cm along 0 and 90 deg, 1 mV noise) on bench/rigs/cfrp_large.toml,
INDEPENDENT records (bench/independent/legendre_safe.py's transfer through the rig's chain), the
specimen file 40 % soft or stiff; the reference is the TRUE plate's group velocity (legendre_safe).

``make``: per (seed, file) 80 records (16 per burst; the first 10 are the 2-shot run of that seed),
pickled in DIR once. ``run``: analyses them with the code of LABID_SRC (default: this tree) and
writes per curve (seed, file, shots, mode, direction, f, err, sigma) as JSON lines to OUT, so that
two versions of the code are compared on the very same records. ``summary``: per curve group and
version, points, within 1 %, rms of err / sigma.

Run: OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_sweep_term.py make DIR --seeds 0,1,2 [--n 80]
     LABID_SRC=TREE nice .venv/bin/python bench/bench_sweep_term.py run DIR OUT [--shots 10,80]
     .venv/bin/python bench/bench_sweep_term.py summary OUT_BEFORE OUT_AFTER
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, os.environ.get("LABID_SRC", str(Path(__file__).resolve().parents[1])))
from bench._machine import machine  # noqa: E402

SCALES = {"soft": 1 / 0.6, "stiff": 1 / 1.4}


def _rig():
    from bench.bench_unknown_plate import HERE
    from labid.inputs.rig import rig_from_text
    from labid.inputs.specimen import load_specimen
    path = HERE / "rigs" / "cfrp_pzt_sweep_2dir_far.toml"
    return rig_from_text(path.read_text(), str(path)), load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))


def make(a) -> None:
    from bench.bench_unknown_plate import records
    rig, large = _rig()
    Path(a.dir).mkdir(parents=True, exist_ok=True)
    for seed in (int(s) for s in a.seeds.split(",")):
        for file in a.files.split(","):
            out = Path(a.dir) / f"{file}_{seed}.pkl"
            if out.exists():
                continue
            c = time.process_time()
            recs = records(replace(rig, sim=replace(rig.sim, truth_scale=(("*", SCALES[file]),))), large, a.n,
                           seed, "independent")
            with out.open("wb") as fh:
                pickle.dump(recs, fh)
            print(f"{out}: {len(recs)} records, {time.process_time() - c:.1f} s CPU", flush=True)


def run(a) -> None:
    from bench.bench_unknown_plate import run_case
    rig, large = _rig()
    for pkl in sorted(Path(a.dir).glob("*.pkl")):
        file, seed = pkl.stem.split("_")
        recs = pickle.loads(pkl.read_bytes())
        for n in (int(s) for s in a.shots.split(",")):
            if n > len(recs):
                continue
            rows, cpu, _ = run_case(f"sweep_far, {n} shots", rig, large, n, SCALES[file], "independent",
                                    seed=int(seed), recs=recs[:n], trace=False)
            with open(a.out, "a") as fh:
                for mode, dd, k, _lo, _hi, e, s, z, f in rows:
                    fh.write(json.dumps({"seed": int(seed), "file": file, "shots": n, "mode": mode, "direction": dd,
                                         "f": list(map(float, f)), "err": list(map(float, e)),
                                         "sigma": list(map(float, s)), "cpu": cpu}) + "\n")


def summary(paths) -> None:
    tabs = []
    for p in paths:
        tab: dict = {}
        for ln in Path(p).read_text().splitlines():
            r = json.loads(ln)
            k = (r["shots"], r["file"], r["mode"], r["direction"])
            t = tab.setdefault(k, {"seeds": set(), "n": 0, "ok": 0, "z2": []})
            e, s = np.array(r["err"]), np.array(r["sigma"])
            t["seeds"].add(r["seed"])
            t["n"] += e.size
            t["ok"] += int(np.sum(np.abs(e) <= 0.01))
            t["z2"] += list((e / s) ** 2)
        tabs.append(tab)
    print("| shots | file | curve | " + " | ".join(f"{Path(p).stem}: seeds, points, within 1 %, z rms" for p in paths)
          + " |")
    print("|---|---|---|" + "---|" * len(paths))
    for k in sorted(set().union(*tabs), key=lambda k: (k[0], k[1], k[2], k[3])):
        cells = []
        for tab in tabs:
            t = tab.get(k)
            cells.append("-" if t is None else f"{len(t['seeds'])}, {t['n']}, {t['ok']}, "
                         f"{np.sqrt(np.mean(t['z2'])):.2f}")
        print(f"| {k[0]} | {k[1]} | {k[2]} {k[3]:g} deg | " + " | ".join(cells) + " |")


def main(argv) -> None:
    if argv and argv[0] == "summary":
        return summary(argv[1:])
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=("make", "run"))
    ap.add_argument("dir")
    ap.add_argument("out", nargs="?")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--files", default="soft,stiff")
    ap.add_argument("--n", type=int, default=80)
    ap.add_argument("--shots", default="10,80")
    a = ap.parse_args(argv)
    print(f"machine: {machine()}", flush=True)
    make(a) if a.what == "make" else run(a)


if __name__ == "__main__":
    main(sys.argv[1:])
