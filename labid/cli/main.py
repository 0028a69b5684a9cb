"""The headless command line: ``labid COMMAND ...`` (CONTRACT section 3).

Exit codes: 0 success, 2 user error (one line on stderr, no traceback),
1 internal failure, 3 a fit inconsistent with its data under ``--strict``,
130 interrupted (Ctrl-C), 143 terminated (SIGTERM, handled like Ctrl-C).
Every failure is mapped here (``failure_line``): a ``UserError``, a storage error
(disk full, file-size limit, read-only directory, permissions), an engine error on
unphysical input or an out-of-memory request is one line, exit 2 (a value echoed in it
cut to 80 characters); anything else is an internal
failure: exit 1, the traceback written to a file (``mkstemp``: a new file under an
unpredictable name) and one line saying where (``LABID_DEBUG=1`` prints it too).
SIGXFSZ is ignored, so that a file-size limit (``ulimit -f``) is a write error the
commands report, not a kill.

The process (``labid ...``, ``python -m labid.cli``) ends at its last exit hook with
``os._exit`` (``_end_process``): a Ctrl-C or SIGTERM that arrives after the command
finished, while the interpreter tears down, still gives 130 or 143 instead of a kill by
the signal; an HDF5 file that could not be written (``labid.store.space.poisoned``) is
never closed again by the library's own exit handlers, which would crash on it; and the
teardown (~0.8 s with numpy, scipy and h5py loaded) is skipped. Every file is closed by
then: the commands write through context managers. Each command lives in ``labid/cli/<name>.py`` (``import_.py``
for ``labid import``) and exposes
``register(subparsers)``, which adds its parser and sets ``func(args) -> dict``.
The returned dict is the ``--json`` result.

Fast start: only the module of the command being run is imported (with its
numerical libraries); ``labid --help`` lists the commands from the static
``COMMANDS`` table and imports none of them (``bench/bench_cli.py``).
"""
from __future__ import annotations

import argparse
import atexit
import errno
import importlib
import keyword
import os
import signal
import sys

from ..base import progress, threads
from .options import bounded, cpu_count, write_json
from ..base.errors import UserError, clip_values

#: every command with its one-line help, in the order ``labid --help`` lists them
#: (each module's ``register`` uses the same line; tests/test_cli.py checks it)
COMMANDS: dict[str, str] = {
    "dispersion": "guided-wave dispersion curves (SAFE)",
    "modes": "free-free natural frequencies of the plate",
    "plan": "design the test: sensor and tap layout, waves, predicted stds",
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
    def error(self, message: str) -> None:  # one line, exit 2, a value echoed cut to 80 characters
        sys.stderr.write(f"{self.prog}: error: {clip_values(' '.join(message.split()))}\n")
        raise SystemExit(2)


def command_module(name: str):
    """The module of command ``name``, imported now (the CLI's lazy loading of commands)."""
    return importlib.import_module(f"labid.cli.{name}_" if keyword.iskeyword(name) else f"labid.cli.{name}")


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
        p.add_argument("--threads", type=bounded(int, 1, cpu_count, "a number of threads (at most the CPU count)"),
                       default=None, metavar="N",
                       help="BLAS/OpenMP threads per process (default 1, or $LABID_THREADS; "
                            "OMP_NUM_THREADS and the like set by you are respected)")
        p.add_argument("--quiet", "-q", action="store_true",
                       help="no progress on stderr (the summary on stdout stays)")
    return parser


#: OSError numbers that are the user's environment, not a bug: one line, exit 2
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                            errno.ENOENT, errno.EISDIR, errno.ENOTDIR, errno.ENAMETOOLONG, errno.EFBIG,
                            errno.EIO, errno.EEXIST, errno.ENXIO, errno.ELOOP, errno.EBUSY, errno.ETXTBSY})


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C (the command unwinds, files are closed)."""


def _on_sigterm(signum, frame):  # noqa: ARG001 - signal handler signature
    raise Terminated()


def failure_line(e: BaseException) -> str | None:
    """The one user-facing line of an exception that is the user's to fix, else None."""
    if isinstance(e, UserError):
        return str(e)
    if isinstance(e, OSError) and e.errno in STORAGE_ERRNOS:
        where = e.filename if e.filename is not None else ""
        return f"{where}: {e.strerror or e}" if where else f"{e.strerror or e}"
    if isinstance(e, MemoryError):
        return "not enough memory for this input (MemoryError); expected a smaller problem"
    if isinstance(e, ValueError) and type(e).__module__.startswith("engine."):
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        return f"{msg} ({type(e).__name__}: the input is outside what the model can hold)"
    return None


def crash_report(command: str, exc: BaseException) -> str | None:
    """Write the traceback of an internal failure to a file; its path (None if unwritable)."""
    import tempfile     # here: only a crash needs them (~8 ms of every command's start otherwise)
    import time
    import traceback

    text = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    if os.environ.get("LABID_DEBUG"):
        sys.stderr.write(text)
    prefix = f"labid-crash-{command}-{time.strftime('%Y%m%dT%H%M%S')}-"
    for d in (os.environ.get("LABID_CRASH_DIR"), tempfile.gettempdir()):
        if not d:
            continue
        try:    # O_CREAT | O_EXCL under an unpredictable name: never through a planted link
            fd, path = tempfile.mkstemp(prefix=prefix, suffix=".txt", dir=d)
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(f"labid {command}: internal error\nargv: {sys.argv!r}\n\n{text}")
            return path
        except OSError:
            continue
    if not os.environ.get("LABID_DEBUG"):
        sys.stderr.write(text)
    return None


def main(argv: list[str] | None = None) -> int:
    """Run ``labid ARGV``; the exit code. ``argv`` None: the process's own arguments, and
    this call owns the process: it ends at its last exit hook (``_end_process``)."""
    owner = argv is None
    if owner:
        atexit.register(_end_process)            # first registered: runs last of the exit hooks
    argv = sys.argv[1:] if argv is None else list(argv)
    command = argv[0] if argv and argv[0] in COMMANDS else "?"
    previous = {}
    for sig, handler in ((signal.SIGTERM, _on_sigterm), (getattr(signal, "SIGXFSZ", None), signal.SIG_IGN)):
        if sig is None:
            continue
        try:
            previous[sig] = signal.signal(sig, handler)
        except ValueError:                          # not the main thread: leave signals alone
            pass
    try:
        # a usage error is one line and exit 2 (argparse's SystemExit(2)), --help exit 0
        if not threads_given(argv):             # else decided once --threads is parsed
            _threads_early()
        try:
            parser = build_parser(command if command != "?" else None)
            nul = next((a for a in argv if "\0" in str(a)), None)
            if nul is not None:                     # no path or value holds one (os.open would raise)
                parser.error(f"argument {nul!r} holds a NUL character; expected text without one")
            args = parser.parse_args(argv)
        except SystemExit as e:
            rc = e.code if isinstance(e.code, int) else 2
        else:
            rc = _run(args)
    except Terminated:                              # arrived outside the command's own handling
        rc = 143
    except KeyboardInterrupt:                       # Ctrl-C while the command was being loaded
        rc = 130
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if owner and previous:                  # the command is done: a signal now is only noted
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, _note_signal)
    if owner:
        _ENDING["rc"] = rc
    return rc


def threads_given(argv: list[str]) -> bool:
    """True when ``argv`` may give ``--threads`` as argparse reads it: ``--threads`` or an
    abbreviation of it (``--t`` ... ``--thread``), alone or as ``OPTION=VALUE``, before any
    ``--`` (after it every word is positional). ``--total``, ``--truth``, ``--target-u``
    are not it (the early decision was skipped for any word starting with ``--t``)."""
    for a in map(str, argv):
        if a == "--":
            return False
        opt = a.split("=", 1)[0]
        if len(opt) >= 3 and "--threads".startswith(opt):
            return True
    return False


def _threads_early() -> None:
    """Decide the threads before the command's module loads numpy (labid.base.threads: the
    variables then suffice, no threadpoolctl). ``_run_command`` decides again with the
    parsed ``--threads`` and reports a bad value; here it is left for that."""
    try:
        threads.configure()
    except UserError:
        pass


_ENDING: dict = {}


def _note_signal(signum, frame):  # noqa: ARG001 - signal handler signature
    _ENDING.setdefault("signal", signum)


def _end_process() -> None:
    """The last exit hook of a process ``main`` owned: end it now (``os._exit``) with the
    command's exit code, or 130/143 when a Ctrl-C/SIGTERM arrived after the command
    finished (module docstring)."""
    if "rc" not in _ENDING:
        return
    sig = _ENDING.get("signal")
    rc = 130 if sig == signal.SIGINT else 143 if sig == signal.SIGTERM else _ENDING["rc"]
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(rc if isinstance(rc, int) else 1)


class _PipeSafe:
    """stdout that survives a reader leaving (``labid identify ... | head``): on a broken
    pipe further console text is dropped (the descriptor now points at the null device),
    while the command goes on and writes its results (``--json``, the run file)."""

    def __init__(self, stream):
        self._stream, self.broken = stream, False

    def write(self, text: str) -> int:
        if not self.broken:
            try:
                return self._stream.write(text)
            except BrokenPipeError:
                self._drop()
        return len(text)

    def flush(self) -> None:
        if not self.broken:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._drop()

    def _drop(self) -> None:
        self.broken = True
        try:                                    # Python's own flush at exit must not fail either
            fd = os.open(os.devnull, os.O_WRONLY)
            os.dup2(fd, self._stream.fileno())
            os.close(fd)
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _run(args) -> int:
    stdout = sys.stdout
    sys.stdout = _PipeSafe(stdout)
    try:
        return _run_command(args)
    finally:
        sys.stdout.flush()
        sys.stdout = stdout


def _run_command(args) -> int:
    try:
        threads.configure(args.threads)
        progress.set_quiet(args.quiet)
        result = args.func(args)
        if getattr(args, "json", None) and result is not None:
            write_json(result, args.json)
    except Terminated:
        sys.stderr.write(f"labid {args.command}: terminated\n")
        return 143
    except KeyboardInterrupt:
        sys.stderr.write(f"labid {args.command}: interrupted\n")
        return 130
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else 1
    except Exception as e:  # noqa: BLE001 - the door: every failure is mapped to the contract
        line = failure_line(e)
        if line is not None:
            line = " ".join(line.split())            # one line, whatever the message held
            line = line if isinstance(e, UserError) else clip_values(line)   # UserError clips its own
            sys.stderr.write(f"labid {args.command}: error: {line}\n")
            return 2
        where = crash_report(args.command, e)
        tail = f"; traceback in {where}" if where else ""
        sys.stderr.write(f"labid {args.command}: internal error ({type(e).__name__}){tail} (exit 1)\n")
        return 1
    # a command may ask for another exit code on success (``identify --strict``: 3)
    return int(getattr(args, "exit_code", 0) or 0)


if __name__ == "__main__":
    raise SystemExit(main())
