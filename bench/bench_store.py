"""Cost of storing a kept result (issue 29, session 27): ``store_result`` of an
identification on a run file that already keeps K identifications, and the whole
``labid identify`` process on the demo's features with K kept.

Inputs: the demo's run (``labid demo --seed 0 --workers 1 --out DEMO``: simulated shots
and results) and its stored identification (the identification-sized result, ~24 kB of
JSON, ~27 keys). For each K a run file is built once with plain h5py (the same bytes for
every tree timed): the demo's run without its identifications, plus K copies of the
demo's identification numbered 1..K (K-1 under ``/results/history/identification``, the
newest at ``/results/identification``). Every timed run works on a fresh copy of it.

Each measurement is its own process (a fresh interpreter, as ``labid identify`` is:
the store's probe cache starts empty), run with ``PYTHONPATH=<tree>`` from a directory
holding no labid package, so ``--tree before=/tmp/before`` ``--tree after=.`` times
two checkouts back to back (alternating, one repetition of each in turn). CPU is
user+sys of the process and of every child it waited for (the store's forked probes),
from ``os.times`` around ``store_result`` and from ``wait4`` for the whole process.
After each store the returned number, the history count and the file size are checked
and printed. Output: Markdown for ``bench/RESULTS.md``.

    OMP_NUM_THREADS=1 nice python bench/bench_store.py --demo /tmp/h50_demo \\
        --tree before=/tmp/before_h50 --tree after=. [--kept 0,1,5,20,50] [--reps 3] \\
        [--identify-kept 0,20] [--identify-reps 2]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench._machine import machine  # noqa: E402

NAME = "identification"

#: the timed child: one store_result in a fresh interpreter (labid imported before the clock)
STORE = r"""
import json, os, sys, time
import h5py
from labid.runresults import store_result
run, data_file, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
data = json.loads(open(data_file).read())
t0, w0 = os.times(), time.perf_counter()
where = store_result(run, "identification", data, by="bench")
w1, t1 = time.perf_counter(), os.times()
cpu = sum(getattr(t1, a) - getattr(t0, a) for a in ("user", "system", "children_user", "children_system"))
with h5py.File(run, "r") as f:
    hist = sorted(int(x) for x in f["results/history/identification"]) if "results/history/identification" in f else []
    number = int(f["results/identification/stored/number"][()])
    newest = json.loads(f["results/identification/json"].asstr()[()])["stored"]["number"]
ok = number == newest == k + 1 and hist == list(range(1, k + 1)) and f"no. {k + 1}" in where
print(json.dumps({"cpu": cpu, "wall": w1 - w0, "ok": ok, "size": os.path.getsize(run), "where": where}))
"""


#: the timed child: result_history (the panel's and the report's list of kept results)
HISTORY = r"""
import json, os, sys, time
from labid.runresults import result_history
run, k = sys.argv[1], int(sys.argv[2])
t0, w0 = os.times(), time.perf_counter()
hist = result_history(run, "identification")
w1, t1 = time.perf_counter(), os.times()
cpu = sum(getattr(t1, a) - getattr(t0, a) for a in ("user", "system", "children_user", "children_system"))
ok = [h["number"] for h in hist] == list(range(1, k + 1)) and all(h["by"] == "bench" for h in hist)
print(json.dumps({"cpu": cpu, "wall": w1 - w0, "ok": ok}))
"""


def kept_run(demo_run: Path, ident: dict, k: int, out: Path) -> None:
    """``out``: the demo's run without identifications, plus ``k`` kept identifications."""
    with h5py.File(demo_run, "r") as src, h5py.File(out, "w", libver="latest") as dst:
        for a, v in src.attrs.items():
            dst.attrs[a] = v
        for name in src:
            if name != "results":
                src.copy(src[name], dst, name)
        res = dst.create_group("results")
        for a, v in src["results"].attrs.items():
            res.attrs[a] = v
        for name in src["results"]:
            if name not in (NAME, "history"):
                src.copy(src["results"][name], res, name)
        for n in range(1, k + 1):
            where = f"history/{NAME}/{n}" if n < k else NAME
            src.copy(src[f"results/{NAME}"], res, where)
            g = res[where]
            doc = dict(ident, stored={"number": n, "time": "2026-11-28T23:00:00+0000", "by": "bench"})
            del g["json"]
            g["json"] = json.dumps(doc)
            del g["stored"]                     # the structured twin says the same as the JSON copy
            st = g.create_group("stored")
            st.attrs["NX_class"] = "NXcollection"
            st["number"] = n
            for key in ("time", "by"):
                st.create_dataset(key, data=doc["stored"][key], dtype=h5py.string_dtype())


class Failed(Exception):
    """A timed process that failed (its last line of stderr)."""


def run_child(tree: Path, argv: list[str], cwd: Path) -> tuple[float, float, str]:
    """(CPU s, wall s, stdout) of one process: user+sys of it and of every child it waited
    for (the rusage of this process's waited children, before and after)."""
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1")
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.perf_counter()
    proc = subprocess.run([sys.executable, *argv], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - w0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        last = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()][-1:] or ["?"]
        raise Failed(f"exit {proc.returncode}: {last[0][-300:]}")
    return (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime), wall, proc.stdout


def med(xs: list[float]) -> str:
    return f"{statistics.median(xs):.3f}"


def timed_reps(trees, reps: int, cwd: Path, argv: list[str], before=None, after=None):
    """``reps`` rounds of the child script ``argv`` under each (label, tree), ``before`` /
    ``after`` each run (``after`` only when it succeeded): per label the CPU and wall (s)
    the children report, their last ``size``, whether every ``ok`` held, the first failure."""
    cpu = {lab: [] for lab, _ in trees}
    wall = {lab: [] for lab, _ in trees}
    size, ok, fails = {}, True, {}
    for _ in range(reps):
        for lab, tree in trees:
            if before is not None:
                before()
            try:
                _, _, out = run_child(tree, argv, cwd)
            except Failed as e:
                fails.setdefault(lab, str(e))
                continue
            got = json.loads(out.strip().splitlines()[-1])
            cpu[lab].append(got["cpu"])
            wall[lab].append(got["wall"])
            if "size" in got:
                size[lab] = got["size"]
            ok &= got["ok"]
            if after is not None:
                after()
    return cpu, wall, size, ok, fails


def times_cells(trees, cpu: dict, wall: dict) -> str:
    """The CPU and wall medians of each tree, as table cells."""
    return " | ".join(f"{med(cpu[lab])} | {med(wall[lab])}" if cpu[lab] else "failed | failed" for lab, _ in trees)


def failed_cells(fails: dict) -> str:
    return "".join(f"; {lab} failed: {msg}" for lab, msg in fails.items())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demo", type=Path, required=True, help="folder of `labid demo --seed 0 --workers 1 --out`")
    ap.add_argument("--tree", action="append", default=[], help="label=path of a checkout (repeatable)")
    ap.add_argument("--kept", default="0,1,5,20,50")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--identify-kept", default="0,20")
    ap.add_argument("--identify-reps", type=int, default=2)
    a = ap.parse_args(argv)
    trees = [(t.split("=", 1)[0], Path(t.split("=", 1)[1]).resolve()) for t in a.tree] or [("this", ROOT)]
    kept = [int(x) for x in a.kept.split(",") if x != ""]
    ikept = [int(x) for x in a.identify_kept.split(",") if x != ""]
    demo_run = a.demo / "demo_run.h5"
    with h5py.File(demo_run, "r") as f:
        ident = json.loads(f[f"results/{NAME}/json"].asstr()[()])
    ident.pop("stored", None)
    print(f"## bench_store\n\n{machine(f'h5py {h5py.version.version} (HDF5 {h5py.version.hdf5_version})')}\n")
    print(f"uptime: {os.popen('uptime').read().strip()}\n")
    work = Path(tempfile.mkdtemp(prefix="bench_store_"))
    cwd = work / "cwd"                      # holds no labid package
    cwd.mkdir()
    try:
        data_file = work / "ident.json"
        data_file.write_text(json.dumps(ident))
        fixtures = {}
        for k in sorted(set(kept) | set(ikept)):
            fixtures[k] = work / f"kept{k}.h5"
            kept_run(demo_run, ident, k, fixtures[k])
        script = work / "store.py"
        script.write_text(STORE)
        print("### store_result of one identification (own process; CPU = user+sys incl. forked children)\n")
        print("| kept before | " + " | ".join(f"{lab} CPU s | {lab} wall s" for lab, _ in trees)
              + " | run file bytes before -> after (" + ", ".join(lab for lab, _ in trees) + ") | checks |")
        print("|---" * (2 + 2 * len(trees) + 1) + "|")
        for k in kept:
            run = work / "run.h5"

            def fresh(k=k, run=run):
                shutil.copyfile(fixtures[k], run)

            def tidy():
                for p in work.glob(".run.h5*"):
                    p.unlink()
            cpu, wall, size, ok, fails = timed_reps(trees, a.reps, cwd, [str(script), str(run), str(data_file), str(k)],
                                                    before=fresh, after=tidy)
            print(f"| {k} | " + times_cells(trees, cpu, wall)
                  + f" | {fixtures[k].stat().st_size} -> " + ", ".join(str(size.get(lab, "-")) for lab, _ in trees)
                  + f" | {'numbers, history, JSON copy right' if ok else 'WRONG'} ({a.reps} reps, medians)"
                  + failed_cells(fails) + " |", flush=True)
        hscript = work / "history.py"
        hscript.write_text(HISTORY)
        print("\n### result_history of the kept identifications (own process; CPU incl. forked children)\n")
        print("| kept | " + " | ".join(f"{lab} CPU s | {lab} wall s" for lab, _ in trees) + " | checks |")
        print("|---" * (2 + 2 * len(trees)) + "|")
        for k in kept:
            cpu, wall, _, ok, fails = timed_reps(trees, a.reps, cwd, [str(hscript), str(fixtures[k]), str(k)])
            print(f"| {k} | " + times_cells(trees, cpu, wall)
                  + f" | {'numbers and writers right' if ok else 'WRONG'} ({a.reps} reps, medians)"
                  + failed_cells(fails) + " |", flush=True)
        print("\n### whole `labid identify features.json --quiet --json X` (own process, wait4 CPU)\n")
        print("| kept before | " + " | ".join(f"{lab} CPU s | {lab} wall s" for lab, _ in trees) + " | CPU of each run |")
        print("|---" * (2 + 2 * len(trees)) + "|")
        for k in ikept:
            cpu = {lab: [] for lab, _ in trees}
            wall = {lab: [] for lab, _ in trees}
            for _ in range(a.identify_reps):
                for lab, tree in trees:
                    d = work / "demo"
                    shutil.rmtree(d, ignore_errors=True)
                    shutil.copytree(a.demo, d)
                    shutil.copyfile(fixtures[k], d / "demo_run.h5")
                    c, w, _ = run_child(tree, ["-m", "labid.cli.main", "identify", str(d / "features.json"),
                                                 "--quiet", "--json", str(work / "out.json")], cwd)
                    with h5py.File(d / "demo_run.h5", "r") as f:
                        n = int(f["results/identification/stored/number"][()])
                    if n != k + 1:
                        raise SystemExit(f"identify with {tree}: stored no. {n}, expected {k + 1}")
                    cpu[lab].append(c)
                    wall[lab].append(w)
            print(f"| {k} | " + " | ".join(f"{med(cpu[lab])} | {med(wall[lab])}" for lab, _ in trees)
                  + " | " + "; ".join(f"{lab} " + ", ".join(f"{x:.2f}" for x in cpu[lab]) for lab, _ in trees)
                  + f" ({a.identify_reps} reps, medians) |",
                  flush=True)
        print(f"\nuptime at end: {os.popen('uptime').read().strip()}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
