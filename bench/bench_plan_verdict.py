"""The verdict's set-aside test (issue 25, session 25) on bench/bench_identify_real.py's cases:
does it flag good fits? Not a test: writes one JSON line per case and prints the counts.

    OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_plan_verdict.py TREE N OUT.jsonl [BEFORE.jsonl]

TREE: the source tree to run (e.g. main's, extracted with git archive, for "before"; this
worktree for "after"); the first N cases of bench_identify_real (seed 12: reference-mesh peak
lists of nine plates with 0-3 modes per octave dropped and 0-2 random spurious peaks), each
fitted by ``labid.workflows.identification.run``; recorded: peaks, peaks set aside, chi^2, dof,
p, consistent, identified, the errors in stds. With BEFORE, the counts of both and every case
whose verdict changed. "Right answer": every constant within 3 of its stds of the truth.
"""
import json
import sys
import time

tree, N, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
sys.path.insert(0, tree)
import numpy as np  # noqa: E402

import bench.bench_identify_real as B  # noqa: E402
from labid.workflows.identification import problem_from_features, run  # noqa: E402


def counts(rows, label):
    right = [r for r in rows if r["max_z"] <= 3]
    print(f"{label}: {len(rows)} cases; consistent {sum(r['consistent'] for r in rows)}, identified "
          f"{sum(r['identified'] for r in rows)}; right answers {len(right)}: consistent "
          f"{sum(r['consistent'] for r in right)}, identified {sum(r['identified'] for r in right)}; peaks set aside "
          f"by right answers {sum(r['set_aside'] for r in right)} of {sum(r['n_peaks'] for r in right)}, "
          f"spurious injected {sum(r['spurious'] for r in rows)}")


rng = np.random.default_rng(12)
plates = B._plates()
rows = []
with open(out, "w") as fh:
    for k in range(N):
        spec, doc, names, truth, start, info = B.draw_case(k, rng, plates)
        t0 = time.process_time()
        est = run(problem_from_features(doc, specimen=spec), names, start)
        z = {n: (est.params[n] - truth[n]) / est.std[i] for i, n in enumerate(est.names)}
        pairing = est.fit.get("pairing") or []
        r = {"case": k, "plate": spec.name, **info, "n_peaks": len(pairing),
             "set_aside": sum(p["mode_index"] is None for p in pairing), "chi2": est.fit["chi2"],
             "dof": est.fit["dof"], "p": est.fit["p_value"], "consistent": bool(est.fit["consistent"]),
             "identified": bool(est.fit["identified"]), "questionable": bool(est.fit.get("questionable")),
             "max_z": max(abs(v) for v in z.values()), "cpu": time.process_time() - t0}
        rows.append(r)
        fh.write(json.dumps(r) + "\n")
        fh.flush()
        print(k, spec.name, r["n_peaks"], "set aside", r["set_aside"], "consistent", r["consistent"],
              "identified", r["identified"], f"max|z| {r['max_z']:.2f}", flush=True)
counts(rows, "this tree")
if len(sys.argv) > 4:
    before = [json.loads(line) for line in open(sys.argv[4])]
    counts(before, "before")
    for b, a in zip(before, rows):
        if (b["consistent"], b["identified"]) != (a["consistent"], a["identified"]):
            print("  changed:", a["case"], a["plate"], b, "->", a)
