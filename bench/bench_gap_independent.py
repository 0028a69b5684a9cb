"""The gap diagnosis on cases from the independent generator (issue 28; bench/blind_independent.py).

Run (one nice process; resumes from --out):
  OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_gap_independent.py [--plan calibration|effects|all]
      [--only KIND=N,...] [--out bench/gap_independent_cases.jsonl] [--summary-only]
      [--waves legendre|safe] [--with-waves]

Each case: the features from the Ritz plate and, for wave data, the independent Legendre SAFE
(``--waves legendre``, the default since session 24; ``safe``: engine.safe at a higher order,
the generator of session 23's rows, which carry no ``wave_generator``), diagnosed as a lab would
(``labid.workflows.diagnosis.run_diagnosis``: modal only -> E1, E2, G12 (E, G); with waves ->
all six constants with a 30 % prior). For an effect case the oracle is the chi^2 that the
noise-free data leave after labid identify's fit of the constants alone (same parameters,
sigmas and prior): an effect (in the library or not) below ``VISIBLE`` is not in the data,
and `none` counts right.
Prints the markdown summary for bench/RESULTS.md (false-alarm rate with its Clopper-Pearson
95 % interval, top-1 per effect, magnitude errors, out-of-library outcome, CPU per case).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.blind_independent import KINDS, LIBRARY, OUT_OF_LIBRARY, WAVE_GENERATORS, draw, recipe  # noqa: E402
from labid.base import progress  # noqa: E402
from labid.workflows.diagnosis import run_diagnosis  # noqa: E402
from labid.workflows.identification import estimation  # noqa: E402

PLANS = {
    "calibration": [("clean", 220)],
    "effects": [(k, 20) for k in LIBRARY] + [(k, 10) for k in OUT_OF_LIBRARY],
}
PLANS["all"] = PLANS["calibration"] + PLANS["effects"]
#: oracle chi^2 (noise-free data, constants refitted) below which an effect is not in the data
VISIBLE = 30.0
#: look-alikes outside the library that a verdict may name (``diagnosis_notes``/``confusable``)
LOOKALIKE = {"curvature": "support_stiffness"}
#: effects whose sign the free-free frequencies do not see (even in the magnitude)
UNSIGNED = ("density_gradient", "thickness_taper")


def oracle(case) -> float:
    """chi^2 of labid identify's constants-only fit to the noise-free features (case sigmas)."""
    if case.kind == "clean":
        return 0.0
    doc = json.loads(json.dumps(case.features))
    clean = iter(case.noiseless)
    if doc.get("modal"):
        doc["modal"]["frequencies_hz"] = [next(clean) for _ in doc["modal"]["frequencies_hz"]]
    for w in doc["waves"]:
        w["group_velocity_m_s"] = [next(clean) for _ in w["group_velocity_m_s"]]
    try:
        pr = estimation.problem_from_features(doc)
        res = estimation.run(pr, case.params, None, method="lm", prior=case.prior, scale_sigmas=False,
                             consistency=False).to_dict()
        return float(res["fit"]["chi2"])
    except Exception:  # noqa: BLE001 - recorded as unknown
        return float("nan")


def generator_of(r: dict) -> str:
    """Who made a row's wave data: 'legendre', 'safe' (session 23's rows carry no field) or '-'."""
    if r["data"] == "modal":
        return "-"
    return r.get("wave_generator") or "safe"


def run_case(seed: int, kind: str, waves: str = "legendre") -> dict:
    t0 = time.process_time()
    case = draw(seed, kind, wave_generator=waves)
    t1 = time.process_time()
    row = {"seed": seed, "kind": kind, "specimen": case.specimen, "data": case.data, "n_modes": case.n_modes,
           "noise": case.noise, "magnitude": case.magnitude, "params": case.params, "prior": case.prior,
           "wave_generator": case.detail["wave_generator"], "cpu_generate": t1 - t0}
    try:
        res = run_diagnosis(case.features, names=case.params, prior=case.prior)
    except Exception as exc:  # noqa: BLE001 - recorded as a failed case
        row.update(verdict="error", error=f"{type(exc).__name__}: {exc}", confusable=[])
        row["cpu_diagnose"] = time.process_time() - t1
        return row
    t2 = time.process_time()
    chosen = next((e for e in res["effects"] if e["name"] == kind), None)
    g = res["gap"]
    row.update(verdict=res["verdict"], confusable=res["confusable"], groups=res.get("confusable_groups"),
               magnitude_est=None if chosen is None else chosen["magnitude"],
               magnitude_std=None if chosen is None else chosen["std"],
               chi2=g["chi2_before"], dof=g["dof"], threshold=g["threshold_chi2"], p=g["p_value_before"],
               gap_before=g["before"], gap_after=g["after"], n=g["n"],
               top=[(e["name"], round(e["delta_chi2"], 2), e["refitted"]) for e in res["effects"][:4]],
               notes=res.get("diagnosis_notes", [])[-3:], cpu_diagnose=t2 - t1)
    row["oracle_chi2"] = oracle(case)
    row["cpu_oracle"] = time.process_time() - t2
    return row


def visible(r: dict) -> bool:
    """Whether the case's effect is in the data (oracle chi^2 >= VISIBLE; clean: no effect)."""
    o = r.get("oracle_chi2")
    return r["kind"] != "clean" and (o is None or not (o < VISIBLE))


def correct(r: dict) -> bool:
    k, v = r["kind"], r["verdict"]
    if k == "clean":
        return v == "none"
    if not visible(r) and v == "none":
        return True                  # an effect the data do not hold: `none` is right
    if k in OUT_OF_LIBRARY:
        if v == "unattributed":
            return True
        look = LOOKALIKE.get(k)
        return look is not None and (v == look or look in r.get("confusable", [])) and any(
            k in n for n in r.get("notes", []) + [json.dumps(r.get("groups"))])
    return v == k or k in r.get("confusable", [])


def mag_error(r: dict) -> float | None:
    if r.get("magnitude_est") is None or not r["magnitude"]:
        return None
    est, true = r["magnitude_est"], r["magnitude"]
    if r["kind"] in UNSIGNED:
        est, true = abs(est), abs(true)
    return abs(est / true - 1.0)


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    a = 1.0 - level
    lo = 0.0 if k == 0 else float(stats.beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def _ci(k: int, n: int) -> str:
    lo, hi = clopper_pearson(k, n)
    return f"{lo:.0%}-{hi:.0%}" if n else "-"


def tables(rows: list[dict], plan: list[tuple[str, int]]) -> str:
    """The RESULTS tables: per library effect ran / asked, visible, top-1 and right (top-1 or
    group) among the visible with the 95 % Clopper-Pearson interval, magnitude within 30 % (max
    error), what the invisible cases got; per out-of-library effect the same with `unattributed`."""
    asked = dict(plan)
    out = ["| effect | ran / asked | visible | top-1 (visible) | right: top-1 or group (visible, 95 % CI) | "
           "magnitude within 30 % (max error) | invisible cases -> |", "|---|---|---|---|---|---|---|"]
    tot = Counter()
    for k in LIBRARY:
        sel = [r for r in rows if r["kind"] == k]
        if not sel:
            continue
        vis = [r for r in sel if visible(r)]
        top1 = sum(r["verdict"] == k for r in vis)
        right = [r for r in vis if correct(r)]
        m = [e for r in right for e in [mag_error(r)] if e is not None]
        inv = Counter(r["verdict"] for r in sel if not visible(r))
        out.append(f"| {k} | {len(sel)} / {asked.get(k, '-')} | {len(vis)} | {top1} | {len(right)} "
                   f"({_ci(len(right), len(vis))}) | "
                   + (f"{sum(e <= 0.3 for e in m)}/{len(m)} ({max(m):.0%})" if m else "-")
                   + " | " + (", ".join(f"{n} {v}" for v, n in inv.items()) or "-") + " |")
        tot.update(ran=len(sel), asked=asked.get(k, 0), vis=len(vis), top1=top1, right=len(right),
                   mag=sum(e <= 0.3 for e in m), nmag=len(m), allright=sum(map(correct, sel)))
    if tot:
        out.append(f"| **all** | {tot['ran']} / {tot['asked']} | {tot['vis']} | {tot['top1']} | **{tot['right']}** "
                   f"({_ci(tot['right'], tot['vis'])}) | **{tot['mag']}/{tot['nmag']}** | "
                   f"{tot['allright']} of {tot['ran']} right incl. invisible |")
    out += ["", "| effect | ran / asked | visible (oracle >= 30) | visible -> unattributed | visible -> other | "
            "invisible -> |", "|---|---|---|---|---|---|"]
    for k in OUT_OF_LIBRARY:
        sel = [r for r in rows if r["kind"] == k]
        if not sel:
            continue
        vis = [r for r in sel if visible(r)]
        ok = [r for r in vis if correct(r)]
        other = Counter(r["verdict"] for r in vis if not correct(r))
        inv = Counter(r["verdict"] for r in sel if not visible(r))
        out.append(f"| {k} | {len(sel)} / {asked.get(k, '-')} | {len(vis)} | {len(ok)} | "
                   + (", ".join(f"{n} {v}" for v, n in other.items()) or "-") + " | "
                   + (", ".join(f"{n} {v}" for v, n in inv.items()) or "-") + " |")
    vis = [r for r in rows if r["kind"] in OUT_OF_LIBRARY and visible(r)]
    if vis:
        k = sum(map(correct, vis))
        out.append(f"| **all** | {sum(r['kind'] in OUT_OF_LIBRARY for r in rows)} | {len(vis)} | **{k}** "
                   f"({k / len(vis):.0%}, 95 % CI {_ci(k, len(vis))}) | | |")
    return "\n".join(out)


def summary(rows: list[dict]) -> str:
    out = []
    clean = [r for r in rows if r["kind"] == "clean"]
    if clean:
        fa = [r for r in clean if r["verdict"] != "none"]
        lo, hi = clopper_pearson(len(fa), len(clean))
        out.append(f"- clean: false alarms {len(fa)} of {len(clean)} = {len(fa) / len(clean):.1%} "
                   f"(95 % CI {lo:.1%}-{hi:.1%}); verdicts {dict(Counter(r['verdict'] for r in clean))}")
        for key in ("specimen", "data", "waves by"):
            parts = defaultdict(list)
            for r in clean:
                parts[generator_of(r) if key == "waves by" else r[key]].append(r["verdict"] != "none")
            out.append(f"  - by {key}: " + ", ".join(f"{k} {sum(v)}/{len(v)}" for k, v in sorted(parts.items())))
        for lo_n, hi_n in ((10, 20), (21, 30), (31, 40)):
            sel = [r for r in clean if lo_n <= r["n_modes"] <= hi_n]
            if sel:
                out.append(f"  - {lo_n}-{hi_n} modes: {sum(r['verdict'] != 'none' for r in sel)}/{len(sel)}")
        ps = np.array([r["p"] for r in clean if r.get("p") is not None])
        if ps.size:
            out.append(f"  - p-values: fraction below 0.01 / 0.05 / 0.5: {np.mean(ps < 0.01):.3f} / "
                       f"{np.mean(ps < 0.05):.3f} / {np.mean(ps < 0.5):.3f} (uniform: 0.01 / 0.05 / 0.5); "
                       f"KS p = {stats.kstest(ps, 'uniform').pvalue:.2g}")
        if fa:
            out.append("  - false alarms: " + "; ".join(
                f"seed {r['seed']} {r['specimen']} {r['data']} {r['n_modes']} modes -> {r['verdict']} "
                f"(chi2 {r.get('chi2', float('nan')):.1f}/{r.get('threshold', float('nan')):.1f})" for r in fa))
    lib = [r for r in rows if r["kind"] in LIBRARY]
    if lib:
        out.append("| effect | cases | right (top-1 or group) | invisible (oracle < 30) | verdicts | "
                   "magnitude error median / max | within 30 % |")
        out.append("|---|---|---|---|---|---|---|")
        for k in LIBRARY:
            sel = [r for r in lib if r["kind"] == k]
            if not sel:
                continue
            m = [e for r in sel if correct(r) and r["verdict"] != "none" for e in [mag_error(r)] if e is not None]
            out.append(f"| {k} | {len(sel)} | {sum(map(correct, sel))} | {sum(not visible(r) for r in sel)} | "
                       f"{dict(Counter(r['verdict'] for r in sel))} | "
                       + (f"{np.median(m):.1%} / {np.max(m):.1%} | {np.mean(np.array(m) <= 0.3):.0%} |" if m
                          else "- | - |"))
        vis = [r for r in lib if visible(r)]
        out.append(f"- library effects right: {np.mean([correct(r) for r in lib]):.1%} of {len(lib)}; "
                   f"visible only: {np.mean([correct(r) for r in vis]):.1%} of {len(vis)}")
    ool = [r for r in rows if r["kind"] in OUT_OF_LIBRARY]
    if ool:
        vis = [r for r in ool if visible(r)]
        out.append(f"- out of library right: {np.mean([correct(r) for r in ool]):.1%} of {len(ool)}; visible "
                   f"(oracle >= {VISIBLE:g}) -> unattributed: {np.mean([r['verdict'] == 'unattributed' for r in vis]) if vis else float('nan'):.1%} of {len(vis)}: "
                   + "; ".join(f"{k} {dict(Counter(r['verdict'] for r in ool if r['kind'] == k))} "
                               f"({sum(not visible(r) for r in ool if r['kind'] == k)} invisible)" for k in OUT_OF_LIBRARY))
    cpu = [r.get("cpu_diagnose", 0.0) for r in rows]
    if cpu:
        out.append(f"- CPU per diagnosis: median {np.median(cpu):.1f} s, max {np.max(cpu):.1f} s "
                   f"(generation median {np.median([r['cpu_generate'] for r in rows]):.1f} s)")
    wrong = [r for r in rows if r["kind"] != "clean" and not correct(r)]
    if wrong:
        out.append("- wrong: " + "; ".join(f"{r['kind']}({r['magnitude']:.3g}, {r['specimen']}, seed {r['seed']}) "
                                           f"-> {r['verdict']}" for r in wrong))
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--plan", default="all", choices=list(PLANS))
    ap.add_argument("--only", default=None, help="KIND=N,... instead of the plan")
    ap.add_argument("--out", default="bench/gap_independent_cases.jsonl")
    ap.add_argument("--summary-only", action="store_true")
    ap.add_argument("--waves", default="legendre", choices=WAVE_GENERATORS,
                    help="generator of the wave data (default: the independent Legendre SAFE)")
    ap.add_argument("--with-waves", action="store_true",
                    help="only the cases of the plan whose data hold waves (re-running them with --waves)")
    ap.add_argument("--specimens", default=None, help="only these specimens (comma-separated), e.g. wood,aluminium")
    ap.add_argument("--data", default=None, help="only these data kinds (comma-separated: modal, waves, combined)")
    ap.add_argument("--redo", default=None,
                    help="KIND:SEED,... re-run these cases on the current code, replacing their rows in --out "
                         "(not while another run writes --out)")
    a = ap.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    progress.set_quiet(True)          # this bench prints its own progress line per case
    plan = PLANS[a.plan]
    if a.only:
        plan = []
        for item in a.only.split(","):
            kind, _, n = item.partition("=")
            if kind not in KINDS or not n.isdigit():
                ap.error(f"--only {item!r}: expected KIND=N with KIND one of {KINDS}")
            plan.append((kind, int(n)))
    out = Path(a.out)
    done = {}
    if out.exists():
        for line in out.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done[(r["seed"], r["kind"])] = r
    if a.redo:
        for item in a.redo.split(","):
            kind, _, seed = item.partition(":")
            if kind not in KINDS or not seed.isdigit():
                ap.error(f"--redo {item!r}: expected KIND:SEED with KIND one of {KINDS}")
            old = done.get((int(seed), kind), {})
            r = run_case(int(seed), kind, old.get("wave_generator") or a.waves)
            r["redone"] = True
            print(f"redo {kind} seed {seed}: {old.get('verdict')} {old.get('confusable')} -> {r['verdict']} "
                  f"{r['confusable']}", file=sys.stderr, flush=True)
            done[(int(seed), kind)] = r
        tmp = out.with_suffix(".tmp")
        tmp.write_text("".join(json.dumps(r) + "\n" for r in done.values()))
        tmp.replace(out)
    jobs = sorted(((i, 1 + i, kind) for kind, count in plan for i in range(count)), key=lambda j: (j[0], j[2]))
    keep = {"with_waves": a.with_waves, "specimen": a.specimens and a.specimens.split(","),
            "data": a.data and a.data.split(",")}
    if any(keep.values()):
        def wanted(job) -> bool:
            rc = recipe(job[1], job[2])
            return ((not keep["with_waves"] or rc["data"] != "modal")
                    and (not keep["specimen"] or rc["specimen"] in keep["specimen"])
                    and (not keep["data"] or rc["data"] in keep["data"]))
        jobs = [j for j in jobs if wanted(j)]
    rows = []
    todo = [j for j in jobs if (j[1], j[2]) not in done]
    for n_done, (_, seed, kind) in enumerate(jobs):
        if (seed, kind) in done:
            rows.append(done[(seed, kind)])
            continue
        if a.summary_only:
            continue
        r = run_case(seed, kind, a.waves)
        rows.append(r)
        with out.open("a") as fh:
            fh.write(json.dumps(r) + "\n")
        k = len([x for x in rows if (x["seed"], x["kind"]) not in done])
        print(f"[{k}/{len(todo)}] {kind:17s} seed {seed:3d} {r['specimen']:9s} {r['data']:8s} "
              f"{r['n_modes']:2d} modes {r['magnitude']:+.3g} -> {r['verdict']:17s} "
              f"{'ok ' if correct(r) else 'BAD'} {r.get('cpu_diagnose', 0):.0f}s", file=sys.stderr, flush=True)
    print(summary(rows))
    print()
    print(tables(rows, PLANS["effects"] if not a.only else plan))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
