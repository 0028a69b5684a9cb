"""labid.base.progress: silent under --quiet, a tqdm bar on stderr when asked for."""
import io
import sys

from labid.base import progress


def test_quiet_silences_bar_and_note(monkeypatch, capsys):
    monkeypatch.setenv("LABID_PROGRESS", "1")
    progress.set_quiet(True)
    try:
        with progress.bar(3, "x") as b:
            b.update()
        progress.note("hello")
    finally:
        progress.set_quiet(False)
    err = capsys.readouterr().err
    assert err == ""


def test_bar_writes_to_stderr_when_enabled(monkeypatch):
    monkeypatch.setenv("LABID_PROGRESS", "1")
    buf = io.StringIO()
    monkeypatch.setattr(sys, "stderr", buf)
    with progress.bar(2, "fitting") as b:
        b.update(2)
    assert "fitting" in buf.getvalue()


def test_cli_quiet_flag_accepted(capsys):
    from labid.cli.main import main
    assert main(["dispersion", "aluminium", "--fmax", "1e5", "--n", "5", "--quiet"]) == 0
