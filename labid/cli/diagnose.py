"""``labid diagnose FEATURES.json``: sim-to-real gap diagnosis (CONTRACT section 3).

Result (``--json``): ``gap`` {before, after, held_out_before, held_out_after,
chi2..., significant} (rms whitened residuals, 1 = noise level), ``where``
(groups of features carrying the gap), ``effects`` (ranked ``{name,
magnitude, unit, gap_after, score, ...}``), ``verdict`` (an effect name,
``"none"``, ``"unattributed"``, ``"pairing"`` or ``"insufficient_data"``), plus ``confusable``
and ``confusable_groups`` (what separates them), ``advice`` (what to add), ``undetectable``
(effects the constants absorb, with the bias they put into them), ``constants``
(before/after) and per-feature residuals. ``--plot PNG`` draws where the gap lies.

The diagnosis starts from the estimate ``labid identify`` reports with the same
``--params``, ``--start`` and ``--prior`` (``--estimate``: that result, read from
its ``--json`` file instead of identifying again). The console shows the verdict, the gap
before -> after, the top three candidates with magnitudes and units, the
pairing findings, and where each output file went; progress goes to stderr.

Every option and output path is checked before any computing; the result goes into the run
the features came from beside the older ones (``--replace``: over the newest).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from .. import services
from ..base.errors import UserError
from ..inputs.files import read_json_file
from ..report.plots import check_format, plot_gap
from .options import add_json_option, bounded, check_output_dir, check_output_file


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="sim-to-real gap diagnosis of a features file",
                       description=__doc__.splitlines()[0])
    p.add_argument("features", metavar="FEATURES.json", help="measured features (CONTRACT section 2)")
    p.add_argument("--plot", metavar="PNG", help="write a figure of where the gap lies")
    p.add_argument("--alpha", type=bounded(float, 0.0, 0.5, "a false-alarm rate"), default=0.01,
                   help="false-alarm rate of the chi^2 gap test (default 0.01)")
    p.add_argument("--csv", metavar="DIR", help="also write the diagnosis tables as DIR/diagnosis_*.csv")
    p.add_argument("--params", metavar="P1,P2,..",
                   help="constants identified before the diagnosis (as labid identify --params)")
    p.add_argument("--start", metavar="P=V,..", help="initial values in SI units (as labid identify --start)")
    p.add_argument("--prior", type=bounded(float, 0.0, 1e3, "a positive prior std"), default=None, metavar="S",
                   help="prior std of log(p) about the start (as labid identify --prior; default none)")
    p.add_argument("--estimate", metavar="IDENTIFY.json",
                   help="start from this labid identify --json result of the same features (and the same "
                        "--start/--prior) instead of identifying again")
    p.add_argument("--replace", action="store_true",
                   help="replace the newest diagnosis stored in the run file (default: keep it, the new one "
                        "beside it)")
    add_json_option(p)
    p.set_defaults(func=run)


def read_estimate(path: str, doc: dict, names) -> dict:
    """A ``labid identify --json`` result to start the diagnosis from, checked against the
    features ``doc`` (every parameter with a finite positive value, one pairing row per peak)."""
    est = read_json_file(path, "a labid identify JSON result")
    par = est.get("parameters") if isinstance(est, dict) else None
    if not isinstance(par, dict) or not par:
        raise UserError("missing or empty; expected the 'parameters' of a labid identify --json result",
                        file=path, key="parameters")
    for n, d in par.items():
        v = d.get("value") if isinstance(d, dict) else None
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise UserError(f"value {v!r}: expected a positive number (SI)", file=path, key=f"parameters.{n}.value")
    if names is not None and tuple(par) != tuple(names):
        raise UserError(f"parameters {list(par)} differ from --params {list(names)}", file=path, key="parameters")
    n_peaks = len((doc.get("modal") or {}).get("frequencies_hz") or [])
    pairing = est.get("pairing")
    if isinstance(pairing, list) and len(pairing) != n_peaks:
        raise UserError(f"{len(pairing)} pairing rows for {n_peaks} peaks: not a result of these features",
                        file=path, key="pairing")
    return est


def run(args) -> dict:
    if not 0.0 < args.alpha < 0.5:
        raise UserError(f"value {args.alpha!r}: expected a false-alarm rate in (0, 0.5)", key="--alpha")
    names = services.parse_names(args.params, "--params")
    services.check_prior(args.prior, "--prior")
    start = services.parse_start(args.start, "--start")
    check_output_file(args.json, "--json")
    check_output_file(args.plot, "--plot")
    if args.plot:
        check_format(args.plot, "--plot")
    check_output_dir(args.csv, "--csv")
    doc = services.load_features_file(args.features)
    est = read_estimate(args.estimate, doc, names) if args.estimate else None
    res = services.run_diagnosis(doc, Path(args.features).parent, args.features, names=names, start=start,
                                 prior=args.prior, estimate=est, alpha=args.alpha)
    out = sys.stdout if args.json != "-" else sys.stderr
    _print(res, out)
    if note := services.store_for_features(args.features, "diagnosis", res, replace=args.replace,
                                           by="labid diagnose"):
        out.write(f"  {note}\n")
    if args.plot:
        plot_gap(res, args.plot)
        out.write(f"  figure: {args.plot}\n")
    if args.json and args.json != "-":
        out.write(f"  result: {args.json}\n")
    if args.csv:
        for f in services.write_result_tables(res, "diagnosis", args.csv):
            out.write(f"  table: {f}\n")
    return res


def _print(res: dict, out) -> None:
    """The verdict, the gap before -> after, the top three candidates, pairing findings."""
    g, ident = res["gap"], res["identification"]
    v = res["verdict"]
    what = {"none": "no significant gap", "unattributed": "a gap no candidate explains",
            "pairing": "the peaks are paired with the wrong modes",
            "insufficient_data": "too few features to tell a gap from the fit"}.get(v, f"{v} explains the gap")
    out.write(f"verdict: {v} ({what}; chi^2 {g['chi2_before']:.1f} vs threshold {g['threshold_chi2']:.1f}, "
              f"p = {g['p_value_before']:.2g})\n")
    out.write(f"  gap {g['before']:.2f} -> {g['after']:.2f} (rms residual/sigma, 1 = noise); held-out "
              f"{g['held_out_before']:.2f} -> {g['held_out_after']:.2f}\n")
    out.write(f"  start: {', '.join(ident['parameters'] or [])} from {ident['source']} "
              f"({'converged' if ident['converged'] else 'NOT converged'})\n")
    for e in res["effects"][:3]:
        mag = f"{e['magnitude']:.4g}" + (f" +- {e['std']:.2g}" if e.get("std") else "")
        tag = "refitted" if e["refitted"] else "screened"
        out.write(f"  {e['name']:18s} {mag} {e['unit']:4s} gap_after {e['gap_after']:.2f} "
                  f"score {e['score']:.2f} ({tag})\n")
    for grp in res.get("confusable_groups") or []:    # issue 28: look-alikes and what separates them
        out.write(f"  confusable: {' ~ '.join(grp['effects'] + grp['outside_library'])}\n")
        for how in grp["separate_by"]:
            out.write(f"    separate: {how}\n")
    for i, a in enumerate(res.get("advice") or []):
        out.write(f"  {'too few' if i == 0 else 'add'}: {a}\n")
    for w in res["where"][:6]:
        out.write(f"  where: {w}\n")
