"""Generated inputs for the fuzz suite (tests/integration/test_fuzz.py, bench/bench_fuzz.py).

hypothesis strategies that mutate valid specimen TOML, rig TOML, features JSON, run files
(HDF5), the results stored in them, recordings (CSV, WAV, MAT, TDMS, UFF), documents nested
deep, and the options of every command; and ``run_case``: one command in-process under a
bound on its CPU time (not its wall time: a busy machine is not a hang), classified against
the CLI contract (exit 0/2/3; a 2 is one line; never a traceback, a hang or a signal).
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import shutil
import signal
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from hypothesis import strategies as st

from labid.cli import main as cli

# ------------------------------------------------------------------ TOML out (no writer library here)


def toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        r = repr(v)
        return r if ("." in r or "e" in r or "n" in r) else r + ".0"
    if isinstance(v, str):
        return json.dumps(v)                       # JSON escapes are TOML basic-string escapes
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v if x is not None) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(x)}" for k, x in v.items()
                               if x is not None) + "}"
    return json.dumps(str(v))


def toml_text(doc: dict) -> str:
    """A TOML document of ``doc`` (every table inline; None values left out)."""
    return "".join(f"{json.dumps(str(k))} = {toml_value(v)}\n" for k, v in doc.items() if v is not None)


# ------------------------------------------------------------------ valid bases
def base_specimen() -> dict:
    return tomllib.loads(resources.files("labid.data").joinpath("cfrp_12ply.toml").read_text())


def base_rig_text() -> str:
    return resources.files("labid.data").joinpath("rig_default.toml").read_text()


def base_features() -> dict:
    return {"specimen": "aluminium",
            "modal": {"frequencies_hz": [20.0, 30.0, 45.0], "sigma_hz": [0.1, 0.1, 0.1],
                      "mode_index": [1, 2, None]},
            "waves": [{"mode": "A0", "direction_deg": 0.0, "frequency_hz": [5000.0, 10000.0],
                       "group_velocity_m_s": [800.0, 1100.0], "sigma_m_s": [10.0, 10.0]}],
            "rig": {"temperature_c": 23.0, "accelerometers": [{"x": 0.02, "y": 0.02, "mass_kg": 0.002}],
                    "supports": [{"x": 0.0, "y": 0.3}], "wave_path_m": 0.375, "sensor_length_m": 0.01},
            "analysis": {"notes": []}}


# ------------------------------------------------------------------ hostile values
ABSURD_FLOATS = (0.0, -0.0, -1.0, 1e-300, 5e-324, 1e300, 1.7e308, math.inf, -math.inf, math.nan,
                 136.7, 1e30, 3.3e8, 1e-9, 1e12, -1e12, 2.0 ** 63)
hostile = st.one_of(
    st.sampled_from(ABSURD_FLOATS),
    st.integers(min_value=-(2 ** 70), max_value=2 ** 70),
    st.booleans(),
    st.text(max_size=12),
    st.sampled_from(["", "\0", "/dev/zero", "/", "../../../../etc/passwd", "x" * 5000, "A0", "cfrp"]),
    st.lists(st.sampled_from(ABSURD_FLOATS), max_size=4),
    st.just([]), st.just({}), st.just(["a"]), st.just({"a": {"b": []}}),
)
NONE = object()   # "delete this key"


def _paths(doc: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path (tuple of keys/indices) into a nested dict/list document."""
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:6]):
            out += _paths(v, prefix + (i,))
    return out


def _set(doc: Any, path: tuple, value: Any) -> Any:
    if not path:
        return doc if value is NONE else value
    head, rest = path[0], path[1:]
    if isinstance(doc, dict):
        new = dict(doc)
        if not rest and value is NONE:
            new.pop(head, None)
        else:
            new[head] = _set(doc.get(head), rest, value)
        return new
    if isinstance(doc, list) and isinstance(head, int) and head < len(doc):
        new = list(doc)
        if not rest and value is NONE:
            del new[head]
        else:
            new[head] = _set(doc[head], rest, value)
        return new
    return doc


@st.composite
def mutated(draw, base: dict, extra_keys: tuple[str, ...] = ("typo", "E1 ", "plate.lenght")) -> dict:
    """``base`` with 1-3 hostile changes: a value replaced, a key deleted or added."""
    doc = base
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        what = draw(st.sampled_from(("replace", "replace", "delete", "add")))
        if what == "add" or not paths:
            at = draw(st.sampled_from([()] + [p for p in paths if isinstance(_get(doc, p), dict)]))
            doc = _set(doc, at + (draw(st.sampled_from(extra_keys)),), draw(hostile))
            continue
        path = draw(st.sampled_from(paths))
        doc = _set(doc, path, NONE if what == "delete" else draw(hostile))
    return doc


def _get(doc: Any, path: tuple) -> Any:
    for k in path:
        doc = doc[k]
    return doc


@st.composite
def garbled_text(draw, text: str) -> str:
    """``text`` with a slice replaced by random characters (mostly broken TOML/JSON)."""
    i = draw(st.integers(0, len(text)))
    j = draw(st.integers(i, min(len(text), i + 40)))
    return text[:i] + draw(st.text(max_size=20)) + text[j:]


@st.composite
def rig_texts(draw) -> str:
    """Rig TOML: the default rig with one line's value replaced, a line dropped or garbled."""
    lines = base_rig_text().splitlines()
    assigns = [i for i, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")]
    i = draw(st.sampled_from(assigns))
    key = lines[i].split("=", 1)[0].strip()
    how = draw(st.sampled_from(("value", "value", "drop", "garble")))
    if how == "value":
        lines[i] = f"{key} = {toml_value(draw(hostile))}"
    elif how == "drop":
        del lines[i]
    else:
        return draw(garbled_text("\n".join(lines)))
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ one case
class CaseTimeout(BaseException):
    """A case ran past its timeout (a hang); BaseException so that no handler swallows it."""


@dataclass
class Outcome:
    argv: list
    rc: int | None
    err: str
    kind: str        # "ok", "user", "traceback", "internal", "multiline", "hang", "signal"


def _alarm(signum, frame):
    raise CaseTimeout()


def run_case(argv: list[str], cpu_s: float = 60.0) -> Outcome:
    """``labid ARGV`` in-process with at most ``cpu_s`` s of CPU time (this process's, every
    thread: ``ITIMER_PROF``), classified against the contract; past it, a hang."""
    out, err = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGPROF, _alarm)
    signal.setitimer(signal.ITIMER_PROF, cpu_s)
    rc: int | None = None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = cli.main([*map(str, argv), "--quiet"])
            except SystemExit as e:                # usage errors (argparse), if main lets one out
                rc = e.code if isinstance(e.code, int) else 2
    except CaseTimeout:
        return Outcome(argv, None, err.getvalue(), "hang")
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old)
    return classify(argv, rc, err.getvalue())


def classify(argv: list, rc: int | None, err: str) -> Outcome:
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("warning")
             and ": note:" not in ln and "warning:" not in ln]
    if "Traceback (most recent call last)" in err:
        kind = "traceback"
    elif rc is None:
        kind = "hang"
    elif rc < 0 or rc > 128 and rc not in (130, 143):
        kind = "signal"
    elif rc == 1:
        kind = "internal"
    elif rc == 2 and len(lines) != 1:
        kind = "multiline"
    elif rc == 2:
        kind = "user"
    else:
        kind = "ok"
    return Outcome(list(argv), rc, err, kind)


BAD = ("traceback", "internal", "multiline", "hang", "signal")


def write_case(path: Path, text: str | bytes) -> Path:
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
    return path


# ------------------------------------------------------------------ damaged run files
def damaged_copy(base: Path, dst: Path, how: str, seed: int) -> Path:
    shutil.copyfile(base, dst)
    rng = np.random.default_rng(seed)
    if how == "flip":
        data = bytearray(dst.read_bytes())
        for i in rng.integers(0, len(data), int(rng.integers(1, 40))):
            data[i] ^= int(rng.integers(1, 256))
        dst.write_bytes(bytes(data))
    elif how == "truncate":
        data = dst.read_bytes()
        dst.write_bytes(data[: int(rng.integers(0, len(data)))])
    else:
        with h5py.File(dst, "a") as f:
            g = f["shots/hammer"]
            name, value = how.split("=", 1)
            target = f if name == "labid_schema" else g
            numeric = name in ("rate_hz", "samples", "pretrigger")
            target.attrs[name] = json.loads(value) if numeric else value   # JSON attrs stay text
    return dst


ATTR_DAMAGE = ["labid_schema=one", "rate_hz=0", "rate_hz=-1", "samples=0", "pretrigger=-5",
               "channels={bad", "channels=[]", "trigger=[1, 2]", "channels=[{\"name\": 3}]",
               "samples=99999999999"]


# ------------------------------------------------------------------ results stored in a run (issue 27)
def with_results(base: Path, dst: Path, name: str, doc) -> Path:
    """A copy of the run ``base`` whose ``/results/<name>`` holds ``doc`` as its JSON copy
    (what ``write_result`` stores and readers prefer)."""
    shutil.copyfile(base, dst)
    with h5py.File(dst, "a") as f:
        if f"results/{name}" in f:
            del f[f"results/{name}"]
        f["results"].create_group(name)["json"] = json.dumps(doc, allow_nan=True, default=str)
    return dst


# ------------------------------------------------------------------ recordings (labid import)
def recording_bases(d: Path) -> dict[str, Path]:
    """Valid recordings of the default rig's force and acc1 channels, one per format."""
    import scipy.io
    from scipy.io import wavfile
    n = 256
    t = np.arange(n) / 1e4
    force, acc = np.sin(t * 900.0), np.cos(t * 1300.0)
    out = {}
    p = d / "base.csv"
    p.write_text("time,force [N],acc1 [m/s^2]\n" + "\n".join(f"{t[i]:.6g},{force[i]:.6g},{acc[i]:.6g}"
                                                              for i in range(n)) + "\n")
    out["csv"] = p
    p = d / "base.wav"
    wavfile.write(p, 10000, (np.column_stack([force, acc]) * 0.5).astype(np.float32))
    out["wav"] = p
    p = d / "base.mat"
    scipy.io.savemat(p, {"force": force, "acc1": acc, "fs": 1e4})
    out["mat"] = p
    from nptdms import ChannelObject, TdmsWriter
    p = d / "base.tdms"
    with TdmsWriter(p) as w:
        w.write_segment([ChannelObject("g", c, x, properties={"wf_increment": 1e-4, "unit_string": u})
                         for c, x, u in (("force", force, "N"), ("acc1", acc, "m/s^2"))])
    out["tdms"] = p
    import pyuff
    p = d / "base.uff"
    sets = [pyuff.prepare_58(binary=0, id1=c, func_type=1, rsp_node=k + 1, rsp_dir=3, ref_node=0, ref_dir=0,
                             data=x, x=t, abscissa_spacing=1, abscissa_spec_data_type=17,
                             abscissa_axis_units_lab="s", ordinate_spec_data_type=12 if k else 13,
                             ordinate_axis_units_lab=u, orddenom_spec_data_type=0, z_axis_spec_data_type=0)
            for k, (c, x, u) in enumerate((("force", force, "N"), ("acc1", acc, "m/s^2")))]
    pyuff.UFF(str(p)).write_sets(sets, mode="add")
    out["uff"] = p
    return out


@st.composite
def damaged_bytes(draw, data: bytes) -> bytes:
    """``data`` with bytes flipped, a slice cut out or replaced, or truncated."""
    how = draw(st.sampled_from(("flip", "flip", "truncate", "splice", "extend")))
    b = bytearray(data)
    if how == "flip":
        for _ in range(draw(st.integers(1, 30))):
            i = draw(st.integers(0, len(b) - 1))
            b[i] ^= draw(st.integers(1, 255))
    elif how == "truncate":
        b = b[:draw(st.integers(0, len(b)))]
    elif how == "splice":
        i = draw(st.integers(0, len(b)))
        j = draw(st.integers(i, min(len(b), i + 200)))
        b[i:j] = draw(st.binary(max_size=64))
    else:
        b += draw(st.binary(max_size=64))
    return bytes(b)


# ------------------------------------------------------------------ deep documents
@st.composite
def nested_text(draw, kind: str) -> str:
    """A features JSON or a specimen/rig TOML with a value nested 1 to 100,000 deep."""
    depth = draw(st.sampled_from((1, 10, 31, 33, 100, 1000, 20_000, 100_000)))
    open_, close = draw(st.sampled_from((("[", "]"), ("{\"a\": ", "}") if kind == "json" else ("{a = ", "}"))))
    inner = open_ * depth + ("1" if "a" in open_ else "") + close * depth
    if kind == "json":
        return '{"specimen": "aluminium", "modal": {"frequencies_hz": [20.0, 30.0]}, "analysis": {"x": ' + inner + "}}"
    return toml_text(base_specimen()) + f"extra = {inner}\n"


# ------------------------------------------------------------------ options of every command
OPTION_VALUES = ("0", "-1", "1", "2", "3", "1e9", "1e12", "1000000000000", "-1e300", "nan", "inf", "-inf", "",
                 " ", "x", "1,2", "1e9,1e9", "0,0", "-5,5", "2,5", "20,20", "21,1", "E=1", "E1=136.7",
                 "E=nan", "=", ",,", "\0", "0x10", "1_000", "٣", "9" * 400, "x" * 300)
#: (command, its other arguments, the options whose values are fuzzed); placeholders: RUN, FEATS,
#: OUT, CSV, DIR filled in by the caller
OPTION_TARGETS = (
    ("modes", ["aluminium", "--mesh", "2x2"], ["--n", "--mesh", "--grid", "--threads"]),
    ("dispersion", ["aluminium", "--n", "4"], ["--fmax", "--n", "--direction-deg"]),
    ("acquire", ["--specimen", "aluminium", "--out", "OUT", "--hits", "0", "--waves", "0"],
     ["--hits", "--waves", "--seed", "--effects", "--backend"]),
    ("import", ["CSV", "--rig", "default", "--specimen", "cfrp", "--out", "OUT"],
     ["--rate", "--pretrigger", "--map", "--units", "--kind"]),
    ("analyze", ["RUN", "--out", "FEATSOUT"], ["--wavelet", "--wave-band", "--modal-fmax", "--exp-window"]),
    ("identify", ["FEATS", "--params", "E"], ["--workers", "--starts", "--mcmc", "--seed", "--prior", "--start",
                                              "--params", "--method"]),
    ("diagnose", ["FEATS", "--params", "E"], ["--alpha", "--prior", "--start", "--params"]),
    ("report", ["RUN", "--out", "DIR/r.html"], ["--out"]),
    ("export", ["RUN", "--csv", "DIR/csv"], ["--uff", "--csv"]),
    ("demo", ["--out", "DIR/demo"], ["--hits", "--waves", "--seed"]),
)
@st.composite
def option_cases(draw) -> tuple[str, list[str], str, str]:
    """(command, argv with one option set to a hostile value, the option, the value)."""
    cmd, base, options = draw(st.sampled_from(OPTION_TARGETS))
    opt = draw(st.sampled_from(options))
    value = draw(st.one_of(st.sampled_from(OPTION_VALUES), st.text(max_size=8)))
    if cmd == "demo":                              # only values refused before the demo runs
        value = draw(st.sampled_from(("-1", "1e9", "x", "", "1000000000000", "nan", "2.5")))
    argv = [cmd, *base]
    if opt in argv:
        i = argv.index(opt)
        argv[i + 1] = value
    else:
        argv += [opt, value]
    return cmd, argv, opt, value
