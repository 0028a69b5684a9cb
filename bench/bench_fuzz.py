"""The long fuzz run of issue 15: N generated cases per family through every command,
tallied against the CLI contract (exit 0/2/3, a 2 in one line; never a traceback,
an exit 1, a hang past the per-case timeout or a signal).

    PYTHONPATH=. python bench/bench_fuzz.py [--n 200] [--root /path/to/labid/tree] [--json out.json]

``--root`` runs the same generated cases against another checkout (the "before"
column of bench/RESULTS.md: ``--root /work/main``). Cases run in-process (a case's
timeout via SIGALRM) under an address-space limit of 3 GiB, so that an input that
asks for petabytes fails fast instead of starving the machine. The generator is
``tests/fuzzcases.py`` (hypothesis, derandomized: both trees see the same cases).
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import shutil
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200, help="cases per family (default 200)")
    ap.add_argument("--root", default=str(HERE), help="the labid tree to test (default: this one)")
    ap.add_argument("--timeout", type=float, default=60.0, help="per-case timeout, s")
    ap.add_argument("--json", default=None)
    ap.add_argument("--families", default="specimen,features,rig,run")
    args = ap.parse_args()
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))
    sys.path.insert(0, str(Path(args.root).resolve()))
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    os.environ.setdefault("MPLBACKEND", "Agg")
    spec = importlib.util.spec_from_file_location("fuzzcases", HERE / "tests" / "fuzzcases.py")
    fc = importlib.util.module_from_spec(spec)
    sys.modules["fuzzcases"] = fc
    spec.loader.exec_module(fc)
    import labid
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    work = Path(tempfile.mkdtemp(prefix="labid-fuzz-"))
    os.environ["LABID_CRASH_DIR"] = str(work)
    cfg = settings(max_examples=args.n, deadline=None, derandomize=True, database=None,
                   suppress_health_check=list(HealthCheck))
    tally: dict[str, Counter] = {}
    examples: dict[str, list] = {}

    def run(family: str, argv: list[str]) -> object:
        o = fc.run_case(argv, args.timeout)
        tally.setdefault(family, Counter())[o.kind] += 1
        if o.kind in fc.BAD and len(examples.setdefault(family, [])) < 5:
            crash = o.err.split("traceback in ")[-1].split(" (exit 1)")[0].strip()
            tb = Path(crash).read_text()[-600:] if crash.endswith(".txt") and Path(crash).exists() else ""
            inputs = {q.name: q.read_text(errors="replace")[:4000] for q in work.glob("*.toml")}
            examples[family].append({"argv": o.argv, "kind": o.kind, "err": o.err.strip()[-300:],
                                     "traceback": tb, "inputs": inputs})
        return o

    families = args.families.split(",")
    t0, c0 = time.time(), time.process_time()
    if "specimen" in families:
        @cfg
        @given(doc=fc.mutated(fc.base_specimen()),
               fmax=st.sampled_from([1e3, 1e12, 1e-9, -5.0, float("nan"), 2e5]))
        def specimens(doc, fmax):
            p = fc.write_case(work / "spec.toml", fc.toml_text(doc))
            run("specimen -> modes", ["modes", str(p), "--n", "1", "--mesh", "2x2"])
            run("specimen -> dispersion", ["dispersion", str(p), "--fmax", repr(fmax), "--n", "2"])
        specimens()
    if "features" in families:
        base = fc.base_features()
        base["modal"] = {"frequencies_hz": [20.0, 30.0, 45.0], "mode_index": [1, 2, None]}

        @cfg
        @given(doc=st.one_of(fc.mutated(base, extra_keys=("typo", "modal", "specimen", "wavelet")),
                             fc.mutated(fc.base_features())))
        def features(doc):
            p = fc.write_case(work / "f.json", json.dumps(doc, allow_nan=True))
            run("features -> identify", ["identify", str(p), "--params", "E"])
        features()
    if "rig" in families:
        @cfg
        @given(text=fc.rig_texts())
        def rigs(text):
            p = fc.write_case(work / "rig.toml", text)
            out = work / "rig_run.h5"
            out.unlink(missing_ok=True)
            o = run("rig -> acquire", ["acquire", "--rig", str(p), "--specimen", "cfrp", "--out", str(out),
                                       "--hits", "0", "--waves", "0"])
            if o.rc not in (0, None) and out.exists():
                tally["rig -> acquire"]["empty run file left"] += 1
        rigs()
    if "run" in families:
        base_run = work / "base.h5"
        o = fc.run_case(["acquire", "--specimen", "aluminium", "--out", str(base_run), "--hits", "1",
                         "--waves", "0"], args.timeout)
        assert o.rc == 0, o.err
        ATTR_DAMAGE, damaged_copy = fc.ATTR_DAMAGE, fc.damaged_copy

        @cfg
        @given(how=st.sampled_from(["flip", "flip", "truncate", *ATTR_DAMAGE]), seed=st.integers(0, 10_000))
        def runs(how, seed):
            p = damaged_copy(base_run, work / "damaged.h5", how, seed)
            run("run file -> report", ["report", str(p), "--out", str(work / "r.html")])
            run("run file -> export", ["export", str(p), "--csv", str(work / "csv")])
            run("run file -> analyze", ["analyze", str(p), "--out", str(work / "d.json")])
        runs()
    wall, cpu = time.time() - t0, time.process_time() - c0
    total = Counter()
    for c in tally.values():
        total.update(c)
    print(f"labid tree: {Path(labid.__file__).resolve().parents[1]}")
    print(f"| family | cases | ok (0/3) | user error (2, one line) | traceback | exit 1 | multi-line 2 | hang | signal |")
    print("|---|---|---|---|---|---|---|---|---|")
    for fam, c in [*tally.items(), ("all", total)]:
        n = sum(v for k, v in c.items() if k != "empty run file left")
        print(f"| {fam} | {n} | {c['ok']} | {c['user']} | {c['traceback']} | {c['internal']} | "
              f"{c['multiline']} | {c['hang']} | {c['signal']} |")
    print(f"wall {wall:.0f} s, CPU {cpu:.0f} s (this process); load {os.getloadavg()[0]:.2f}")
    for fam, ex in examples.items():
        for e in ex[:3]:
            print(f"  {fam}: {e['kind']}: {' '.join(map(str, e['argv']))[:120]} :: {e['err'][-160:]!r}")
            if e.get("traceback"):
                print("    " + e["traceback"].replace("\n", "\n    "))
    if args.json:
        Path(args.json).write_text(json.dumps({"tally": {k: dict(v) for k, v in tally.items()},
                                               "examples": examples, "wall_s": wall, "cpu_s": cpu}, indent=1))
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
