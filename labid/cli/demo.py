"""``labid demo [--out DIR]``: the whole job end to end on the simulated rig (``make demo``), no
hardware.

1. acquire hammer hits and wave shots of the built-in CFRP specimen into a run file;
2. analyse them into a features file (resonances, A0 group velocities);
3. identify the constants from modal data only, waves only, and both combined;
4. print true vs identified +/- std and the error for every constant;
5. diagnose the remaining sim-to-real gap, and write the run file, the figures
   and an HTML report;
6. waves only, as a pitch-catch lab records them: the built-in aluminium plate, a
   180 kHz tone burst from a bonded PZT and two PZT sensors (rig ``pzt-aluminium``:
   edge reflections, sensor high-pass and resonance, crosstalk, 12-bit ADC), E and G
   from the A0 and S0 group velocities alone.
"""
from __future__ import annotations

import math
import multiprocessing
import os
import sys
import time
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, Callable, Mapping

from .. import services
from ..base.errors import UserError
from ..base.summary import display_unit
from ..inputs.specimen import load_specimen
from ..report.certificate import REPORT_SHOTS, report_figures, write_report
from ..report.figures import fig_gap
from .options import MAX_SEED, MAX_SHOTS, add_json_option, count

DATASETS = ("modal", "waves", "combined")
#: the identification starts from datasheet values (issue 12): 17-22 % below the simulated
#: truth (136.7 / 9.0 / 0.30 / 5.0 / 5.08 / 3.16 GPa), as a lab would start
DATASHEET_START = {"E1": 110e9, "E2": 7e9, "nu12": 0.25, "G12": 4e9, "G13": 4e9, "G23": 2.5e9}
#: what waves alone identify (labid.workflows.identification.estimation.default_params, A0 only)
WAVES_PARAMS = ("E1", "G13", "G23")


def _fmt(name: str, v: float) -> str:
    unit, scale = display_unit(name)
    return f"{v * scale:.3f} {unit}" if unit else f"{v:.4f}"


def format_table(truth: dict[str, float], results: dict[str, services.Identification]) -> str:
    """Text table: true, identified +/- std and error (%) per constant and data set; a fitted
    constant that is not identified (``Identification.status``) is marked * and named below."""
    names = [n for n in truth if n != "density"]
    lines = [f"{'constant':<9}{'true':>14}  " + "".join(f"{ds + ' (value ± std, error)':>42}" for ds in results)]
    starred = False
    for n in names:
        row = f"{n:<9}{_fmt(n, truth[n]):>14}  "
        for ds, res in results.items():
            p = res.parameters.get(n)
            if p is None:
                row += f"{'not identified':>42}"
                continue
            v, s = p["value"], p["std"]
            err = 100.0 * (v - truth[n]) / truth[n]
            scale = display_unit(n)[1]
            mark = " " if res.is_identified(n) else "*"
            starred |= mark == "*"
            cell = f"{v * scale:.4g} ± {s * scale:.2g}  ({err:+.2f} %){mark}"
            row += f"{cell:>42}"
        lines.append(row.rstrip())
    if starred:
        lines.append("* fitted but not identified (held at its start, poorly constrained or flagged: "
                     "labid identify says why)")
    return "\n".join(lines)


WAVES_RIG = "pzt-aluminium"


def _waves_only(out: Path, seed: int, step: Callable[[str], None], report: Callable[[str], None]) -> dict:
    """Section 6: E and G of the built-in aluminium plate from a pitch-catch run alone."""
    spec = load_specimen("aluminium")
    truth = next(iter(spec.laminate.materials.values())).params()
    run = out / "demo_waves.h5"
    if run.exists():
        run.unlink()
    step(f"6/6 waves only: {spec.name}, 180 kHz tone burst from a PZT, PZT sensors at 120 and 420 mm "
         f"(rig {WAVES_RIG})")
    summary = services.acquire(run, WAVES_RIG, spec, backend="mock", seed=seed)
    if not summary["complete"]:
        raise UserError("the simulated pitch-catch rig did not complete the session: "
                        + "; ".join(summary["problems"]))
    feats_path = out / "features_waves.json"
    feats = services.run_analysis(run, out=feats_path).features
    curves = feats.get("waves", [])
    step("    " + ", ".join(f"{w['mode']} {len(w['frequency_hz'])} independent points "
                            f"{w['frequency_hz'][0] / 1e3:.0f}-{w['frequency_hz'][-1] / 1e3:.0f} kHz"
                            for w in curves) + f" from {summary['recorded']['wave']} shots -> {feats_path}")
    if not curves:
        raise UserError("the pitch-catch run gave no group velocity: "
                        + "; ".join(feats.get("analysis", {}).get("notes", [])))
    res = services.run_identification(feats, base_dir=out, src=str(feats_path))
    services.store_result(run, "identification", res.to_dict(), by="labid demo")
    report(format_table({n: truth[n] for n in res.parameters if n in truth}, {"waves": res}))
    errors = {n: (res.parameters[n]["value"] - truth[n]) / truth[n] for n in res.parameters if n in truth}
    return {"true": truth, "identified": res.parameters, "relative_error": errors,
            "converged": res.converged, "max_abs_error": max(abs(e) for e in errors.values()),
            "points": {w["mode"]: len(w["frequency_hz"]) for w in curves},
            "files": {"run": str(run), "features": str(feats_path)}}


# -- the second process (issue 29) ----------------------------------------------------------
# The waves-only section and the modal-only and waves-only identifications depend on nothing
# the combined identification, the diagnosis and the report need: with two cores they run in
# one worker process while the main process does the rest (bench/RESULTS.md, issue 29).
def default_workers() -> int:
    """2 when this process may run on two cores or more, else 1 (everything in this process)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:          # no affinity on this platform
        cores = os.cpu_count() or 1
    return 2 if cores >= 2 else 1


def _waves_only_task(out: Path, seed: int) -> tuple[dict, list[tuple[str, str]]]:
    """Section 6 in the worker: its result and its console lines (kind, text), replayed in order."""
    lines: list[tuple[str, str]] = []
    res = _waves_only(out, seed, lambda m: lines.append(("step", m)), lambda m: lines.append(("report", m)))
    return res, lines


def _identify_task(doc: dict, out: Path, src: str, start: dict, budget: bool):
    """(Identification, wall s, CPU s) of one data set, timed where it runs."""
    t0, c0 = time.perf_counter(), time.process_time()
    res = services.run_identification(doc, base_dir=out, src=src, start=start, budget=budget)
    return res, time.perf_counter() - t0, time.process_time() - c0


def _warm_figures_task() -> None:
    """Import pyplot and draw one tiny figure (fonts loaded): ~0.7 s CPU the worker spends while
    the main process stores the identifications, not later on step 5's critical path."""
    from ..report.figures import fig_png  # noqa: PLC0415 - the worker's, not the main process'
    from ..report.plots import pyplot  # noqa: PLC0415

    fig, ax = pyplot().subplots(figsize=(1, 1))
    ax.set_title("warm-up")
    fig_png(fig)


class _Awaited(Mapping):
    """The report's figures, each read from its job when the report places it (the report's
    text before it is written meanwhile)."""

    def __init__(self, jobs: dict[str, Callable[[], Any]]):
        self.jobs, self.got = jobs, {}

    def __getitem__(self, key: str) -> Any:
        if key not in self.got:
            self.got[key] = self.jobs[key]()
        return self.got[key]

    def __iter__(self):
        return iter(self.jobs)

    def __len__(self) -> int:
        return len(self.jobs)


class _Later:
    """A finished computation with the interface of a Future (the single-process path)."""

    def __init__(self, fn: Callable, *args):
        self.fn, self.args = fn, args

    def result(self) -> Any:
        """``fn(*args)``, computed on the first call only."""
        if self.fn is not None:
            self.value, self.fn, self.args = self.fn(*self.args), None, ()
        return self.value


def _submit(pool: ProcessPoolExecutor | None, fn: Callable, *args) -> Future | _Later:
    """``fn(*args)`` in the worker (None, or a worker that died: here, when asked for)."""
    if pool is not None:
        try:
            fut = pool.submit(fn, *args)
            return _Guarded(fut, fn, args)
        except (BrokenProcessPool, RuntimeError):
            pass
    return _Later(fn, *args)


class _Guarded:
    """A worker's Future whose result is computed here if the worker died (e.g. killed)."""

    def __init__(self, fut: Future, fn: Callable, args: tuple):
        self.fut, self.fn, self.args = fut, fn, args

    def result(self) -> Any:
        try:
            return self.fut.result()
        except BrokenProcessPool:
            self.fut = _Later(self.fn, *self.args)     # computed here, once
            return self.fut.result()


def _pool(workers: int) -> ProcessPoolExecutor | None:
    if workers < 2:
        return None
    methods = multiprocessing.get_all_start_methods()
    # fork: the worker starts with the imports done (spawn would repeat ~1.5 s of them)
    ctx = multiprocessing.get_context("fork" if "fork" in methods else None)
    return ProcessPoolExecutor(max_workers=1, mp_context=ctx)


def run_demo(out_dir: str | Path = "demo_out", *, seed: int = 0, hits: int | None = None,
             waves: int | None = None, report: Callable[[str], None] = print,
             workers: int | None = None) -> dict:
    """Run the demo into ``out_dir``; return the JSON-ready summary. ``workers``: 2 runs the
    independent stages in a second process (default :func:`default_workers`), 1 none."""
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise UserError(f"value {workers!r}: expected 1 or more worker processes", key="--workers")
    t_start = time.perf_counter()
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"cannot create the output folder: {e.strerror}", file=str(out), key="--out") from None
    run = out / "demo_run.h5"
    if run.exists():  # the demo's own output of an earlier demo: start afresh
        run.unlink()
    spec = load_specimen("cfrp")
    truth = next(iter(spec.laminate.materials.values())).params()

    def step(msg: str) -> None:
        report(f"[{time.perf_counter() - t_start:6.1f} s] {msg}")

    pool = _pool(workers)
    try:
        return _run_demo(out, run, spec, truth, seed, hits, waves, report, step, t_start, pool)
    except BaseException:
        # interrupted or failed: the worker's job is not waited for (ProcessPoolExecutor has no
        # public way to stop a running task before Python 3.14's terminate_workers)
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.terminate()
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


def _run_demo(out: Path, run: Path, spec, truth: dict, seed: int, hits: int | None, waves: int | None,
              report: Callable[[str], None], step: Callable[[str], None], t_start: float,
              pool: ProcessPoolExecutor | None) -> dict:
    # section 6 shares nothing with sections 1-5: started first, in the worker when there is one
    waves_only_job = _submit(pool, _waves_only_task, out, seed) if pool is not None else None
    step(f"1/6 acquiring on the simulated rig: {spec.name}")
    summary = services.acquire(run, "default", spec, backend="mock", seed=seed, hits=hits, waves=waves)
    rec = summary["recorded"]
    step(f"    recorded {rec['hammer']} hammer hits and {rec['wave']} wave shots -> {run}")
    if not summary["complete"]:
        raise UserError("the simulated rig did not complete the session: " + "; ".join(summary["problems"]))

    step("2/6 analysing: resonance peaks and CWT group velocities")
    features_path = out / "features.json"
    features = services.run_analysis(run, out=features_path).features
    n_modes = len(features.get("modal", {}).get("frequencies_hz", []))
    n_waves = sum(len(w.get("frequency_hz", [])) for w in features.get("waves", []))
    step(f"    {n_modes} resonances, {n_waves} group-velocity points -> {features_path}")

    step("3/6 identifying: modal only, waves only, combined")
    step("    start: datasheet values, not the simulated truth: "
         + ", ".join(f"{n} {_fmt(n, v)}" for n, v in DATASHEET_START.items()))
    jobs: dict[str, Any] = {}
    for ds in DATASETS:
        doc = services.select_data(features, ds)
        if ds != "combined" and not doc.get("modal" if ds == "modal" else "waves"):
            jobs[ds] = None
            continue
        start = {n: v for n, v in DATASHEET_START.items() if ds != "waves" or n in WAVES_PARAMS}
        if ds == "combined":
            # the report's certificate, with its GUM budget (u_c, U at k = 2): here, while the
            # worker (if any) identifies from modal and waves data alone
            jobs[ds] = _Later(_identify_task, doc, out, str(features_path), start, True)
        else:
            jobs[ds] = _submit(pool, _identify_task, doc, out, str(features_path), start, False)
    if pool is not None:
        _submit(pool, _warm_figures_task)          # after the worker's two fits, before step 5
    combined = jobs["combined"].result()           # here, while the worker runs the other two
    results: dict[str, services.Identification] = {}
    for ds in DATASETS:
        if jobs[ds] is None:
            step(f"    {ds}: no data")
            continue
        done = combined if ds == "combined" else jobs[ds].result()
        results[ds] = res = done[0]
        # the step's own time, where it ran (the stage times add up to the total, issue 26): the
        # last fit's 'seconds' leaves out the global stage, the consistency refits and the budget
        where = "" if ds == "combined" or pool is None else " in the second process"
        step(f"    {ds}: {'converged' if res.converged else 'NOT converged'}; step {done[1]:.1f} s "
             f"({done[2]:.1f} s CPU){where}, of which the final fit {res.estimate['seconds']:.1f} s"
             + (" (the rest: global stage, consistency refits, GUM budget)" if ds == "combined" else
                " (the rest: global stage, checks)"))
    for ds, res in results.items():
        services.store_result(run, "identification" if ds == "combined" else f"identification_{ds}", res.to_dict(),
                              by="labid demo")

    step("4/6 identified vs true constants")
    table = format_table(truth, results)
    report(table)

    step("5/6 diagnosing the sim-to-real gap; writing figures and the report")
    # the report's spectrum, scalogram and dispersion figures do not depend on the diagnosis:
    # drawn in the worker (if any) from the run's data read here, while the diagnosis runs; the
    # gap figure is drawn there too while this process stores the diagnosis (issue 29, session 26)
    figures_job = _submit(pool, report_figures, services.open_run(run, max_shots=REPORT_SHOTS))
    # from the combined identification just reported (same features, start and options): the
    # diagnosis judges that fit, and does not repeat it (~10 s CPU, bench/RESULTS.md)
    gap = services.run_diagnosis(features, base_dir=out, src=str(features_path), start=DATASHEET_START,
                                 estimate=results.get("combined"))
    gap_job = _submit(pool, fig_gap, gap, out / "gap.png")
    services.store_result(run, "diagnosis", gap, by="labid demo")
    report(f"gap: {gap['gap']['before']:.3g} -> {gap['gap']['after']:.3g}; verdict: {gap['verdict']}")
    figures = _Awaited({**{k: (lambda k=k: figures_job.result()[k]) for k in ("spectrum", "scalogram", "dispersion")},
                        "gap": gap_job.result})
    html = write_report(run, out / "report.html", figures=figures)
    gap_job.result()                               # gap.png written, whatever the report placed
    if waves_only_job is None:
        waves_only = _waves_only(out, seed, step, report)
    else:
        waves_only, lines = waves_only_job.result()
        for kind, msg in lines:
            (step if kind == "step" else report)(msg)
    step(f"done: {run}, {features_path}, {out / 'gap.png'}, {html}, {waves_only['files']['run']}")

    errors = {ds: {n: (res.parameters[n]["value"] - truth[n]) / truth[n]
                   for n in res.parameters if n in truth}
              for ds, res in results.items()}
    return {
        "start": dict(DATASHEET_START),
        "true": truth,
        "identified": {ds: res.parameters for ds, res in results.items()},
        "relative_error": errors,
        "converged": {ds: res.converged for ds, res in results.items()},
        "gap": {k: gap[k] for k in ("gap", "where", "effects", "verdict")},
        "files": {"run": str(run), "features": str(features_path), "gap_figure": str(out / "gap.png"),
                  "report": str(html)},
        "waves_only_aluminium": waves_only,
        "seconds": round(time.perf_counter() - t_start, 1),
        "max_abs_error": {ds: max((abs(e) for e in errs.values()), default=math.nan)
                          for ds, errs in errors.items()},
    }


def register(sub) -> None:
    p = sub.add_parser("demo", help="the whole job end to end on the simulated rig")
    p.add_argument("--out", default="demo_out", metavar="DIR", help="output folder (default demo_out)")
    p.add_argument("--seed", type=count(MAX_SEED, "a seed"), default=0, help="seed of the simulated rig")
    p.add_argument("--hits", type=count(MAX_SHOTS, "a number of hits"), default=None,
                   help="hammer hits (default: the rig file's)")
    p.add_argument("--waves", type=count(MAX_SHOTS, "a number of wave shots"), default=None,
                   help="wave shots (default: the rig file's)")
    p.add_argument("--workers", type=count(2, "a number of processes (1 or 2)", 1), default=None, metavar="N",
                   help="processes: 2 runs the independent stages in a second one (default: 2 when "
                        "two cores are available, else 1)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    def report(line: str) -> None:
        # progress goes to stderr when the JSON result goes to stdout
        print(line, file=sys.stderr if args.json == "-" else sys.stdout, flush=True)

    return run_demo(args.out, seed=args.seed, hits=args.hits, waves=args.waves, report=report, workers=args.workers)
