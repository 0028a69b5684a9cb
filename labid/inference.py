"""Identification and diagnosis for the front-ends: the part of the ``labid.services`` facade
that runs them (front-ends import these names from ``labid.services``).

``labid identify``, ``labid diagnose``, the panel's Identification and Gap tabs and the
demo all call :func:`run_identification` (-> the typed ``labid.base.results.Identification``,
through ``labid.workflows.identification.flow.identify``) and :func:`run_diagnosis` (the
``labid diagnose`` document, ``labid.workflows.diagnosis``). The option parsers
(:func:`parse_names`, :func:`parse_start`, :func:`check_prior`) give the one-line errors of
both commands and the panel; :func:`store_for_features` keeps a result computed from a
features file in the run file it came from (``labid.services.store_result``: never replacing
an older one silently).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from .base.errors import UserError
from .base.results import Identification
from .inputs.features import read_features, specimen_of
from .inputs.specimen import BUILTIN, Specimen
from .workflows.identification import METHODS, minima_summary, parse_assignments
from .workflows.identification.estimation import default_names
from .workflows.identification.flow import identify

__all__ = ["Identification", "METHODS", "minima_summary", "default_params_for", "select_data", "load_features_file", "specimen_for_features",
           "parse_start", "parse_names", "check_prior", "connect_scheduler", "run_identification",
           "identification_of", "run_diagnosis", "run_of_features"]

Progress = Callable[[Any], None]
ShouldStop = Callable[[], bool]


def select_data(doc: Mapping, data: str) -> dict:
    """The features document restricted to 'modal', 'waves' or 'combined' data."""
    out = dict(doc)
    if data == "modal":
        out.pop("waves", None)
    elif data == "waves":
        out.pop("modal", None)
    return out


def load_features_file(path: str | Path) -> dict:
    """A features file, validated (``labid.inputs.features.read_features``), its specimen path
    made usable from anywhere (absolute; a built-in name kept)."""
    doc = read_features(path)
    spec = doc.get("specimen")
    if isinstance(spec, str) and spec not in BUILTIN:
        p = Path(spec)
        doc["specimen"] = str(p if p.is_absolute() else Path(path).parent / p)
    return doc


def specimen_for_features(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>") -> Specimen | None:
    """The specimen a features document refers to (``labid.inputs.features.specimen_of``:
    inline, path relative to ``base_dir`` or built-in); None if it names none."""
    if doc.get("specimen") is None:
        return None
    return specimen_of(doc, base_dir, src)


def default_params_for(doc: Mapping, isotropic: bool) -> tuple[str, ...]:
    """The constants ``labid identify`` fits by default for features ``doc`` (its rule,
    ``estimation.default_names``, asked without building the FE model)."""
    waves = doc.get("waves") or []
    waves = [w for w in ([waves] if isinstance(waves, Mapping) else waves) if isinstance(w, Mapping)]
    kinds = ({"modal"} if doc.get("modal") else set()) | ({"waves"} if waves else set())
    return default_names(kinds, isotropic, [w.get("mode", "A0") for w in waves])


def parse_start(text: str | None, option: str = "start") -> dict[str, float]:
    """Initial values 'P=V,..' (SI) as a dict; UserError naming ``option`` on a bad value."""
    return parse_assignments(text, option)


def parse_names(text: str | None, option: str = "--params") -> tuple[str, ...] | None:
    """Constants 'P1,P2,..' (None when not given); UserError naming ``option`` when empty."""
    if not text:
        return None
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise UserError(f"value {text!r}: expected P1,P2,..", key=option)
    return names


def check_prior(prior: float | None, option: str = "--prior") -> float | None:
    """A prior std (None: none); UserError naming ``option`` unless positive."""
    if prior is not None and not prior > 0:
        raise UserError(f"value {prior!r}: expected a positive number", key=option)
    return prior


def connect_scheduler(address: str | None, n_starts: int):
    """The Dask client of ``labid identify --scheduler`` (None without an address), its
    workers checked before any fitting (``labid.workflows.cluster``)."""
    from .workflows import cluster  # here: importlib.metadata and Dask only with --scheduler
    return cluster.connect(address, n_starts)


def run_identification(doc: Mapping, *, specimen: Specimen | None = None, base_dir: str | Path = ".",
                       src: str = "<features>", names: Sequence[str] | None = None,
                       start: Mapping[str, float] | None = None, method: str = "lm", prior: float | None = None,
                       n_starts: int = 0, seed: int = 0, workers: int = 1, executor=None, mcmc: int = 0,
                       budget: bool = False, progress: Progress | None = None,
                       should_stop: ShouldStop | None = None) -> Identification:
    """The one identification flow (``labid.workflows.identification.flow.identify``: options,
    progress and cancellation there) -> ``Identification``; ``to_dict()`` is the
    ``labid identify --json`` document and what the run file keeps."""
    return identify(doc, base_dir=base_dir, src=src, specimen=specimen, names=names, start=start, method=method,
                    prior=prior, n_starts=n_starts, seed=seed, workers=workers, executor=executor, mcmc=mcmc,
                    budget=budget, progress=progress, should_stop=should_stop)


def identification_of(result: Mapping | Identification | None) -> Identification | None:
    """The typed identification of a stored or ``--json`` result (None for none)."""
    if result is None or isinstance(result, Identification):
        return result
    return Identification.from_dict(result) if isinstance(result, Mapping) and result.get("parameters") else None


def run_diagnosis(doc: Mapping, base_dir: str | Path = ".", src: str = "<features>", options=None,
                  names: Sequence[str] | None = None, start: Mapping[str, float] | None = None,
                  prior: float | None = None, estimate: Mapping | Identification | None = None,
                  alpha: float | None = None) -> dict:
    """The sim-to-real gap diagnosis of a features document (``labid.workflows.diagnosis``),
    from identify's estimate of ``names`` (None: identify's default selection) from
    ``start`` with ``prior``; ``estimate``: that identification when at hand (not
    recomputed); ``alpha``: the false-alarm rate of the gap test (``options`` else)."""
    # imported here: engine.gap brings scipy.stats (~0.3-0.5 s CPU), which the commands that
    # do not diagnose (acquire, analyze, report, export, the panel's start) need not import
    from engine.gap import GapOptions
    from .workflows import diagnosis as diag
    if alpha is not None:
        if not 0.0 < alpha < 0.5:
            raise UserError(f"value {alpha!r}: expected a false-alarm rate in (0, 0.5)", key="--alpha")
        options = GapOptions(alpha=alpha)
    if isinstance(estimate, Identification):
        estimate = estimate.to_dict()
    return diag.run_diagnosis(doc, base_dir, src, options, names=names, start=start, prior=prior, estimate=estimate)


def run_of_features(features_file: str | Path) -> Path | None:
    """The run file a features file was computed from (its ``analysis.run``, relative
    to the features file), if that file exists; else None."""
    p = Path(features_file)
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    ref = (doc.get("analysis") or {}).get("run") if isinstance(doc, dict) else None
    if not isinstance(ref, str) or not ref:
        return None
    run = (Path(ref) if Path(ref).is_absolute() else p.parent / ref).resolve()
    return run if run.is_file() else None
