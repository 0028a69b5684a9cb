"""``labid export``: a run's data and results in the formats modal and NDT tools exchange.

UFF (written by pyuff; SI units, data set 164 first):

- 15 nodes: one per rig channel with a position on the plate (node = the channel's number
  in the rig, from 1; z = 0) and the hammer point (node = number of channels + 1), in m;
- 58 FRFs (function type 4): H1 of each accelerometer to the force, as the analysis
  computes it (its exponential and force windows), (m/s^2)/N against Hz; response node and
  direction +Z, reference the hammer node +Z; ID line 1 ``H1 <channel>``;
- 58 time data (function type 1): every channel of every shot in its physical unit
  (m/s^2, N, V: the stored volts divided by the sensitivity), abscissa from -pretrigger/rate
  (s); ID line 1 the channel name (what ``labid import`` maps), line 2 the shot, line 3 its
  date and time, line 5 ``kind=<hammer|wave>``;
- 55 modes (normal modes, analysis type 2): the picked peaks in frequency order, frequency
  (Hz), modal viscous damping ratio zeta and hysteretic loss factor eta = 2 zeta (the same
  damping in its two conventions: do not add them; labid.workflows.damping), ID line 3 the mode's
  family label ('(2,0)', 'unlabelled'; 'NONE' without labels), the mode shape
  (+Z, any scaling) at the accelerometer nodes where the analysis has one.

Binary UFF58 keeps the samples exactly (double); ASCII keeps 12 digits. UFF keeps the
abscissa increment and the modal frequency to 6 digits (format E13.5).

CSV tables (one header row, units in the column names or in a ``unit`` column):

- ``features_modal.csv``: mode, frequency_hz, sigma_hz, damping_ratio, confidence, loss_factor
  (eta = 2 zeta), family (the mode's (m, n) label, labid.workflows.damping);
- ``features_waves.csv``: mode, direction_deg, frequency_hz, group_velocity_m_s, sigma_m_s;
- ``constants.csv``: result, parameter, value, std, unit, rel_std, identified, constrained_by
  (value and std in the unit: Pa, kg/m^3, 1);
- ``diagnosis_summary.csv``: quantity, value (the gap figures: rms of residual/sigma, chi^2,
  p-values, verdict, where); ``diagnosis_effects.csv``: rank, name, magnitude, std, unit,
  gap_after, score, delta_chi2, detectable, refitted, absorbed_fraction;
  ``diagnosis_residuals.csv``: feature, then per feature the diagnosis's columns (modality,
  set, residual_before, residual_after: whitened residuals, 1 = noise level).

Every file is written atomically (``labid.base.atomic``: a temporary file beside it, renamed
over it once complete and synced): a kill or a full disk leaves the old file or the new
one, never a part (issue 27); a failure to write is one line naming the file.
"""
from __future__ import annotations

import csv
import datetime as dt
import io
import json
import math
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from ..base import atomic
from ..base.errors import UserError
from ..inputs.rig import rig_from_text
from ..inputs.units import loss_factors
from ..base.results import Identification
from ..base.summary import unit_of
from ..store import RunStore, decode_result, software_version

#: UFF58 specific data types (record 8-11, field 1)
SPEC_TYPE = {"accelerometer": 12, "force": 13, "voltage": 1}
UNIT_LABEL = {"accelerometer": "m/s^2", "force": "N", "voltage": "V"}
# ------------------------------------------------------------------ UFF
def node_numbers(channels: Sequence[Any], hammer: bool) -> tuple[dict[str, int], int | None]:
    """UFF node of each rig channel (its number in the rig, from 1) and of the hammer point."""
    nodes = {c.name: i + 1 for i, c in enumerate(channels)}
    return nodes, (len(channels) + 1 if hammer else None)


def uff_nodes(channels: Sequence[Any], hammer_xy: tuple[float, float] | None) -> dict | None:
    """Data set 15: the positioned channels and the hammer point (m)."""
    import pyuff  # noqa: PLC0415 - only when UFF is written

    nodes, hn = node_numbers(channels, hammer_xy is not None)
    pts = [(nodes[c.name], c.x, c.y) for c in channels if c.x is not None and c.y is not None]
    if hammer_xy is not None:
        pts.append((hn, *hammer_xy))
    if not pts:
        return None
    n = np.array([p[0] for p in pts])
    return pyuff.prepare_15(node_nums=n, def_cs=np.zeros_like(n), disp_cs=np.zeros_like(n),
                            color=np.ones_like(n), x=np.array([float(p[1]) for p in pts]),
                            y=np.array([float(p[2]) for p in pts]), z=np.zeros(len(pts)))


def uff_time(name: str, kind: str, node: int, data: np.ndarray, rate_hz: float, pretrigger: int,
             channel_kind: str, shot: str = "", stamp: float | None = None, note: str = "",
             binary: bool = True) -> dict:
    """Data set 58, function type 1: one channel of one shot in its physical unit."""
    import pyuff  # noqa: PLC0415

    x = (np.arange(data.size) - pretrigger) / rate_hz
    when = dt.datetime.fromtimestamp(stamp).strftime("%d-%b-%y %H:%M:%S") if stamp else "NONE"
    return pyuff.prepare_58(binary=int(binary), id1=name, id2=shot or "NONE", id3=when, id4=note or "NONE",
                            id5=f"kind={kind}", func_type=1, rsp_node=int(node), rsp_dir=3, ref_node=0, ref_dir=0,
                            data=np.asarray(data, float), x=x, abscissa_spacing=1, abscissa_spec_data_type=17,
                            abscissa_axis_units_lab="s", ordinate_spec_data_type=SPEC_TYPE[channel_kind],
                            ordinate_axis_units_lab=UNIT_LABEL[channel_kind], orddenom_spec_data_type=0,
                            z_axis_spec_data_type=0)


def uff_frf(channel: str, node: int, ref_node: int, freqs: np.ndarray, h: np.ndarray, note: str = "",
            binary: bool = True) -> dict:
    """Data set 58, function type 4: H1 (m/s^2)/N of one accelerometer to the hammer."""
    import pyuff  # noqa: PLC0415

    return pyuff.prepare_58(binary=int(binary), id1=f"H1 {channel}", id2="accelerance (m/s^2)/N",
                            id4=note or "NONE", id5="kind=frf", func_type=4, rsp_node=int(node), rsp_dir=3,
                            ref_node=int(ref_node), ref_dir=3, data=np.asarray(h, complex),
                            x=np.asarray(freqs, float), abscissa_spacing=1, abscissa_spec_data_type=18,
                            abscissa_axis_units_lab="Hz", ordinate_spec_data_type=12,
                            ordinate_axis_units_lab="m/s^2", orddenom_spec_data_type=13,
                            orddenom_axis_units_lab="N", z_axis_spec_data_type=0)


def uff_modes(frequencies_hz: Sequence[float], nodes: Sequence[int] = (),
              shapes: Sequence[Sequence[float]] | None = None, damping_ratio: Sequence[float] | None = None,
              loss_factor: Sequence[float] | None = None, note: str = "",
              labels: Sequence[str] | None = None) -> list[dict]:
    """Data sets 55 (normal modes): one per mode, frequency in Hz, modal viscous damping
    ratio (``damping_ratio``) and hysteretic loss factor (``loss_factor``) when given, the
    shape (+Z) at ``nodes`` when ``shapes[i]`` has one value per node; ``labels[i]`` (the
    mode family, e.g. '(2,0)') goes on ID line 3."""
    import pyuff  # noqa: PLC0415

    out = []
    nn = np.asarray(list(nodes), int)
    for i, f in enumerate(frequencies_hz):
        s = shapes[i] if shapes is not None and i < len(shapes) and len(shapes[i]) == nn.size else None
        r3 = np.asarray(s, float) if s is not None else np.zeros(0)
        n = nn if s is not None else np.zeros(0, int)
        z = 0.0
        vis = float(damping_ratio[i]) if damping_ratio is not None and np.isfinite(damping_ratio[i]) else z
        his = float(loss_factor[i]) if loss_factor is not None and np.isfinite(loss_factor[i]) else z
        lab = labels[i] if labels is not None and i < len(labels) and labels[i] else "NONE"
        out.append(pyuff.prepare_55(id1=f"mode {i + 1}", id2=f"{float(f):.6g} Hz", id3=lab, id4=note or "NONE",
                                    id5="picked peaks (labid analyze)", model_type=1, analysis_type=2, data_ch=2,
                                    spec_data_type=8, load_case=1, mode_n=i + 1, freq=float(f), modal_m=0.0,
                                    modal_damp_vis=vis, modal_damp_his=his, node_nums=n, r1=np.zeros(r3.size),
                                    r2=np.zeros(r3.size), r3=r3))
    return out


#: the hammer spectra (``engine.modal.Spectra``, with ``frf`` when a force is recorded) of a
#: run's hammer records as its stored analysis (or None) computed them: the analysis
#: workflow's, passed in by ``labid.services`` (io imports no workflow)
SpectraOf = Callable[[Sequence[Any], Any], Any]


def export_uff(run: str | Path, path: str | Path, binary: bool = True, spectra: SpectraOf | None = None) -> dict:
    """Write the UFF file of a run (module docstring); returns what was written. Without
    ``spectra`` no FRF is written."""
    import pyuff  # noqa: PLC0415

    with RunStore(run, "r") as st:
        rig = rig_from_text(st.rig_toml(), f"{run}#config/rig_toml")
        hammer, wave = st.shots("hammer"), st.shots("wave")
        analysis = decode_result(st.read_group("analysis")) if "analysis" in st.result_names() else None
    chans = [c for d in rig.devices for c in d.channels]
    nodes, hnode = node_numbers(chans, rig.hammer is not None)
    note = f"labid {software_version()} {Path(run).name}"[:80]
    sets: list[dict] = [pyuff.prepare_164(units_code=1, units_description="SI", temp_mode=1, length=1.0,
                                          force=1.0, temp=1.0, temp_offset=273.15)]
    n15 = uff_nodes(chans, (rig.hammer.x, rig.hammer.y) if rig.hammer is not None else None)
    if n15 is not None:
        sets.append(n15)
    counts = {"frf": 0, "time": 0, "modes": 0}
    notes = []
    if hammer:
        spec = spectra(hammer, analysis if isinstance(analysis, dict) else None) if spectra else None
        if spec is not None and spec.frf is not None and hnode is not None:
            for k, ch in enumerate(spec.channels):
                sets.append(uff_frf(ch, nodes.get(ch, k + 1), hnode, spec.frequencies_hz, spec.frf[k], note,
                                    binary))
                counts["frf"] += 1
        else:
            notes.append("no FRF: the hammer shots record no force (or the rig has no hammer point)")
    for kind, recs in (("hammer", hammer), ("wave", wave)):
        for r in recs:
            for c in r.channels:
                sets.append(uff_time(c.name, kind, nodes.get(c.name, 0), r.scaled(c.name), r.timing.rate_hz,
                                     r.timing.pretrigger, c.kind, r.meta.get("shot", ""), r.timestamp, note,
                                     binary))
                counts["time"] += 1
    feats = _features(analysis)
    modal = (feats or {}).get("modal") or {}
    if modal.get("frequencies_hz"):
        ms = modal.get("mode_shapes") or {}
        pts = ms.get("points") or []
        acc = [c for c in chans if c.kind == "accelerometer" and c.x is not None]
        nn = []
        for x, y in pts:            # the shape points are the accelerometers' positions
            m = next((c for c in acc if abs(c.x - x) < 1e-9 and abs(c.y - y) < 1e-9), None)
            nn.append(nodes[m.name] if m is not None else None)
        shapes = ms.get("values") if pts and None not in nn else None
        loss, labels = _damping_columns(feats, len(modal["frequencies_hz"]))
        sets += uff_modes(modal["frequencies_hz"], nn if shapes else (), shapes, modal.get("damping_ratio"),
                          loss, note, labels)
        counts["modes"] = len(modal["frequencies_hz"])
    else:
        notes.append("no modes: the run has not been analysed (labid analyze) or holds no peak")
    path = Path(path)
    with atomic.replacing(path, key="--uff") as tmp:
        try:
            pyuff.UFF(str(tmp)).write_sets(sets, mode="add")
        except Exception as e:  # noqa: BLE001 - pyuff turns the OSError of a full disk into a bare Exception
            cause = _os_error(e)
            if cause is None:
                raise
            raise cause from None           # atomic.replacing: one line, the old file kept
    return {"uff": str(path), "datasets": len(sets), **counts, "notes": notes}


def _os_error(e: BaseException | None) -> OSError | None:
    """The OSError with an errno behind ``e`` (itself, or its cause or context), if any."""
    seen = 0
    while e is not None and seen < 10:
        if isinstance(e, OSError) and e.errno is not None:
            return e
        e, seen = e.__cause__ or e.__context__, seen + 1
    return None


def _damping_columns(feats: Mapping, n: int) -> tuple[list[float] | None, list[str] | None]:
    """(loss factor, family label) per mode: the analysis's ``damping`` section (issue 16),
    else eta = 2 zeta from the modal damping ratios, without labels."""
    modes = (feats.get("damping") or {}).get("modes") or []
    f = (feats.get("modal") or {}).get("frequencies_hz") or []
    if len(modes) == n == len(f) and all(m.get("frequency_hz") == x for m, x in zip(modes, f)):  # not stale
        return [m.get("loss_factor", math.nan) for m in modes], [m.get("label") or "" for m in modes]
    z = (feats.get("modal") or {}).get("damping_ratio")
    return (loss_factors(z) if z and len(z) == n else None), None


def _features(analysis: Any) -> dict | None:
    if not isinstance(analysis, dict):
        return None
    f = analysis.get("features")
    if isinstance(f, dict) and isinstance(f.get("json"), str):
        return json.loads(f["json"])
    return f if isinstance(f, dict) else None


# ------------------------------------------------------------------ CSV
def _write(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(header)
    for r in rows:
        w.writerow(["" if v is None else (repr(float(v)) if isinstance(v, (float, np.floating)) else v)
                    for v in r])
    atomic.write_text(path, buf.getvalue(), key="--csv")
    return str(path)


def _dir(d: str | Path) -> Path:
    p = Path(d)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"cannot create the folder: {e.strerror or e}", file=str(p), key="--csv") from None
    return p


def feature_tables(features: Mapping, csv_dir: str | Path) -> list[str]:
    """features_modal.csv and features_waves.csv of a features document (CONTRACT section 2)."""
    d, out = _dir(csv_dir), []
    m = features.get("modal") or {}
    f = m.get("frequencies_hz") or []
    if f:
        col = {k: m.get(k) or [None] * len(f) for k in ("sigma_hz", "damping_ratio", "confidence")}
        loss, labels = _damping_columns(features, len(f))
        loss, labels = loss or [None] * len(f), labels or [""] * len(f)
        out.append(_write(d / "features_modal.csv", ["mode", "frequency_hz", "sigma_hz", "damping_ratio",
                                                     "confidence", "loss_factor", "family"],
                          ([i + 1, f[i], col["sigma_hz"][i], col["damping_ratio"][i], col["confidence"][i],
                            loss[i], labels[i]] for i in range(len(f)))))
    rows = []
    for w in features.get("waves") or []:
        for i, fr in enumerate(w.get("frequency_hz") or []):
            rows.append([w.get("mode"), w.get("direction_deg"), fr, w["group_velocity_m_s"][i],
                         (w.get("sigma_m_s") or [None] * (i + 1))[i]])
    if rows:
        out.append(_write(d / "features_waves.csv", ["mode", "direction_deg", "frequency_hz", "group_velocity_m_s",
                                                     "sigma_m_s"], rows))
    return out


def constants_rows(result: Mapping, name: str = "identification") -> list[list[Any]]:
    """Rows of constants.csv for one identification result (``identified``: the one
    definition, ``labid.base.results.Identification.status``)."""
    typed = Identification.from_dict(result)
    ident = ((result.get("identifiability") or {}).get("parameters")) or {}
    rows = []
    for p, v in typed.parameters.items():
        val, std = v.get("value"), v.get("std")
        info = ident.get(p) or {}
        rel = info.get("rel_std", (std / abs(val)) if val and std is not None else None)
        rows.append([name, p, val, std, unit_of(p, plain=True), rel, typed.is_identified(p),
                     "+".join(info.get("constrained_by") or [])])
    return rows


CONSTANTS_HEADER = ["result", "parameter", "value", "std", "unit", "rel_std", "identified", "constrained_by"]


def diagnosis_tables(res: Mapping, csv_dir: str | Path) -> list[str]:
    """diagnosis_summary.csv, diagnosis_effects.csv, diagnosis_residuals.csv of a diagnosis."""
    d, out = _dir(csv_dir), []
    g = res.get("gap") or {}
    summary = [[k, v] for k, v in g.items() if not isinstance(v, (dict, list))]
    summary += [["verdict", res.get("verdict")], ["where", ";".join(map(str, res.get("where") or []))]]
    out.append(_write(d / "diagnosis_summary.csv", ["quantity", "value"], summary))
    cols = ["name", "magnitude", "std", "unit", "gap_after", "score", "delta_chi2", "detectable", "refitted",
            "absorbed_fraction"]
    out.append(_write(d / "diagnosis_effects.csv", ["rank"] + cols,
                      ([i + 1] + [e.get(c) for c in cols] for i, e in enumerate(res.get("effects") or []))))
    f = res.get("features") or {}
    labels = f.get("labels") or []
    if labels:
        keys = [k for k, v in f.items() if k != "labels" and isinstance(v, list) and len(v) == len(labels)]
        out.append(_write(d / "diagnosis_residuals.csv", ["feature"] + keys,
                          ([labels[i]] + [f[k][i] for k in keys] for i in range(len(labels)))))
    return out


def result_tables(result: Mapping, what: str, csv_dir: str | Path) -> list[str]:
    """The CSV tables of one result: 'identification' -> constants.csv, 'diagnosis' -> diagnosis_*.csv."""
    if what == "identification":
        return [_write(_dir(csv_dir) / "constants.csv", CONSTANTS_HEADER, constants_rows(result))]
    if what == "diagnosis":
        return diagnosis_tables(result, csv_dir)
    raise ValueError(f"result {what!r}: expected 'identification' or 'diagnosis'")


def export_csv(run: str | Path, csv_dir: str | Path) -> dict:
    """The CSV tables of a run's stored features, identifications and diagnosis."""
    with RunStore(run, "r") as st:
        names = st.result_names()
        res = {n: decode_result(st.read_group(n)) for n in names
               if n == "analysis" or n.startswith(("identification", "diagnosis"))}
    files = feature_tables(_features(res.get("analysis")) or {}, csv_dir)
    rows = [r for n in sorted(res) if n.startswith("identification") and isinstance(res[n], dict)
            for r in constants_rows(res[n], n)]
    if rows:
        files.append(_write(_dir(csv_dir) / "constants.csv", CONSTANTS_HEADER, rows))
    if isinstance(res.get("diagnosis"), dict):
        files += diagnosis_tables(res["diagnosis"], csv_dir)
    notes = [] if files else ["nothing to write: the run holds no features, constants or diagnosis yet"]
    return {"csv": [str(f) for f in files], "notes": notes}


def export_run(run: str | Path, *, uff: str | Path | None = None, csv_dir: str | Path | None = None,
               binary: bool = True, spectra: SpectraOf | None = None) -> dict:
    """``labid export``: the UFF file and/or the CSV tables of a run."""
    if uff is None and csv_dir is None:
        raise UserError("nothing to do; expected --uff FILE and/or --csv DIR", key="--uff")
    out: dict[str, Any] = {"run": str(run), "notes": []}
    if uff is not None:
        u = export_uff(run, uff, binary, spectra)
        out["notes"] += u.pop("notes")
        out.update(u)
    if csv_dir is not None:
        c = export_csv(run, csv_dir)
        out["notes"] += c.pop("notes")
        out.update(c)
    return out

