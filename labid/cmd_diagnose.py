"""``labid diagnose FEATURES.json``: sim-to-real gap diagnosis (CONTRACT section 3).

Result (``--json``): ``gap`` {before, after, held_out_before, held_out_after,
chi2..., significant} (rms whitened residuals, 1 = noise level), ``where``
(groups of features carrying the gap), ``effects`` (ranked ``{name,
magnitude, unit, gap_after, score, ...}``), ``verdict`` (an effect name,
``"none"`` or ``"unattributed"``), plus ``confusable``, ``undetectable``
(effects the constants absorb, with the bias they put into them), ``constants``
(before/after) and per-feature residuals. ``--plot PNG`` draws where the gap lies.
"""
from __future__ import annotations

import sys

from engine.gap import GapOptions

from . import services
from .cmdutil import add_json_option
from .diagnosis import load_features, plot_gap, run_diagnosis
from .errors import UserError


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="sim-to-real gap diagnosis of a features file",
                       description=__doc__.splitlines()[0])
    p.add_argument("features", metavar="FEATURES.json", help="measured features (CONTRACT section 2)")
    p.add_argument("--plot", metavar="PNG", help="write a figure of where the gap lies")
    p.add_argument("--alpha", type=float, default=0.01,
                   help="false-alarm rate of the chi^2 gap test (default 0.01)")
    p.add_argument("--csv", metavar="DIR", help="also write the diagnosis tables as DIR/diagnosis_*.csv")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    if not 0.0 < args.alpha < 0.5:
        raise UserError(f"value {args.alpha!r}: expected a false-alarm rate in (0, 0.5)", key="--alpha")
    doc, base = load_features(args.features)
    res = run_diagnosis(doc, base, args.features, GapOptions(alpha=args.alpha))
    if args.plot:
        try:
            plot_gap(res, args.plot)
        except OSError as e:
            raise UserError(f"cannot write: {e}", file=args.plot, key="--plot") from None
    if not args.json:
        g = res["gap"]
        sys.stdout.write(f"gap {g['before']:.2f} -> {g['after']:.2f} (rms residual/sigma); "
                         f"verdict: {res['verdict']}\n")
        for e in res["effects"][:3]:
            sys.stdout.write(f"  {e['name']:18s} {e['magnitude']:.4g} {e['unit']:4s} "
                             f"gap_after {e['gap_after']:.2f} score {e['score']:.2f}\n")
    if note := services.store_for_features(args.features, "diagnosis", res):
        sys.stderr.write(f"labid diagnose: {note}\n")
    if args.csv:
        for f in services.write_result_tables(res, "diagnosis", args.csv):
            sys.stderr.write(f"labid diagnose: wrote {f}\n")
    return res
