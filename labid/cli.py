"""The headless command line: ``labid COMMAND ...`` (CONTRACT section 3).

Exit codes: 0 success, 2 user error (one line on stderr, no traceback),
1 internal failure, 3 a fit inconsistent with its data under ``--strict``. Each command lives in ``labid/cmd_<name>.py`` and exposes
``register(subparsers)``, which adds its parser and sets ``func(args) -> dict``.
The returned dict is the ``--json`` result.

Fast start: only the module of the command being run is imported (with its
numerical libraries); ``labid --help`` lists the commands from the static
``COMMANDS`` table and imports none of them (``bench/bench_cli.py``).
"""
from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from . import progress, threads
from .cmdutil import write_json
from .errors import UserError

#: every command with its one-line help, in the order ``labid --help`` lists them
#: (each module's ``register`` uses the same line; tests/test_cli.py checks it)
COMMANDS: dict[str, str] = {
    "dispersion": "guided-wave dispersion curves (SAFE)",
    "modes": "free-free natural frequencies of the plate",
    "acquire": "headless acquisition session (appends to RUN.h5)",
    "import": "recordings of other systems (TDMS, UFF58, WAV, MAT, CSV) into a run file",
    "analyze": "resonance peaks and CWT group velocities of a run -> features",
    "identify": "identify elastic constants from a features file",
    "diagnose": "sim-to-real gap diagnosis of a features file",
    "demo": "the whole job end to end on the simulated rig",
    "report": "self-contained HTML report of a run",
    "export": "a run's FRFs, time data and modes as UFF, its results as CSV tables",
    "gui": "the lab panel",
}
ALL = "*"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


def command_module(name: str):
    """The module of command ``name``, imported now (the CLI's lazy loading of commands)."""
    return importlib.import_module(f"labid.cmd_{name}")


def build_parser(load: str | None = ALL) -> argparse.ArgumentParser:
    """The ``labid`` parser. ``load``: the command whose module is imported to add its
    full parser (``ALL``: every command; None: none); the others are listed by name
    and help line only."""
    parser = _Parser(prog="labid", description="Elastic constants of composite plates from "
                     "vibration and guided waves, without cutting them.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name, help_line in COMMANDS.items():
        if load in (ALL, name):
            command_module(name).register(sub)
        else:
            sub.add_parser(name, help=help_line, add_help=False)
    for p in sub.choices.values():
        p.add_argument("--threads", type=int, default=None, metavar="N",
                       help="BLAS/OpenMP threads per process (default 1, or $LABID_THREADS; "
                            "OMP_NUM_THREADS and the like set by you are respected)")
        p.add_argument("--quiet", "-q", action="store_true",
                       help="no progress on stderr (the summary on stdout stays)")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv[0] if argv and argv[0] in COMMANDS else None)
    args = parser.parse_args(argv)
    try:
        threads.configure(args.threads)
        progress.set_quiet(args.quiet)
        result = args.func(args)
        if getattr(args, "json", None) and result is not None:
            write_json(result, args.json)
    except UserError as e:
        sys.stderr.write(f"labid {args.command}: error: {e}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f"labid {args.command}: interrupted\n")
        return 130
    except Exception:  # internal failure: keep the traceback for the bug report
        traceback.print_exc()
        sys.stderr.write(f"labid {args.command}: internal error (exit 1)\n")
        return 1
    # a command may ask for another exit code on success (``identify --strict``: 3)
    return int(getattr(args, "exit_code", 0) or 0)


if __name__ == "__main__":
    raise SystemExit(main())
