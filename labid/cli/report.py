"""``labid report RUN.h5 [--out REPORT.html]``: a self-contained HTML test report."""
from __future__ import annotations

from ..base import progress
from .options import add_json_option
from ..report.certificate import write_report
from ..base.summary import stream


def register(sub) -> None:
    p = sub.add_parser("report", help="self-contained HTML report of a run",
                       description=__doc__.splitlines()[0])
    p.add_argument("run", metavar="RUN.h5", help="run file")
    p.add_argument("--out", metavar="REPORT.html", default=None, help="output (default RUN.html)")
    p.add_argument("--identification", type=int, default=None, metavar="N",
                   help="certify the kept identification no. N (default: the newest; labid.services.result_history)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    if progress.enabled():      # a terminal: say what the next seconds are for
        progress.note(f"labid report: {args.run}: drawing the figures")
    out = write_report(args.run, args.out, identification=args.identification)
    w = stream(args)
    if w is not None:
        w.write(f"report: {out}\n")
    return {"out": out}
