"""``labid identify FEATURES.json``: elastic constants from modal and/or wave features.

The ``--json`` result has CONTRACT section 3 keys ``parameters`` ({name:
{value, std}}, SI), ``converged`` and ``residual`` ({modal_rms_rel,
waves_rms_rel}, null for absent data), plus ``correlation``,
``identifiability``, ``warnings``, ``method`` and, with ``--starts N``, the
multi-start study.
"""
from __future__ import annotations

import argparse
import sys

from ..workflows import cluster
from .. import services
from ..workflows.budget import budget_text, identify_budget
from .options import MAX_MCMC_STEPS, MAX_SEED, MAX_STARTS, add_json_option, bounded, count, cpu_count
from ..base.errors import UserError
from ..workflows.identification import (METHODS, distinct_minima, load_problem, minima_summary, multi_start,
                                        load_features, parse_assignments, plot_multi_start, random_starts,
                                        result_dict, run, start_values)


def register(sub) -> None:
    p = sub.add_parser("identify", help="identify elastic constants from a features file",
                       description=__doc__.splitlines()[0])
    p.add_argument("features", metavar="FEATURES.json")
    p.add_argument("--params", metavar="P1,P2,..",
                   help="constants to identify (E1 E2 nu12 G12 G13 G23 density, or E G nu density); "
                        "default: what the data can constrain")
    p.add_argument("--start", metavar="P=V,..", help="initial values in SI units (default: specimen nominal)")
    p.add_argument("--method", choices=METHODS, default="lm",
                   help="lm: combined least squares (default); bayes: Lai & Ip update (Eq. 20); "
                        "nelder-mead: relative misfit (Eq. 29)")
    p.add_argument("--prior", type=bounded(float, 0.0, 1e3, "a positive prior std"), default=None, metavar="S",
                   help="prior std of log(p) about the start (lm), or relative prior std (bayes, default 0.5)")
    p.add_argument("--starts", type=count(MAX_STARTS, "a number of starts"), default=0, metavar="N",
                   help="also run a multi-start study from N random initial guesses (within +-50%% of the start)")
    p.add_argument("--workers", type=count(cpu_count, "a number of processes (at most the CPU count)", 1), default=min(2, cpu_count()),
                   metavar="W", help="processes for --starts (default 2, at most the CPU count)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run --starts on a Dask distributed scheduler (pip install 'labid[cluster]'); "
                        "checked before any fitting")
    p.add_argument("--plot", metavar="PATH", help="scatter plot of the multi-start study (PNG)")
    p.add_argument("--seed", type=count(MAX_SEED, "a seed"), default=0, help="random seed of --starts and --mcmc")
    p.add_argument("--mcmc", type=count(MAX_MCMC_STEPS, "a number of MCMC steps"), default=0, metavar="STEPS",
                   help="also sample the full posterior by MCMC (emcee) with STEPS steps per walker")
    p.add_argument("--csv", metavar="DIR", help="also write the constants as DIR/constants.csv")
    p.add_argument("--strict", action="store_true",
                   help="exit 3 (after writing the outputs) when the fit is inconsistent with its data "
                        "(chi^2 p-value < 1e-3)")
    add_json_option(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> dict:
    client = cluster.connect(args.scheduler, args.starts)   # before any fitting (issue 16)
    try:
        return _identify(args, client)
    finally:
        if client is not None:
            client.close()


def _identify(args: argparse.Namespace, client) -> dict:
    problem = load_problem(args.features)
    names = None
    if args.params:
        names = tuple(n.strip() for n in args.params.split(",") if n.strip())
        if not names:
            raise UserError(f"value {args.params!r}: expected P1,P2,..", key="--params")
    start = parse_assignments(args.start, "--start")
    if args.prior is not None and not args.prior > 0:
        raise UserError(f"value {args.prior!r}: expected a positive number", key="--prior")
    if args.starts < 0 or args.workers < 1:
        raise UserError("expected --starts >= 0 and --workers >= 1", key="--starts")
    est = run(problem, names, start, method=args.method, prior=args.prior)
    out = result_dict(est)
    out["data"] = list(problem.kinds)
    if args.mcmc:
        if args.mcmc < 10:
            raise UserError(f"value {args.mcmc}: expected at least 10 steps", key="--mcmc")
        from engine.fit import sample_posterior  # noqa: PLC0415
        prior = args.prior if args.method == "lm" else None
        out["posterior"] = sample_posterior(problem.blocks, est, prior=prior, n_steps=args.mcmc,
                                            seed=args.seed).to_dict()
    out["specimen"] = problem.specimen.name
    if args.starts:
        st0 = start_values(problem, est.names, {k: v for k, v in start.items() if k in est.names})
        starts = random_starts(st0, est.names, args.starts, seed=args.seed, problem=problem)
        doc = load_features(args.features)
        executor = client.get_executor() if client is not None else None
        results = multi_start(doc, starts, est.names, specimen=problem.specimen, method=args.method,
                              prior=args.prior, executor=executor, max_workers=args.workers)
        out["multi_start"] = results
        out["multi_start_minima"] = distinct_minima(results, est.names)
        if args.plot:
            plot_multi_start(results, est.names, args.plot, title=problem.specimen.name)
    if args.json != "-":
        _print(out, est.names)
    # issue 16 (helper s6): the GUM uncertainty budget (JSON uncertainty_budget, console table)
    out["uncertainty_budget"] = identify_budget(problem, est, args.features)
    if args.json != "-":
        sys.stdout.write(budget_text(out["uncertainty_budget"]))
    if args.strict and not out["fit"]["consistent"]:
        args.exit_code = 3
    if note := services.store_for_features(args.features, "identification", out):
        sys.stderr.write(f"labid identify: {note}\n")
    if args.csv:
        for f in services.write_result_tables(out, "identification", args.csv):
            sys.stderr.write(f"labid identify: wrote {f}\n")
    return out


def _print(out: dict, names) -> None:
    w = sys.stdout.write
    fit = out["fit"]
    if not fit["consistent"] and fit.get("unexplained_peaks"):
        w(f"INCONSISTENT FIT: {fit['unexplained_peaks']} of {len(out.get('pairing') or [])} peaks match no "
          "predicted mode: the constants below are NOT identified (labid diagnose looks for the cause)\n")
    elif not fit["consistent"]:
        w(f"INCONSISTENT FIT: chi^2/nu = {fit['chi2_per_dof']:.3g} (p = {fit['p_value']:.2g}): the constants "
          "below are NOT identified\n")
    elif not fit["identified"]:
        w(f"fit consistent (chi^2/nu = {fit['chi2_per_dof']:.3g}, p = {fit['p_value']:.2g}); not identified: "
          + ", ".join(out["identifiability"]["poorly_identified"]) + "\n")
    else:
        w(f"identified: fit consistent (chi^2/nu = {fit['chi2_per_dof']:.3g}, p = {fit['p_value']:.2g})\n")
    w(f"{out['specimen']}: data {'+'.join(out['data'])}, method {out['method']}, "
      f"{'converged' if out['converged'] else 'NOT converged'} in {out['iterations']} iterations\n")
    ident = out["identifiability"]["parameters"]
    for n in names:
        v, s = out["parameters"][n]["value"], out["parameters"][n]["std"]
        unit, sc = ("", 1.0) if n.startswith("nu") else ((" kg/m^3", 1.0) if n == "density" else (" GPa", 1e-9))
        flag = "" if ident[n]["identified"] else (
            f"   (not identified: {ident[n].get('reason', 'poorly identified')})" if n in out.get("held", {})
            else f"   (not identified: {ident[n].get('reason', 'poorly identified')}; "
                 f"+-{100 * ident[n]['conditional_rel_std']:.2g} % if the others were known)")
        w(f"  {n:>7} = {v * sc:10.4g} +- {s * sc:.3g}{unit}{flag}\n")

    r = out["residual"]
    w("  residual: " + ", ".join(f"{k} {v:.3g}" for k, v in r.items() if v is not None) + "\n")
    for msg in out["warnings"]:
        w(f"  note: {msg}\n")
    if "posterior" in out:
        ps = out["posterior"]
        w(f"  MCMC posterior ({ps['n_samples']} samples, acceptance {ps['acceptance']:.2f}): "
          + ", ".join(f"{n} std {ps['std'][n]:.3g}" for n in ps["names"]) + "\n")
    if "multi_start" in out:
        ok = sum(1 for m in out["multi_start"] if m.get("converged"))
        w(f"  {minima_summary(out['multi_start_minima'], len(out['multi_start']))} ({ok} converged)\n")
        for k, m in enumerate(out["multi_start_minima"][:4]):
            w(f"    minimum {k + 1}: " + ", ".join(f"{n} {v:.4g}" for n, v in m["values"].items())
              + f"; chi^2/n {m['chi2_per_point']:.3g}; {m['n_starts']} start(s)\n")
