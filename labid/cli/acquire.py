"""``labid acquire``: a headless acquisition session appended to a run file.

Progress goes to stderr, one line per event. Ctrl-C stops after the shot in
progress (a second Ctrl-C at once); every recorded shot is kept, the summary
is written, and the exit status is 130.
"""
from __future__ import annotations

import signal
import sys
from dataclasses import replace
from pathlib import Path

from .. import services
from .options import MAX_SEED, MAX_SHOTS, add_json_option, count, write_json
from ..base.errors import UserError
from ..inputs.rig import load_rig, parse_truth_scale
from ..inputs.specimen import load_specimen
from ..base.summary import stream


def register(sub) -> None:
    p = sub.add_parser("acquire", help="headless acquisition session (appends to RUN.h5)",
                       description=__doc__.splitlines()[0])
    p.add_argument("--rig", default="default", metavar="RIG.toml",
                   help="rig file, or 'default' for the built-in simulated rig (default)")
    p.add_argument("--specimen", required=True, metavar="SPEC.toml",
                   help="specimen file, or a built-in name ('cfrp', 'aluminium')")
    p.add_argument("--out", required=True, metavar="RUN.h5", help="run file (created or appended to)")
    p.add_argument("--backend", choices=("mock", "nidaqmx"), default="mock",
                   help="simulated rig (mock, default) or NI-DAQmx hardware")
    p.add_argument("--hits", type=count(MAX_SHOTS, "a number of hits"), default=None, metavar="N",
                   help="hammer hits (rig default)")
    p.add_argument("--waves", type=count(MAX_SHOTS, "a number of wave shots"), default=None, metavar="M",
                   help="wave shots (rig default)")
    p.add_argument("--total", action="store_true",
                   help="N and M count the shots already in RUN.h5 (resume to the planned size)")
    p.add_argument("--seed", type=count(MAX_SEED, "a seed"), default=0, metavar="S",
                   help="random seed of the simulated rig")
    p.add_argument("--effects", default="", metavar="NAME=V,..",
                   help="unmodelled effects injected into the simulated rig, e.g. "
                        "'sensor_mass=0.003,temperature=10' (CONTRACT effect names, SI units)")
    p.add_argument("--truth", default=None, metavar="F|NAME=F,..",
                   help="the simulated plate's moduli are the specimen file's times F (e.g. 0.7), or named "
                        "ones (e.g. 'G13=0.6,E2=1.3'): a plate whose constants the file does not know "
                        "(overrides the rig's [simulation] truth_scale; mock backend only)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    if args.effects and args.backend != "mock":
        raise UserError("effects can only be injected into the simulated rig; expected --backend mock",
                        key="--effects")
    effects = services.parse_effects(args.effects, key="--effects")
    if args.truth is not None and args.backend != "mock":
        raise UserError("--truth sets the simulated plate; expected --backend mock", key="--truth")
    for opt in ("hits", "waves"):
        v = getattr(args, opt)
        if v is not None and v < 0:
            raise UserError(f"value {v}: expected a non-negative count", key=f"--{opt}")

    stop = {"flag": False}

    def on_sigint(signum, frame):
        stop["flag"] = True
        signal.signal(signal.SIGINT, signal.default_int_handler)   # a second Ctrl-C: now
        sys.stderr.write("labid acquire: stopping after the current shot (Ctrl-C again to abort)\n")

    def progress(ev: dict) -> None:
        if args.quiet:
            return
        sys.stderr.write(f"{ev['kind']} {ev['index']}/{ev['total']}: {ev['message']}\n")
        sys.stderr.flush()

    rig, specimen = load_rig(args.rig), load_specimen(args.specimen)   # errors before any file
    if args.truth is not None:
        rig = replace(rig, sim=replace(rig.sim, truth_scale=parse_truth_scale(args.truth, "--truth",
                                                                              "command line")))
    rig.check_specimen(specimen.length, specimen.width)
    cal = services.calibration_status(rig)              # the calibration sheet, said before any shot
    for note in cal["notes"]:
        sys.stderr.write(f"labid acquire: {note}\n")
    services.warn_calibration(cal, prefix="labid acquire")
    out = Path(args.out)
    existed = out.exists()
    old = signal.signal(signal.SIGINT, on_sigint)
    try:
        summary = services.acquire(out, rig, specimen, backend=args.backend, effects=effects, seed=args.seed,
                                   hits=args.hits, waves=args.waves, total=args.total, progress=progress,
                                   should_stop=lambda: stop["flag"])
    except BaseException:  # any failure (SIGTERM too): never leave an empty run file behind
        if not existed:   # do not leave behind a run file this command created without a shot
            services.discard_empty_run(out)
        raise
    finally:
        signal.signal(signal.SIGINT, old)
    rec = summary["recorded"]
    w = stream(args) or sys.stderr          # the summary: stdout, unless --json - holds it
    w.write(f"recorded {rec['hammer']} hammer and {rec['wave']} wave shots "
            f"into {args.out} ({summary['in_file']['hammer']} + {summary['in_file']['wave']} "
            "in the file)\n")
    if stop["flag"]:            # Ctrl-C during the last shot: that shot is kept, the exit code says 130
        summary["interrupted"] = True
    if not summary["interrupted"]:
        w.write(f"next: labid analyze {args.out}\n")
    if summary["interrupted"]:
        if args.json:
            write_json(summary, args.json)
        raise KeyboardInterrupt
    if any(summary["gave_up"].values()):
        sys.stderr.write("labid acquire: warning: gave up on a shot; " + "; ".join(summary["problems"][-1:]) + "\n")
    return summary
