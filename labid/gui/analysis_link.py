"""How the panel calls the analysis workflow (``labid.analysis``, as ``labid analyze``).

Kept in one place so that the views only see engine objects (``engine.modal.Spectra``,
``Peak``; wave arrivals and group velocities) and the features document.
"""
from __future__ import annotations

#: names the analysis module must define for the panel to use it
ANALYSIS_API: tuple[str, ...] = ("analyze_run",)


def analysis_job(link, run: str, temperature_c, progress, should_stop):
    """Background part: analyse the run file; returns what the views show."""
    raise NotImplementedError("analysis workflow not wired yet")


def show_analysis(main, out) -> None:
    pass


def analysis_summary(out) -> str:
    return ""


def save_picks(link, run: str, peaks) -> None:
    raise NotImplementedError("analysis workflow not wired yet")
