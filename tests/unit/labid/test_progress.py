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


def test_watch_fit_counts_evaluations_and_shows_chi2(monkeypatch):
    """Each model evaluation advances the bar; chi^2 = sum(((pred - obs) / sigma)^2) of the
    last evaluation of every block: block a (2 - 1)/0.5 -> 4, block b (3 - 3)/1 -> 0."""
    from dataclasses import dataclass
    from typing import Callable

    @dataclass(frozen=True)
    class Block:
        observed: tuple
        sigma: tuple
        predict: Callable
        jacobian: Callable | None = None

    monkeypatch.setenv("LABID_PROGRESS", "1")
    progress.set_quiet(False)                     # an earlier --quiet command may have set it
    buf = io.StringIO()
    monkeypatch.setattr(sys, "stderr", buf)
    blocks = [Block((1.0, 2.0), (0.5, 1.0), lambda p: [2.0, 2.0]),
              Block((3.0,), (1.0,), lambda p: [3.0], jacobian=lambda p, n: ([3.0], [[1.0]]))]
    wrapped, bar = progress.watch_fit(blocks, "fit")
    assert wrapped[0].predict({}) == [2.0, 2.0]           # the model's values pass through
    assert wrapped[1].jacobian({}, ["x"]) == ([3.0], [[1.0]])
    assert bar.n == 2 and "chi^2 4" in bar.postfix
    bar.close()


def test_watch_fit_and_counter_are_silent_without_progress(monkeypatch, capsys):
    monkeypatch.setenv("LABID_PROGRESS", "0")
    blocks = [object()]
    wrapped, bar = progress.watch_fit(blocks, "fit")
    assert wrapped == blocks
    done, bar = progress.counter(3, "starts")
    done(2, 3)
    bar.close()
    assert capsys.readouterr().err == ""


def test_counter_reports_k_of_n(monkeypatch):
    monkeypatch.setenv("LABID_PROGRESS", "1")
    progress.set_quiet(False)
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    done, bar = progress.counter(5, "multi-start")
    done(1, 5)
    done(3, 5)
    assert bar.n == 3 and bar.total == 5
    bar.close()
