"""``labid export RUN.h5 [--uff FILE] [--csv DIR]``: a run's data and results for other tools.

``--uff FILE``: FRFs (H1 of each accelerometer) and every shot's time data as UFF58, the
picked modes (frequency, damping, shape at the accelerometers) as UFF55, the nodes as UFF15
(SI, data set 164); binary unless ``--ascii``. ``--csv DIR``: the features
(features_modal.csv, features_waves.csv), the identified constants (constants.csv) and the
diagnosis (diagnosis_summary.csv, diagnosis_effects.csv, diagnosis_residuals.csv). Columns
and units: docs/import-export.md.
"""
from __future__ import annotations

import sys

from .. import services
from ..base import progress
from .options import add_json_option


def register(sub) -> None:
    p = sub.add_parser("export", help="a run's FRFs, time data and modes as UFF, its results as CSV tables",
                       description=__doc__.splitlines()[0])
    p.add_argument("run", metavar="RUN.h5", help="run file")
    p.add_argument("--uff", metavar="FILE", help="UFF file to write (58 FRFs and time data, 55 modes, 15 nodes)")
    p.add_argument("--ascii", action="store_true", help="ASCII UFF58 (12 digits) instead of binary (exact)")
    p.add_argument("--csv", metavar="DIR", help="folder for the CSV tables (created if needed)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    if progress.enabled():      # ~5 s CPU on the demo run (the UFF 55 mode shapes are fitted): say so
        progress.note(f"labid export: {args.run}: reading the shots"
                      + (", fitting the mode shapes and writing the UFF" if args.uff else "")
                      + (", writing the CSV tables" if args.csv else ""))
    res = services.export_run(args.run, uff=args.uff, csv_dir=args.csv, binary=not args.ascii)
    if getattr(args, "json", None) != "-":
        w = sys.stdout.write
        if "uff" in res:
            w(f"{res['uff']}: {res['frf']} FRF(s), {res['time']} time record(s), {res['modes']} mode(s)\n")
        for f in res.get("csv", []):
            w(f"{f}\n")
        for n in res["notes"]:
            w(f"note: {n}\n")
    return res
