"""``labid identify FEATURES.json``: elastic constants from modal and/or wave features.

The ``--json`` result has CONTRACT section 3 keys ``parameters`` ({name:
{value, std}}, SI), ``converged`` and ``residual`` ({modal_rms_rel,
waves_rms_rel}, null for absent data), plus ``correlation``,
``identifiability``, ``warnings``, ``method``, ``data`` (the kinds fitted), ``specimen``,
``nominal``, ``uncertainty_budget`` and, with ``--starts N``, the multi-start study: the
typed result ``labid.base.results.Identification`` the panel and the report read too.

Every option and output path is checked before any fitting; the result goes into the run
the features came from beside the older ones (``--replace``: over the newest).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .. import services
from ..base import progress
from ..base.errors import UserError
from ..base.summary import budget_text, display_unit
from ..report.plots import check_format, plot_multi_start
from .options import (MAX_MCMC_STEPS, MAX_SEED, MAX_STARTS, add_json_option, bounded, check_output_dir,
                      check_output_file, count, cpu_count)


def register(sub) -> None:
    p = sub.add_parser("identify", help="identify elastic constants from a features file",
                       description=__doc__.splitlines()[0])
    p.add_argument("features", metavar="FEATURES.json")
    p.add_argument("--params", metavar="P1,P2,..",
                   help="constants to identify (E1 E2 nu12 G12 G13 G23 density, or E G nu density); "
                        "default: what the data can constrain")
    p.add_argument("--start", metavar="P=V,..", help="initial values in SI units (default: specimen nominal)")
    p.add_argument("--method", choices=services.METHODS, default="lm",
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
    p.add_argument("--plot", metavar="PATH", help="scatter plot of the multi-start study (PNG; needs --starts)")
    p.add_argument("--seed", type=count(MAX_SEED, "a seed"), default=0, help="random seed of --starts and --mcmc")
    p.add_argument("--mcmc", type=count(MAX_MCMC_STEPS, "a number of MCMC steps"), default=0, metavar="STEPS",
                   help="also sample the full posterior by MCMC (emcee) with STEPS steps per walker")
    p.add_argument("--csv", metavar="DIR", help="also write the constants as DIR/constants.csv")
    p.add_argument("--replace", action="store_true",
                   help="replace the newest identification stored in the run file (default: keep it, "
                        "the new one beside it)")
    p.add_argument("--strict", action="store_true",
                   help="exit 3 (after writing the outputs) when the fit is inconsistent with its data "
                        "(chi^2 p-value < 1e-3)")
    add_json_option(p)
    p.set_defaults(func=_run)


def check_options(args: argparse.Namespace) -> tuple:
    """Every option and output path, checked before anything is computed: (names, start)."""
    names = services.parse_names(args.params, "--params")
    start = services.parse_start(args.start, "--start")
    services.check_prior(args.prior, "--prior")
    if args.starts < 0 or args.workers < 1:
        raise UserError("expected --starts >= 0 and --workers >= 1", key="--starts")
    if args.mcmc and args.mcmc < 10:
        raise UserError(f"value {args.mcmc}: expected at least 10 steps", key="--mcmc")
    if args.plot and not args.starts:
        raise UserError("draws the multi-start study; expected --starts N as well", key="--plot")
    check_output_file(args.json, "--json")
    check_output_file(args.plot, "--plot")
    if args.plot:
        check_format(args.plot, "--plot")
    check_output_dir(args.csv, "--csv")
    return names, start


def _run(args: argparse.Namespace) -> dict:
    names, start = check_options(args)
    client = services.connect_scheduler(args.scheduler, args.starts)   # before any fitting (issue 16)
    try:
        return _identify(args, services.load_features_file(args.features), names, start, client)
    finally:
        if client is not None:
            client.close()


def _identify(args: argparse.Namespace, doc: dict, names, start, client) -> dict:
    res = services.run_identification(
        doc, base_dir=Path(args.features).parent, src=args.features, names=names, start=start, method=args.method,
        prior=args.prior, n_starts=args.starts, seed=args.seed, workers=args.workers,
        executor=client.get_executor() if client is not None else None, mcmc=args.mcmc, budget=True,
        progress=_progress())
    out = res.to_dict()
    console = args.json != "-"
    if console:
        sys.stdout.write(summary(res))
        if res.budget is not None:
            sys.stdout.write(budget_text(res.budget))
    if res.budget_error:
        sys.stderr.write(f"labid identify: no uncertainty budget: {res.budget_error}\n")
    if args.strict and not res.fit.get("consistent"):
        args.exit_code = 3
    if note := services.store_for_features(args.features, "identification", out, replace=args.replace,
                                           by="labid identify"):
        sys.stderr.write(f"labid identify: {note}\n")
    if args.csv:
        for f in services.write_result_tables(out, "identification", args.csv):
            sys.stderr.write(f"labid identify: wrote {f}\n")
    if args.plot and res.multi_start:
        plot_multi_start(list(res.multi_start), res.names, args.plot, title=res.specimen)
    return out


def _progress():
    """Model evaluations and multi-start starts on stderr (``labid.base.progress``; silent
    under ``--quiet`` or when stderr is not a terminal)."""
    if not progress.enabled():
        return None
    bars: dict = {}

    def report(item) -> None:
        if "budget" in bars:            # the budget's own model evaluations are not counted
            return
        if item[0] == "eval":
            bars.setdefault("eval", progress.bar(None, "identify: model evaluations", unit="eval")).update(1)
        elif item[0] == "start":
            bars.setdefault("start", progress.bar(item[2], "multi-start", unit="start")).update(1)
        elif item[0] == "budget":
            for b in bars.values():
                b.close()
            bars["budget"] = None
            progress.note("identify: GUM uncertainty budget (sensitivities to the type-B inputs)")
    return report


def summary(res: services.Identification) -> str:
    """The console summary: the verdict first, then per constant value +- std and, when not
    identified, why (``Identification.status``: the one definition), residuals, notes."""
    lines = []
    fit, out = res.fit, res.estimate
    if fit.get("verdict") == "insufficient_data":     # issue 24: the data cannot hold these constants
        lines.append("INSUFFICIENT DATA: " + fit["insufficient_data"]["message"].split(": ", 1)[-1])
    elif not fit.get("consistent") and fit.get("unexplained_peaks"):
        lines.append(f"INCONSISTENT FIT: {fit['unexplained_peaks']} of {len(res.pairing or [])} peaks match no "
                     "predicted mode: the constants below are NOT identified (labid diagnose looks for the cause)")
    elif fit.get("questionable"):     # engine.identify.verdict: more peaks set aside than a peak list holds spurious
        lines.append(fit["questionable"])
    elif not fit.get("consistent"):
        lines.append(f"INCONSISTENT FIT: chi^2/nu = {fit.get('chi2_per_dof', float('nan')):.3g} "
                     f"(p = {fit.get('p_value', float('nan')):.2g}): the constants below are NOT identified")
    elif not res.identified:
        lines.append(f"fit consistent (chi^2/nu = {fit['chi2_per_dof']:.3g}, p = {fit['p_value']:.2g}); "
                     "not identified: " + ", ".join(n for n in res.names if not res.is_identified(n)))
    else:
        lines.append(f"identified: fit consistent (chi^2/nu = {fit['chi2_per_dof']:.3g}, p = {fit['p_value']:.2g})")
    lines.append(f"{res.specimen}: data {'+'.join(res.data)}, method {out.get('method')}, "
                 f"{'converged' if res.converged else 'NOT converged'} in {out.get('iterations')} iterations")
    ident = (out.get("identifiability") or {}).get("parameters") or {}
    for n, p in res.parameters.items():
        v, s = p["value"], p["std"]
        unit, sc = display_unit(n)
        unit = f" {unit}" if unit else ""
        ok, why = res.status(n)
        flag = "" if ok else (f"   (not identified: {why})" if n in res.held or n not in ident else
                              f"   (not identified: {why}; "
                              f"u {100 * ident[n]['conditional_rel_std']:.2g} % if the others were known)")
        lines.append(f"  {n:>7} = {v * sc:10.4g}{unit}, u (k=1, fit) {s * sc:.3g}{unit}{flag}")
    r = out.get("residual") or {}
    lines.append("  residual: " + ", ".join(f"{k} {v:.3g}" for k, v in r.items() if v is not None))
    said = (fit.get("insufficient_data") or {}).get("message")
    lines += [f"  note: {msg}" for msg in res.warnings if msg != said]
    if res.posterior is not None:
        ps = res.posterior
        lines.append(f"  MCMC posterior ({ps['n_samples']} samples, acceptance {ps['acceptance']:.2f}): "
                     + ", ".join(f"{n} std {ps['std'][n]:.3g}" for n in ps["names"]))
    if res.multi_start:
        ok = sum(1 for m in res.multi_start if m.get("converged"))
        lines.append(f"  {services.minima_summary(res.multi_start_minima, len(res.multi_start))} ({ok} converged)")
        for k, m in enumerate(res.multi_start_minima[:4]):
            lines.append(f"    minimum {k + 1}: " + ", ".join(f"{n} {v:.4g}" for n, v in m["values"].items())
                         + f"; chi^2/n {m['chi2_per_point']:.3g}; {m['n_starts']} start(s)")
    return "\n".join(lines) + "\n"
