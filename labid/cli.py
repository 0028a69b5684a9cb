"""The headless command line: ``labid COMMAND ...`` (CONTRACT section 3).

Exit codes: 0 success, 2 user error (one line on stderr, no traceback),
1 internal failure. Each command lives in ``labid/cmd_<name>.py`` and exposes
``register(subparsers)``, which adds its parser and sets ``func(args) -> dict``.
The returned dict is the ``--json`` result.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import sys
import traceback
from pathlib import Path


from . import threads
from .errors import UserError
from .jsonio import to_jsonable

COMMANDS = ("dispersion", "modes", "acquire", "analyze", "identify", "diagnose",
            "demo", "report", "gui")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


def write_json(result: dict, path: str) -> None:
    """Write a result as JSON to ``path``; '-' is standard output. NaN -> null."""
    text = json.dumps(to_jsonable(result), indent=2, allow_nan=False)
    if path == "-":
        sys.stdout.write(text + "\n")
    else:
        try:
            Path(path).write_text(text + "\n")
        except OSError as e:
            raise UserError(f"cannot write: {e.strerror}", file=path, key="--json") from None


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="labid", description="Elastic constants of composite plates from "
                     "vibration and guided waves, without cutting them.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in COMMANDS:
        modname = f"labid.cmd_{name}"
        if importlib.util.find_spec(modname) is not None:
            importlib.import_module(modname).register(sub)
    for p in sub.choices.values():
        p.add_argument("--threads", type=int, default=None, metavar="N",
                       help="BLAS/OpenMP threads per process (default 1, or $LABID_THREADS; "
                            "OMP_NUM_THREADS and the like set by you are respected)")
    return parser


def add_json_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", metavar="PATH", help="write the machine-readable result ('-' for stdout)")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        threads.configure(args.threads)
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
