"""The long fuzz run of issues 15 and 27: N generated cases per family through every command,
tallied against the CLI contract (exit 0/2/3, a 2 in one line; never a traceback, an exit 1,
a hang past the per-case CPU bound or a signal).

    PYTHONPATH=. python bench/bench_fuzz.py [--n 60] [--root /path/to/labid/tree] [--json out.json]
                                            [--checkpoint fuzz.jsonl] [--families a,b,..]

Families (the generator is ``tests/fuzzcases.py``, hypothesis, derandomized: every tree and
every restart sees the same cases in the same order):

- ``specimen``: mutated specimen TOML -> ``modes``, ``dispersion``;
- ``features``: mutated features JSON -> ``identify`` (and ``diagnose``, one case in 10);
- ``rig``: mutated rig TOML -> ``acquire``;
- ``run``: damaged run files (bit flips, truncation, bad attributes) -> ``report``, ``export``,
  ``analyze``;
- ``results``: a run whose stored analysis / identification / diagnosis is a mutated copy of
  a real one -> ``report``, ``export --uff --csv``, ``identify`` storing into it;
- ``recording``: damaged CSV, WAV, MAT, TDMS and UFF recordings -> ``import``;
- ``nested``: features JSON and specimen / rig TOML nested up to 100,000 deep;
- ``options``: one hostile value for one option of every command (``modes``, ``dispersion``,
  ``acquire``, ``import``, ``analyze``, ``identify``, ``diagnose``, ``report``, ``export``,
  ``demo``; ``gui`` opens a window and is tested headless in tests/unit/labid/gui instead).

``--root`` runs the same cases against another checkout (the "before" column of
bench/RESULTS.md). Cases run in-process (each bounded in CPU time: ``--cpu``) under an
address-space limit of 3 GiB, so that an input that asks for petabytes fails fast instead of
starving the machine. ``--checkpoint FILE`` appends each case's outcome as it ends; a rerun
with the same file skips the cases it holds (restart after a kill, or on a busy machine).
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
FAMILIES = "specimen,features,rig,run,results,recording,nested,options"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60, help="cases per family (default 60)")
    ap.add_argument("--root", default=str(HERE), help="the labid tree to test (default: this one)")
    ap.add_argument("--cpu", type=float, default=120.0, help="per-case CPU-time bound, s (a hang past it)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--checkpoint", default=None, help="JSON-lines file of finished cases (resumable)")
    ap.add_argument("--families", default=FAMILIES)
    args = ap.parse_args()
    for k in ("json", "checkpoint"):                 # before the chdir below
        if getattr(args, k):
            setattr(args, k, str(Path(getattr(args, k)).resolve()))
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
    os.chdir(work)                                   # an option value naming a file lands here
    os.environ["LABID_CRASH_DIR"] = str(work)
    cfg = settings(max_examples=args.n, deadline=None, derandomize=True, database=None,
                   suppress_health_check=list(HealthCheck))
    done: dict[str, dict] = {}
    if args.checkpoint and Path(args.checkpoint).exists():
        for line in Path(args.checkpoint).read_text().splitlines():
            if line.strip():
                rec = json.loads(line)
                if rec.get("started"):           # begun and never finished: it killed the process
                    done.setdefault(rec["id"], {**rec, "rc": None, "err": "the case ended the process",
                                                "kind": "signal"})
                else:
                    done[rec["id"]] = rec
    tally: dict[str, Counter] = {}
    examples: dict[str, list] = {}
    seq: Counter = Counter()
    spent = {"cpu": 0.0, "wall": 0.0}

    def run(family: str, argv: list) -> object:
        seq[family] += 1
        cid = f"{family}#{seq[family]}"
        if cid in done:                              # checkpointed: counted, not run again
            rec = done[cid]
            tally.setdefault(family, Counter())[rec["kind"]] += 1
            return fc.Outcome(rec["argv"], rec["rc"], rec["err"], rec["kind"])
        if args.checkpoint:
            with open(args.checkpoint, "a") as fh:
                fh.write(json.dumps({"id": cid, "started": True, "argv": [str(a)[:300] for a in argv]}) + "\n")
        t0, c0 = time.time(), time.process_time()
        o = fc.run_case([str(a) for a in argv], args.cpu)
        spent["wall"] += time.time() - t0
        spent["cpu"] += time.process_time() - c0
        tally.setdefault(family, Counter())[o.kind] += 1
        if o.kind in fc.BAD and len(examples.setdefault(family, [])) < 5:
            crash = o.err.split("traceback in ")[-1].split(" (exit 1)")[0].strip()
            tb = Path(crash).read_text()[-800:] if crash.endswith(".txt") and Path(crash).exists() else ""
            examples[family].append({"argv": [str(a)[:200] for a in o.argv], "kind": o.kind,
                                     "err": o.err.strip()[-300:], "traceback": tb})
        if args.checkpoint:
            with open(args.checkpoint, "a") as fh:
                fh.write(json.dumps({"id": cid, "argv": [str(a)[:300] for a in o.argv], "rc": o.rc,
                                     "err": o.err[-2000:], "kind": o.kind}) + "\n")
        return o

    families = args.families.split(",")
    t0, c0 = time.time(), time.process_time()
    base_run = base_features = None
    if {"run", "results", "options"} & set(families):
        base_run = work / "base.h5"                  # one hammer hit, analysed
        o = fc.run_case(["acquire", "--specimen", "aluminium", "--out", str(base_run), "--hits", "1",
                         "--waves", "0"], args.cpu)
        assert o.rc == 0, o.err
        o = fc.run_case(["analyze", str(base_run)], args.cpu)
        assert o.rc == 0, o.err
    if {"features", "results", "options"} & set(families):
        m = work / "m.json"                          # a cheap modal features file of that run
        assert fc.run_case(["modes", "aluminium", "--n", "4", "--mesh", "6x6", "--json", str(m)], args.cpu).rc == 0
        freqs = [round(1.01 * x, 4) for x in json.loads(m.read_text())["frequencies_hz"]]
        base_features = work / "feats.json"
        base_features.write_text(json.dumps({"specimen": "aluminium", "modal": {"frequencies_hz": freqs},
                                             "analysis": {"run": "base.h5"}}))

    if "specimen" in families:
        @cfg
        @given(doc=fc.mutated(fc.base_specimen()),
               fmax=st.sampled_from([1e3, 1e12, 1e-9, -5.0, float("nan"), 2e5]))
        def specimens(doc, fmax):
            p = fc.write_case(work / "spec.toml", fc.toml_text(doc))
            run("specimen -> modes", ["modes", p, "--n", "1", "--mesh", "2x2"])
            run("specimen -> dispersion", ["dispersion", p, "--fmax", repr(fmax), "--n", "2"])
        specimens()
    if "features" in families:
        base = fc.base_features()
        base["modal"] = {"frequencies_hz": [20.0, 30.0, 45.0], "mode_index": [1, 2, None]}
        count = [0]

        @cfg
        @given(doc=st.one_of(fc.mutated(base, extra_keys=("typo", "modal", "specimen", "wavelet")),
                             fc.mutated(fc.base_features())))
        def features(doc):
            p = fc.write_case(work / "f.json", json.dumps(doc, allow_nan=True))
            run("features -> identify", ["identify", p, "--params", "E"])
            count[0] += 1
            if count[0] % 10 == 0:
                run("features -> diagnose", ["diagnose", p, "--params", "E"])
        features()
    if "rig" in families:
        @cfg
        @given(text=fc.rig_texts())
        def rigs(text):
            p = fc.write_case(work / "rig.toml", text)
            out = work / "rig_run.h5"
            out.unlink(missing_ok=True)
            o = run("rig -> acquire", ["acquire", "--rig", p, "--specimen", "cfrp", "--out", out,
                                       "--hits", "0", "--waves", "0"])
            if o.rc not in (0, None) and out.exists():
                tally["rig -> acquire"]["empty run file left"] += 1
        rigs()
    if "run" in families:
        @cfg
        @given(how=st.sampled_from(["flip", "flip", "truncate", *fc.ATTR_DAMAGE]), seed=st.integers(0, 10_000))
        def runs(how, seed):
            p = fc.damaged_copy(base_run, work / "damaged.h5", how, seed)
            run("run file -> report", ["report", p, "--out", work / "r.html"])
            run("run file -> export", ["export", p, "--csv", work / "csv"])
            run("run file -> analyze", ["analyze", p, "--out", work / "d.json"])
        runs()
    if "results" in families:
        real = {}
        with fc.h5py.File(base_run, "r") as f:
            feats = json.loads(f["results/analysis/features/json"][()].decode())
        o = fc.run_case(["identify", base_features, "--params", "E", "--json", work / "ident.json"], args.cpu)
        assert o.rc in (0, 3), o.err
        real["identification"] = json.loads((work / "ident.json").read_text())
        real["features"] = feats
        real["diagnosis"] = {"gap": {"before": 3.0, "after": 1.0, "p_value_before": 0.001}, "verdict": "none",
                             "where": ["modal"], "effects": [{"name": "sensor_mass", "magnitude": 0.002,
                                                               "unit": "kg", "gap_after": 1.0, "score": 0.5,
                                                               "refitted": True}]}

        @cfg
        @given(name=st.sampled_from(["identification", "diagnosis", "analysis"]), data=st.data())
        def results(name, data):
            doc = data.draw(fc.mutated(real["features"] if name == "analysis" else real[name]))
            if name == "analysis":
                doc = {"features": {"json": json.dumps(doc, allow_nan=True)}, "notes": ["fuzzed"]}
            p = fc.with_results(base_run, work / "res.h5", name, doc)
            run("results -> report", ["report", p, "--out", work / "r.html"])
            run("results -> export", ["export", p, "--csv", work / "csv", "--uff", work / "r.uff"])
            if name == "identification":
                f = work / "feats_res.json"
                f.write_text(base_features.read_text().replace("base.h5", "res.h5"))
                run("results -> identify", ["identify", f, "--params", "E", "--json", work / "i.json"])
        results()
    if "recording" in families:
        recs = fc.recording_bases(work)

        @cfg
        @given(fmt=st.sampled_from(sorted(recs)), data=st.data())
        def recordings(fmt, data):
            blob = data.draw(fc.damaged_bytes(recs[fmt].read_bytes()))
            p = fc.write_case(work / f"rec.{fmt}", blob)
            out = work / "imp.h5"
            out.unlink(missing_ok=True)
            extra = ["--units", "force=2.5V,acc1=2.5V"] if fmt == "wav" else []
            m = "1=force,2=acc1" if fmt == "wav" else "force=force,acc1=acc1"
            run(f"recording ({fmt}) -> import", ["import", p, "--rig", "default", "--specimen", "cfrp", "--out",
                                                 out, "--map", m, "--pretrigger", "0", *extra])
        recordings()
    if "nested" in families:
        @cfg
        @given(kind=st.sampled_from(["json", "toml", "rig"]), data=st.data())
        def nested(kind, data):
            if kind == "rig":
                text = fc.base_rig_text() + "\n" + data.draw(fc.nested_text("toml")).splitlines()[-1] + "\n"
                p = fc.write_case(work / "nested_rig.toml", text)
                run("nested -> acquire", ["acquire", "--rig", p, "--specimen", "cfrp", "--out", work / "n.h5",
                                          "--hits", "0", "--waves", "0"])
            elif kind == "json":
                p = fc.write_case(work / "nested.json", data.draw(fc.nested_text("json")))
                run("nested -> identify", ["identify", p, "--params", "E"])
            else:
                p = fc.write_case(work / "nested.toml", data.draw(fc.nested_text("toml")))
                run("nested -> modes", ["modes", p, "--n", "1", "--mesh", "2x2"])
        nested()
    if "options" in families:
        csv = fc.recording_bases(work)["csv"] if "recording" not in families else work / "base.csv"
        fill = {"RUN": str(base_run), "FEATS": str(base_features), "OUT": str(work / "opt.h5"),
                "FEATSOUT": str(work / "opt.features.json"), "CSV": str(csv)}

        @cfg
        @given(case=fc.option_cases())
        def options(case):
            cmd, argv, opt, value = case
            argv = [fill.get(a, a.replace("DIR", str(work))) for a in argv]
            (work / "opt.h5").unlink(missing_ok=True)
            run(f"options -> {cmd}", argv)
        options()

    wall, cpu = time.time() - t0, time.process_time() - c0
    total = Counter()
    for c in tally.values():
        total.update(c)
    print(f"labid tree: {Path(labid.__file__).resolve().parents[1]}")
    print("| family | cases | ok (0/3) | user error (2, one line) | traceback | exit 1 | multi-line 2 | hang | signal |")
    print("|---|---|---|---|---|---|---|---|---|")
    for fam, c in [*sorted(tally.items()), ("all", total)]:
        n = sum(v for k, v in c.items() if k != "empty run file left")
        print(f"| {fam} | {n} | {c['ok']} | {c['user']} | {c['traceback']} | {c['internal']} | "
              f"{c['multiline']} | {c['hang']} | {c['signal']} |")
    print(f"this session: wall {wall:.0f} s, CPU {cpu:.0f} s (this process; cases run now: wall "
          f"{spent['wall']:.0f} s, CPU {spent['cpu']:.0f} s); load {os.getloadavg()[0]:.2f}")
    for fam, ex in examples.items():
        for e in ex[:3]:
            print(f"  {fam}: {e['kind']}: {' '.join(map(str, e['argv']))[:160]} :: {e['err'][-200:]!r}")
            if e.get("traceback"):
                print("    " + e["traceback"].replace("\n", "\n    "))
    if args.json:
        Path(args.json).write_text(json.dumps({"tally": {k: dict(v) for k, v in tally.items()},
                                               "examples": examples, "wall_s": wall, "cpu_s": cpu}, indent=1))
    os.chdir(HERE)
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
