"""``labid demo [--out DIR]``: the whole job on the simulated rig, no hardware."""
from __future__ import annotations

import sys

from .cmdutil import add_json_option
from .demo import run_demo


def register(sub) -> None:
    p = sub.add_parser("demo", help="the whole job end to end on the simulated rig")
    p.add_argument("--out", default="demo_out", metavar="DIR", help="output folder (default demo_out)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated rig")
    p.add_argument("--hits", type=int, default=None, help="hammer hits (default: the rig file's)")
    p.add_argument("--waves", type=int, default=None, help="wave shots (default: the rig file's)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    def report(line: str) -> None:
        # progress goes to stderr when the JSON result goes to stdout
        print(line, file=sys.stderr if args.json == "-" else sys.stdout, flush=True)

    return run_demo(args.out, seed=args.seed, hits=args.hits, waves=args.waves, report=report)
