"""Enough data for the constants asked? The ``insufficient_data`` verdict (issue 24).

A least-squares fit of p constants to n < p independent data points has no unique minimum:
whatever it returns depends on the start, and a "consistent" chi^2 with zero degrees of
freedom says nothing. So before any verdict on the fit, the data are counted:

* every resonance of the modal block is one point, every group-velocity point of a wave
  curve one point (the features carry only points a wavelet resolution apart:
  ``engine.waves.independent_points``);
* fewer points than fitted constants: ``insufficient_data``. The verdict also lists what
  would help, from what the data lack: another propagation direction (G23 and E2 show
  along 90 deg, G13 and E1 along 0 deg), a wider band (A0's dispersion is what separates
  bending stiffness from transverse shear), S0 (in-plane stiffness and nu12), resonances
  (E1, E2, G12), more resonances.

The same verdict name is used by ``labid diagnose`` (engine.gap): ``insufficient_data``.
Pure: plain descriptions in, a frozen dataclass out.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

__all__ = ["DataSet", "Sufficiency", "VERDICT", "assess", "datasets_of", "apply"]

VERDICT = "insufficient_data"


@dataclass(frozen=True)
class DataSet:
    """One block of data: ``kind`` ('modal' or 'waves'), its number of independent points,
    and for a wave curve its mode ('A0', 'S0', ...), direction (deg) and band (Hz)."""

    kind: str
    n_points: int
    mode: str | None = None
    direction_deg: float | None = None
    band_hz: tuple[float, float] | None = None


@dataclass(frozen=True)
class Sufficiency:
    """The count and its verdict: ``enough`` is False when the independent points are fewer
    than the fitted constants (``verdict`` then ``insufficient_data``); ``help``: what would
    add the missing information; ``message``: the one line to print."""

    n_points: int
    n_params: int
    enough: bool
    help: tuple[str, ...]
    message: str

    @property
    def verdict(self) -> str | None:
        return None if self.enough else VERDICT

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "n_points": self.n_points, "n_params": self.n_params,
                "what_would_help": list(self.help), "message": self.message}


def datasets_of(blocks, features=None) -> list[DataSet]:
    """DataSets of ``engine.fit.DataBlock``s (a wave block named 'waves:<mode>@<dir>deg'); the
    wave bands from ``features`` (``engine.features.Features``) when given."""
    bands = {}
    for w in (getattr(features, "waves", None) or ()):
        f = [x for x in w.frequency_hz if x > 0]
        if f:
            bands[(w.mode, round(float(w.direction_deg), 3))] = (float(min(f)), float(max(f)))
    out = []
    for b in blocks:
        n = int(len(b.observed))
        if b.kind == "waves":
            mode, direction = None, None
            name = str(getattr(b, "name", ""))
            if name.startswith("waves:") and "@" in name:
                mode = name[6:].split("@")[0]
                try:
                    direction = float(name.split("@")[1].replace("deg", ""))
                except ValueError:
                    direction = None
            out.append(DataSet("waves", n, mode, direction,
                               bands.get((mode, round(direction, 3))) if direction is not None else None))
        else:
            out.append(DataSet(str(b.kind), n))
    return out


def datasets_of_features(features) -> list[DataSet]:
    """DataSets of an ``engine.features.Features``: its modal frequencies and each wave set."""
    out = []
    if getattr(features, "modal", None) is not None:
        out.append(DataSet("modal", int(len(features.modal.frequency_hz))))
    for w in (getattr(features, "waves", None) or ()):
        f = [float(x) for x in w.frequency_hz if x > 0]
        out.append(DataSet("waves", len(f), w.mode, float(w.direction_deg), (min(f), max(f)) if f else None))
    return out


def assess(data: Sequence[DataSet], params: Sequence[str]) -> Sufficiency:
    """Count the independent points of ``data`` against the constants ``params`` (module
    docstring)."""
    n = sum(max(int(d.n_points), 0) for d in data)
    p = len(tuple(params))
    waves = [d for d in data if d.kind == "waves" and d.n_points > 0]
    modal = [d for d in data if d.kind == "modal" and d.n_points > 0]
    help_: list[str] = []
    names = set(params)
    if waves:
        dirs = {round(d.direction_deg or 0.0, 3) for d in waves}
        modes = {d.mode for d in waves}
        if len(dirs) < 2:
            help_.append("waves along another direction (G13 and E1 show along the fibres, G23 and E2 across "
                         "them): sensors along 0 and 90 deg")
        if "S0" not in modes and names & {"nu12", "E1", "E2", "G12", "E", "nu", "G"}:
            help_.append("S0 velocities (in-plane stiffness, nu12): a tone-burst sweep from a bonded PZT, or "
                         "sensors on both faces")
        bands = [d.band_hz for d in waves if d.band_hz]
        if any(d.mode == "A0" for d in waves) and (not bands or max(b[1] / b[0] for b in bands) < 3):
            help_.append("a wider band of A0 (its dispersion separates bending stiffness from transverse shear): "
                         "a pencil-lead break, or tone bursts at several centre frequencies")
        if sum(d.n_points for d in waves) < 3 * len(waves):
            help_.append("more independent points per curve: sensors farther from the plate's edges, a longer "
                         "path between the sensors, or a sweep of tone bursts")
    if not modal:
        help_.append("resonances from a modal test (hammer hits, free-free: 10 or more natural frequencies): "
                     "E1, E2 and G12")
    elif modal and sum(d.n_points for d in modal) < p + 3:
        help_.append("more resonances: a wider modal band (labid analyze --modal-fmax)")
    if not waves and names & {"G13", "G23", "nu12"}:
        help_.append("guided waves: G13, G23 and nu12 hardly change the resonances of a thin plate")
    enough = n >= p
    if enough:
        msg = f"{n} independent data points for {p} constants"
    else:
        msg = (f"insufficient data: {n} independent point{'s' if n != 1 else ''} for {p} constants "
               f"({', '.join(params)}); no estimate can be trusted. What would help: "
               + ("; ".join(help_) if help_ else "more data") + ".")
    return Sufficiency(n, p, enough, tuple(help_), msg)


def apply(est, suff: Sufficiency):
    """``est`` (``engine.fit.Estimate``) with the insufficient-data verdict when ``suff`` says
    so: its fit not identified (``fit['verdict']``, ``fit['insufficient_data']``), every
    constant not identified for that reason, the line first among the warnings."""
    if suff.enough:
        return est
    ident = {**est.identifiability}
    params = {n: {**d, "identified": False, "reason": "insufficient data"}
              for n, d in ident.get("parameters", {}).items()}
    ident["parameters"] = params
    ident["poorly_identified"] = list(params)
    fit = dict(est.fit or {})
    fit.update(identified=False, verdict=VERDICT, insufficient_data=suff.to_dict())
    return replace(est, identifiability=ident, fit=fit, warnings=(suff.message,) + tuple(est.warnings))
