"""One read pass of a run file for the panel (issue 26): everything the views show when a run
is opened, read once (off the GUI thread when the window opens a run) and shared by the views
until the run changes.

``load(path, progress=None) -> Snapshot``: the configuration texts, shot counts and every
results group (``services.open_run``, JSON copies), the features, up to :data:`WAVE_SHOTS`
wave shots (Waves tab), the last stored shot (Acquisition tab) and the overdue calibrations.
``progress((k, n, what))`` is called before each of the :data:`STEPS` steps. Before issue 26
the views read the run themselves: 8 ``open_run`` and ~32 k h5py reads, ~15 s CPU in the GUI
thread on the demo run (``bench/bench_panel_open.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .. import services
from ..base.errors import UserError
from ..services import RunData

#: wave shots the Waves tab offers
WAVE_SHOTS = 10
STEPS = ("configuration and results", "wave shots", "last shot", "calibration")


@dataclass
class Snapshot:
    """What the panel shows of one run file, read in one pass."""

    run: RunData
    features: dict = field(default_factory=dict)
    waves: list = field(default_factory=list)
    last: Any = None                     # the last stored shot (a Record) or None
    last_kind: str | None = None
    overdue: list = field(default_factory=list)

    @property
    def path(self) -> str:
        return self.run.path


def load(path: str | Path, progress: Callable[[Any], None] | None = None) -> Snapshot:
    """Read ``path`` once for the panel; a UserError naming the file when it is not a
    readable run (h5py's OSError on a damaged file included)."""
    try:
        return _load(path, progress)
    except OSError as e:
        raise UserError(f"cannot read the run file ({e})", file=str(path)) from None


def _load(path: str | Path, progress: Callable[[Any], None] | None) -> Snapshot:
    say = progress or (lambda obj: None)
    say((0, len(STEPS), STEPS[0]))
    rd = services.open_run(path, max_shots=0)
    snap = Snapshot(rd, services.features_of(rd))
    say((1, len(STEPS), STEPS[1]))
    if rd.counts.get("wave"):
        snap.waves = services.shots(path, "wave", limit=WAVE_SHOTS)
    say((2, len(STEPS), STEPS[2]))
    kind = "wave" if rd.counts.get("wave") else ("hammer" if rd.counts.get("hammer") else None)
    if kind == "wave" and len(snap.waves) == rd.counts["wave"]:
        snap.last, snap.last_kind = snap.waves[-1], kind
    elif kind is not None:
        snap.last, snap.last_kind = services.shots(path, kind)[-1], kind
    say((3, len(STEPS), STEPS[3]))
    try:
        snap.overdue = list(services.run_calibration(path).get("overdue") or [])
    except (UserError, OSError, KeyError, ValueError):
        snap.overdue = []
    return snap
