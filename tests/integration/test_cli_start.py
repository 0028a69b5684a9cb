"""The command line's fast start: ``labid --help`` from a static table, one command
module imported per run, and the shared ``--json`` writer."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from labid.cli import main as cli
from labid.cli.options import write_json
from labid.base.jsonio import to_jsonable

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import sys
from labid.cli.main import main
try:
    code = main({argv!r})
except SystemExit as e:
    code = e.code
print("MODULES", sorted(m for m in sys.modules if (m.startswith("labid.cli.") and m not in
      ("labid.cli.main", "labid.cli.options")) or m in
      ("numpy", "scipy", "labid.workflows.identification", "labid.workflows.analysis", "labid.services")), code, file=sys.stderr)
"""


def probe(argv: list[str]) -> tuple[list[str], int, str]:
    """Run ``labid argv`` in a fresh interpreter: (modules of interest imported, exit code, stdout)."""
    p = subprocess.run([sys.executable, "-c", PROBE.format(argv=argv)], capture_output=True, text=True,
                       cwd=ROOT, timeout=120)
    line = next(ln for ln in p.stderr.splitlines() if ln.startswith("MODULES"))
    mods, code = line[len("MODULES "):].rsplit(" ", 1)
    return eval(mods), int(code), p.stdout   # noqa: S307 - our own repr of a list of str


def test_help_lists_every_command_with_its_own_help_line():
    """The static table says what each command module registers: the lazy top-level help
    equals the help of the parser built from every module."""
    lazy = cli.build_parser(None).format_help()
    full = cli.build_parser().format_help()
    assert lazy == full
    for name, line in cli.COMMANDS.items():
        assert name in lazy and line.split()[0] in lazy


def test_help_imports_no_command_module_and_no_numpy():
    mods, code, out = probe(["--help"])
    assert code == 0 and mods == []
    assert all(name in out for name in cli.COMMANDS)


def test_a_command_imports_its_own_module_only():
    mods, code, out = probe(["dispersion", "aluminium", "--fmax", "1e5", "--n", "4"])
    assert code == 0
    assert "labid.cli.dispersion" in mods and "numpy" in mods
    assert [m for m in mods if m.startswith("labid.cli.")] == ["labid.cli.dispersion"]
    assert "labid.workflows.identification" not in mods and "labid.workflows.analysis" not in mods


def test_unknown_command_is_one_line_and_exit_2(capsys):
    assert cli.main(["disperse", "cfrp"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "invalid choice" in err[0] and "dispersion" in err[0]


def test_json_writer_turns_numpy_values_and_nan_into_plain_json(tmp_path):
    """jsonio no longer imports numpy; numpy values still come out as plain JSON."""
    res = {"a": np.arange(3.0), "b": np.float64(2.5), "c": np.int64(7), "d": np.bool_(True),
           "e": [np.float32(np.nan), float("inf")], "f": Path("x/y"), (1): np.array([[1, 2]])}
    out = tmp_path / "r.json"
    write_json(res, str(out))
    assert json.loads(out.read_text()) == {"a": [0.0, 1.0, 2.0], "b": 2.5, "c": 7, "d": True,
                                           "e": [None, None], "f": "x/y", "1": [[1, 2]]}
    assert type(to_jsonable(np.float64(2.5))) is float and type(to_jsonable(np.int64(7))) is int
