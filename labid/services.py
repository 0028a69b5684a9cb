"""The one place the lab panel, the command line and the report reach run files and workflows.

The single facade every front-end imports (the architecture rule), in sections (run file,
acquisition, analysis, identification and diagnosis, import/export); each function is a thin
call into its workflow module. Identification and diagnosis are written in
``labid.inference``, the stored results in ``labid.runresults``, the picks' editing in
``labid.picks`` and the display in ``labid.display``, re-exported here. The facade is lazy: a
module is imported when a name from it is first used (``__getattr__``, and imports inside the
functions), so each command imports only what it runs.

Front-ends (``labid.gui``, ``labid.cli``, ``labid.report``)
call these functions; they never open a ``RunStore`` or call ``engine``
themselves (except ``labid dispersion`` and ``labid modes``, which touch no
run file and must start fast). Each function opens the run file for as long
as it needs it and closes it again, so a view never holds the file open.

Run file: ``open_run`` (-> ``RunData``: configuration, shot counts, up to
``max_shots`` shots, every results group decoded), ``shots``,
``read_result``/``store_result``/``result_history`` (identifications and diagnoses are
kept: a new one moves the older one to ``/results/history/<name>/<n>``, never replaces it
silently), ``save_session``/``session_state``, ``stored_features``, ``discard_empty_run``.
Workflows: ``acquire`` (+ ``parse_effects``, ``check_daq``,
``read_instruments``), ``run_analysis``, ``save_picks`` (+ ``stored_peaks``,
``spectra_of_run``, ``spectrum_indicator``, ``toggle_peak``: ``labid.picks``),
``run_identification`` (-> ``Identification``, the
typed result), ``run_diagnosis``, ``store_for_features`` (a CLI result into the run its
features came from).
Import, export, calibration (``labid.io``): ``import_records``, ``export_run``,
``write_result_tables``, ``calibration_status`` (a rig's sheet, for the panel),
``run_calibration`` (what a run's shots were recorded with, for the report),
``warn_calibration`` (overdue calibrations, once per session).
Display (``labid.display``, re-exported): ``average_spectrum``, ``scalogram``,
``model_group_velocity``, ``model_frequencies``, ``parameters_of``.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from drivers.protocol import AcquisitionError, Record
from .base.errors import UserError

if TYPE_CHECKING:  # for annotations and type checkers; at run time each is imported where it is used
    from mock_hw.rig import Effects
    from .base.results import Identification
    from .display import (HammerChecks, Scalogram, average_spectrum, hammer_checks, model_frequencies,
                          model_group_velocity, parameters_of, scalogram)
    from .inference import (METHODS, check_prior, connect_scheduler, default_params_for, identification_of,
                            load_features_file, minima_summary, parse_names, parse_start, run_diagnosis,
                            run_identification, run_of_features, select_data, specimen_for_features)
    from .inputs.rig import Rig
    from .inputs.specimen import Specimen
    from .picks import (analysed_spectra, features_path, save_picks, spectra_of_run, spectrum_indicator,
                        stored_peaks, stored_settings, toggle_peak)
    from .runresults import HISTORY_GROUP, KEPT, kept, read_result, result_history, store_for_features, store_result
    from .workflows import plan as planning
    from .workflows.analysis import Analysis, AnalysisSettings
    from .workflows.damping import family_of

# The facade is lazy (issue 29): every command imports ``labid.services``, so a workflow, the run
# store, the simulated rig or the display is imported only when a name from it is used, by the
# functions below (imports inside them) or by ``__getattr__`` for the re-exported names.
# ``labid diagnose`` then imports the identification and the gap alone (measured, -X importtime:
# bench/bench_imports.py; eager, every command paid ~0.4-0.6 s CPU for the others).
_INFERENCE = frozenset({"METHODS", "check_prior", "connect_scheduler", "default_params_for", "identification_of",
                        "load_features_file", "minima_summary", "parse_names", "parse_start", "run_diagnosis",
                        "run_identification", "run_of_features", "select_data", "specimen_for_features"})
_RUNRESULTS = frozenset({"HISTORY_GROUP", "KEPT", "kept", "read_result", "result_history", "store_for_features",
                         "store_result"})
_PICKS = frozenset({"analysed_spectra", "features_path", "save_picks", "spectra_of_run", "spectrum_indicator",
                    "stored_peaks", "stored_settings", "toggle_peak"})
_DISPLAY = frozenset({"HammerChecks", "Scalogram", "average_spectrum", "hammer_checks", "model_frequencies",
                      "model_group_velocity", "parameters_of", "scalogram"})


def __getattr__(name: str) -> Any:
    """The re-exported names, each imported at its first use (PEP 562)."""
    if name in _INFERENCE:
        from . import inference as mod
    elif name in _RUNRESULTS:
        from . import runresults as mod
    elif name in _PICKS:
        from . import picks as mod
    elif name in _DISPLAY:
        from . import display as mod
    elif name == "Identification":
        from .base import results as mod
    elif name == "AnalysisSettings":
        from .workflows import analysis as mod
    elif name == "family_of":
        from .workflows import damping as mod
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(mod, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__all__ = [
    # the run file
    "RunData", "open_run", "shots", "read_result", "store_result", "result_history", "kept", "save_session",
    "session_state", "lookup", "features_of", "stored_features", "discard_empty_run",
    "FEATURES_GROUPS", "IDENT_GROUPS", "GAP_GROUPS", "SESSION_GROUP", "USER_ERRORS", "KEPT", "HISTORY_GROUP",
    # acquisition
    "parse_effects", "acquire", "check_daq", "read_instruments",
    # analysis and picks
    "AnalysisSettings", "features_path", "run_analysis", "run_reference", "stored_peaks", "save_picks", "spectra_of_run",
    "spectrum_indicator", "toggle_peak", "stored_settings", "analysed_spectra",
    # identification and diagnosis (labid.inference)
    "Identification", "identification_of", "METHODS", "minima_summary", "default_params_for", "select_data", "load_features_file",
    "specimen_for_features", "parse_start", "parse_names", "check_prior", "connect_scheduler", "family_of",
    "run_identification", "run_diagnosis", "run_of_features", "store_for_features", "plan_test",
    # import, export, calibration (labid.io)
    "import_records", "export_run", "write_result_tables", "calibration_status", "run_calibration",
    "warn_calibration",
    # display (labid.display)
    "Scalogram", "average_spectrum", "scalogram", "HammerChecks", "hammer_checks", "model_group_velocity", "model_frequencies", "parameters_of",
]

#: where the workflows' results sit under /results (first match wins)
FEATURES_GROUPS = ("features", "analysis/features", "analysis")
IDENT_GROUPS = ("identification", "identify")
GAP_GROUPS = ("diagnosis", "gap", "diagnose")
#: exceptions whose message is for the user (one line, no traceback)
USER_ERRORS: tuple[type[BaseException], ...] = (UserError, AcquisitionError, ValueError)
#: the results group the panel keeps its session state in
SESSION_GROUP = "gui"

Progress = Callable[[Any], None]
ShouldStop = Callable[[], bool]


# ============================================================== the run file
@dataclass
class RunData:
    """What a front-end reads from a run file (``open_run``)."""

    path: str
    specimen_toml: str = ""
    rig_toml: str = ""
    attrs: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)
    hammer: list = field(default_factory=list)
    wave: list = field(default_factory=list)
    results: dict = field(default_factory=dict)


def open_run(path: str | Path, max_shots: int = 0) -> RunData:
    """Read configuration, shot counts, at most ``max_shots`` shots per kind and every
    results group (JSON copies preferred). UserError for a file that is not a run."""
    from .runresults import HISTORY_GROUP
    from .store import KINDS, RunStore
    with RunStore(path, "r") as st:
        rd = RunData(str(path), st.specimen_toml(), st.rig_toml())
        rd.attrs = st.attributes()
        rd.counts = {k: st.n_shots(k) for k in KINDS}
        if rd.counts["hammer"] and max_shots:
            rd.hammer = st.shots("hammer", limit=max_shots)
        if rd.counts["wave"] and max_shots:
            rd.wave = st.shots("wave", limit=max_shots)
        for name in st.result_names():
            if name == HISTORY_GROUP:                 # older results: read on request (result_history)
                continue
            try:
                rd.results[name] = st.read_result(name)     # the JSON copy alone when there is one
            except (KeyError, ValueError, OSError):
                continue
    return rd


def shots(run: str | Path, kind: str, limit: int | None = None) -> list[Record]:
    """The committed shots of ``kind`` in ``run`` (at most ``limit``), as Records."""
    from .store import RunStore
    with RunStore(run, "r") as st:
        return st.shots(kind, limit=limit)


def save_session(run: str | Path, state: Mapping) -> None:
    """Store the panel's session state (views, settings) in ``run``."""
    from .store import RunStore
    with RunStore(run, "a") as st:
        st.write_group(SESSION_GROUP, {"state_json": json.dumps(state)})


def session_state(rd: RunData) -> dict:
    """The panel's session state stored in a run ({} if none or unreadable)."""
    gui = rd.results.get(SESSION_GROUP)
    text = gui.get("state_json") if isinstance(gui, dict) else None
    if not text:
        return {}
    try:
        st = json.loads(text)
    except (TypeError, ValueError):
        return {}
    return st if isinstance(st, dict) else {}


def lookup(results: dict, paths: tuple[str, ...]) -> Any:
    """The first of ``paths`` ('a/b') present in the nested results dict, else None."""
    for p in paths:
        node: Any = results
        for part in p.split("/"):
            if isinstance(node, dict) and part in node:
                node = node[part]
            else:
                node = None
                break
        if node is not None:
            return node
    return None


def features_of(rd: RunData) -> dict:
    """The measured features (CONTRACT section 2) stored in the run, or {}."""
    f = lookup(rd.results, FEATURES_GROUPS)
    if isinstance(f, dict) and isinstance(f.get("features"), dict):
        f = f["features"]
    if isinstance(f, dict) and isinstance(f.get("json"), str):
        try:
            return json.loads(f["json"])
        except ValueError:
            return {}
    return f if isinstance(f, dict) and ("modal" in f or "waves" in f) else {}


def stored_features(run: str | Path) -> dict:
    """The features the analysis stored in ``run`` ({} if none)."""
    return features_of(open_run(run, max_shots=0))


def discard_empty_run(path: str | Path) -> bool:
    """Delete ``path`` if it is a run file without any shot (created by a session that
    recorded nothing); True if deleted. Unreadable files are left alone, and so is a file
    another writer holds (it may be a session that has just created it)."""
    from .store import RunStore, WriterLock
    path = Path(path)
    if not path.exists():
        return False
    try:
        with WriterLock(path):
            with RunStore(path, "r") as s:
                empty = s.n_shots() == 0
            if empty:
                path.unlink()
    except Exception:  # noqa: BLE001 - not ours to judge: keep it
        return False
    return empty


# ============================================================== acquisition
def parse_effects(text: str, key: str = "--effects") -> Effects | None:
    """Unmodelled effects for the simulated rig from 'name=value,..' (SI units; None if
    empty); UserError naming ``key`` on a bad name or value."""
    from mock_hw.rig import Effects
    text = (text or "").strip()
    if not text:
        return None
    try:
        return Effects.parse(text)
    except ValueError as e:
        raise UserError(str(e), key=key) from None


def acquire(run: str | Path, rig: Rig | str | None, specimen: Specimen | str, *, backend: str = "mock",
            effects: Effects | None = None, seed: int = 0, hits: int | None = None,
            waves: int | None = None, total: bool = False, progress: Progress | None = None,
            should_stop: ShouldStop | None = None,
            on_record: Callable[[str, Record], None] | None = None) -> dict:
    """Record ``hits`` hammer hits and ``waves`` wave shots into ``run`` (created or
    appended to; each shot flushed at once). ``on_record(kind, record)`` sees every
    device read (accepted or not). Returns the session summary."""
    from .store import RunStore
    from .workflows.acquisition import AcquisitionSession, LiveSession
    with RunStore(run, "a") as store:
        if on_record is None:
            session = AcquisitionSession(rig, specimen, store, backend=backend, effects=effects, seed=seed)
        else:
            session = LiveSession(rig, specimen, store, backend=backend, effects=effects, seed=seed,
                                  on_record=on_record)
        return session.run(hits, waves, progress=progress, should_stop=should_stop, total=total)


def check_daq(rig: Rig, specimen: Specimen) -> list[str]:
    """Configure every device of ``rig`` on NI-DAQmx as an acquisition would; returns
    their names (UserError naming the device and the cause otherwise)."""
    from .workflows.acquisition import AcquisitionSession
    session = AcquisitionSession(rig, specimen, None, backend="nidaqmx")
    try:
        for d in rig.devices:
            session.device(d.role)
    finally:
        session.close()
    return [d.name for d in rig.devices]


def read_instruments(env_port: str, hammer_port: str) -> dict:
    """Query the environment probe and the hammer unit on their serial ports.

    Returns ``{"env": {...}, "hammer": {...}}`` for the ports given, each
    ``ok`` with its readings or not ``ok`` with a one-line ``message``."""
    from drivers.serial_instruments import EnvironmentProbe, HammerUnit, InstrumentError
    out = {}
    for key, port, cls in (("env", env_port, EnvironmentProbe), ("hammer", hammer_port, HammerUnit)):
        if not port:
            continue
        try:
            with cls(port, timeout_s=0.3, tries=2, retry_delay_s=0.02) as inst:
                who = inst.identify()
                if key == "env":
                    out[key] = dict(ok=True, ident=f"{who.model} {who.serial} fw {who.firmware}",
                                    temperature_c=inst.temperature(), humidity_pct=inst.humidity())
                else:
                    out[key] = dict(ok=True, ident=f"{who.model} {who.serial} fw {who.firmware}",
                                    ready=inst.ready(), count=inst.count(), level=inst.level())
        except InstrumentError as e:
            out[key] = dict(ok=False, message=str(e))
    return out


# ============================================================== analysis (the picks' editing: labid.picks)
def run_analysis(run: str | Path, settings: AnalysisSettings | None = None, *,
                 out: str | Path | None = None, temperature_c: float | None = None,
                 iterate: int = 0, iterate_params: Sequence[str] | None = None) -> Analysis:
    """Analyse the shots of ``run`` (as ``labid analyze``): write the features file
    ``out`` (default ``features_path(run)``) and ``/results/analysis``.

    ``temperature_c`` (the environment probe) goes into ``rig.temperature_c`` unless
    the rig section has one. ``analysis.run`` of the features is the run file's path
    relative to the features file, so that results computed from the features can be
    stored back into their run (``store_for_features``).
    ``iterate`` > 0: the wave picks are redone with the identified constants until they
    stop changing, at most that many rounds (``labid.workflows.waveloop``; ``iterate_params``:
    the constants identified in each round, default identify's)."""
    from .store import RunStore, WriterLock
    from .workflows import waveloop
    from .picks import features_path
    from .workflows.analysis import AnalysisSettings, analyze_store, store_analysis
    settings = settings or AnalysisSettings()
    out = Path(out) if out is not None else features_path(run)
    with RunStore(run, "r") as st:               # a damaged or missing run: one line first
        pass
    with WriterLock(run):                        # one writer at a time, refused at once
        with RunStore(run, "r") as st:
            an = analyze_store(st, settings)
            if iterate:       # issue 24: pick <-> identify until the picks stop changing
                an = waveloop.iterate_store(st, an, settings, names=iterate_params, max_iter=iterate)
        if temperature_c is not None and math.isfinite(temperature_c):
            an.features.setdefault("rig", {}).setdefault("temperature_c", float(temperature_c))
        an.features.setdefault("analysis", {})["run"] = run_reference(run, out)
        store_analysis(run, an, out, settings)
    return an


def run_reference(run: str | Path, features_file: str | Path) -> str:
    """The run file as the features file refers to it: relative to its directory."""
    return os.path.relpath(Path(run).resolve(), Path(features_file).resolve().parent)


# ============================================================== identification and diagnosis
# (labid.inference: run_identification, run_diagnosis and their option parsers, re-exported)


def plan_test(spec: Specimen | str, rig: Rig | str | None = None, compare: Sequence[Rig | str] = (), *,
              progress: Callable[[str], None] | None = None, should_stop: ShouldStop | None = None,
              **options) -> "planning.PlanResult":
    """``labid plan`` and the setup view's Plan box (issue 25, ``labid.workflows.plan``): the
    recommended test of ``spec`` (object, path or built-in name) on ``rig`` (None: the built-in
    rig) and ``compare`` rigs; ``options``: the command's raw option values
    (``labid.workflows.plan_inputs.parse_options``). The result has ``to_dict()`` (the
    ``--json`` document), ``text()``, ``write_rig(path)`` and ``save_figure(path)``."""
    from .inputs.rig import Rig, load_rig
    from .inputs.specimen import Specimen, load_specimen
    from .workflows import plan as planning
    spec = spec if isinstance(spec, Specimen) else load_specimen(spec)
    rigs = [r if isinstance(r, Rig) else load_rig(r) for r in ([rig] if rig is not None else []) + list(compare)]
    for r in rigs:
        r.check_specimen(spec.length, spec.width)
    opts = planning.parse_options(planning.material_of(spec)[1], **options)
    return planning.plan_test(spec, rigs[0] if rig is not None else None, opts,
                              compare=rigs[1:] if rig is not None else rigs, progress=progress,
                              should_stop=should_stop)


# ============================================================== import, export, calibration (issue 16)
def import_records(files: Sequence[str | Path], rig: Rig | str, specimen: Specimen | str, out: str | Path,
                   map_text: str | None = None, **options) -> dict:
    """Recordings of other systems into the run ``out`` (``labid import``; options and rules:
    ``labid.io.importers.import_records``). Returns its summary dict."""
    from .io import importers
    return importers.import_records(files, rig, specimen, out, map_text, **options).to_dict()


def export_run(run: str | Path, *, uff: str | Path | None = None, csv_dir: str | Path | None = None,
               binary: bool = True) -> dict:
    """Write a run's FRFs, time data and picked modes as UFF (58, 55, 15) and its features,
    constants and diagnosis as CSV tables (``labid export``; ``labid.io.exporters``)."""
    from .io import exporters
    from .picks import analysed_spectra
    return exporters.export_run(run, uff=uff, csv_dir=csv_dir, binary=binary, spectra=analysed_spectra)


def write_result_tables(result: Mapping, what: str, csv_dir: str | Path) -> list[str]:
    """CSV tables of one result: ``what`` 'identification' (constants.csv) or 'diagnosis'
    (diagnosis_*.csv); returns the paths written (``labid identify/diagnose --csv``)."""
    from .io import exporters
    return exporters.result_tables(result, what, csv_dir)


def calibration_status(rig: Rig | str | None) -> dict:
    """The calibration a rig would be used with (its sheet; TEDS is read at acquisition
    only): ``{sheet, entries: [{channel, serial, sensitivity, ..., due_date, source}],
    overdue: [one line each], notes}``, for the panel. UserError on a bad sheet."""
    from .inputs import calibration as calib
    from .inputs.rig import Rig, load_rig
    r = rig if isinstance(rig, Rig) else load_rig(rig)
    return calib.status(calib.calibrate(r)[1])


def run_calibration(run: str | Path) -> dict:
    """The calibration a run's shots were recorded with, for the report: the sheet text
    (``/config/calibration_csv``), per channel the entry of its last shot (``{serial,
    sensitivity, calibration_date, due_date, source}``), and one line per channel that was
    recorded past its calibration's due date."""
    from .inputs import calibration as calib
    from .store import KINDS, RunStore
    with RunStore(run, "r") as st:
        sheet = st.config_text("calibration_csv")
        metas = [m for k in KINDS for m in st.metas(k)]
    return {"sheet_csv": sheet, "channels": calib.from_shot_meta(metas), "overdue": calib.overdue_in_metas(metas)}


def warn_calibration(status: Mapping | None, prefix: str = "labid", write: Callable[[str], Any] | None = None) -> list[str]:
    """Write each overdue calibration of a ``calibration_status`` once per process (the
    session: the panel calls it when a rig is loaded, the CLI on each command)."""
    from .inputs import calibration as calib
    lines = list((status or {}).get("overdue") or [])
    return calib.warn_lines(lines, (status or {}).get("sheet"), prefix=prefix, write=write)
