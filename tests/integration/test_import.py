"""``labid import``: recordings written by the formats' own libraries (npTDMS TdmsWriter,
pyuff write_sets, scipy.io.wavfile.write, scipy.io.savemat, the csv module) into run files
that ``labid analyze`` reads as it reads acquired shots."""
from __future__ import annotations

import csv
import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import pyuff
from nptdms import ChannelObject, TdmsWriter
from scipy.io import savemat, wavfile

from labid import services
from labid.cli.main import main
from labid.base.errors import UserError
from labid.io.importers import import_records
from labid.io.readers import split_header
from labid.inputs.units import G0, parse_unit
from labid.store import RunStore

DEFAULT_RIG = resources.files("labid.data").joinpath("rig_default.toml").read_text()


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    """Three hammer hits on the simulated rig (default rig, CFRP plate)."""
    d = tmp_path_factory.mktemp("sim")
    run = d / "sim.h5"
    assert main(["acquire", "--specimen", "cfrp", "--out", str(run), "--hits", "3", "--waves", "0", "--quiet"]) == 0
    return run


def analysis_lines(run: Path, capsys) -> list[str]:
    """The picked peaks of ``labid analyze RUN`` to the precision it used to print
    (4 decimals in Hz, damping to 0.0001 %), from its features file."""
    capsys.readouterr()
    out = run.with_suffix(".json")
    assert main(["analyze", str(run), "--out", str(out)]) == 0
    m = json.loads(out.read_text()).get("modal") or {}
    return [f"peak {f:.4f} Hz {100 * z:.4f} %" for f, z in zip(m.get("frequencies_hz", []), m.get("damping_ratio", []))]


def rig_file(tmp_path: Path, text: str = DEFAULT_RIG, name: str = "rig.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


# -------------------------------------------------------------- the check: TDMS
def test_tdms_hammer_record_gives_the_peaks_of_the_simulated_shots(sim, tmp_path, capsys):
    """The samples of simulated shots, written by npTDMS in physical units (as DAQmx logs
    them: m/s^2, N, wf_increment, a negative wf_start_offset for the pre-trigger), imported
    and analysed, give the same resonance peaks to the last digit printed."""
    recs = services.shots(sim, "hammer")
    tdms = tmp_path / "hammer.tdms"
    with TdmsWriter(tdms) as w:
        for i, r in enumerate(recs):
            w.write_segment([ChannelObject(f"hit{i + 1}", c.name, r.scaled(c.name), properties={
                "wf_increment": 1.0 / r.timing.rate_hz, "wf_start_offset": -r.timing.pretrigger / r.timing.rate_hz,
                "unit_string": c.unit}) for c in r.channels])
    out = tmp_path / "imported.h5"
    assert main(["import", str(tdms), "--rig", "default", "--specimen", "cfrp", "--out", str(out),
                 "--map", "force=force,acc1=acc1,acc2=acc2,acc3=acc3"]) == 0
    got = services.shots(out, "hammer")
    assert len(got) == len(recs) == 3
    for a, b in zip(got, recs):
        assert a.timing == b.timing and [c.name for c in a.channels] == [c.name for c in b.channels]
        for c in b.channels:     # physical x sensitivity: the stored volts to the last bit or two
            np.testing.assert_allclose(a.data[c.name], b.data[c.name], rtol=4.5e-16, atol=0)
    expected = analysis_lines(sim, capsys)
    assert len(expected) > 10
    assert analysis_lines(out, capsys) == expected


# -------------------------------------------------------------- UFF58 by pyuff
def uff58(name: str, data: np.ndarray, rate: float, t0: float, unit: str, node: int = 1) -> dict:
    return pyuff.prepare_58(binary=1, id1=name, func_type=1, rsp_node=node, rsp_dir=3, ref_node=0, ref_dir=0,
                            data=data, x=t0 + np.arange(data.size) / rate, abscissa_spacing=1,
                            abscissa_spec_data_type=17, ordinate_spec_data_type=12, ordinate_axis_units_lab=unit,
                            orddenom_spec_data_type=0, z_axis_spec_data_type=0)


def test_uff58_written_by_pyuff_is_imported_with_its_rate_pretrigger_and_units(tmp_path):
    rng = np.random.default_rng(1)
    acc_g, force_n = rng.normal(size=(2, 1000)), 100 * rng.normal(size=(2, 1000))
    path = tmp_path / "hits.uff"
    sets = []
    for k in range(2):     # two hits: each channel twice -> two shots
        sets += [uff58("F", force_n[k], 10000.0, -0.02, "N", 1), uff58("A1", acc_g[k], 10000.0, -0.02, "g", 2)]
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    res = import_records([path], "default", "cfrp", tmp_path / "run.h5", "F=force,A1=acc1")
    assert res.kind == "hammer" and res.shots == ["hammer_0001", "hammer_0002"]
    assert (res.rate_hz, res.samples, res.pretrigger) == (10000.0, 1000, 200)   # -0.02 s at 10 kHz
    recs = services.shots(tmp_path / "run.h5", "hammer")
    s_acc, s_f = recs[0].channel("acc1").sensitivity, recs[0].channel("force").sensitivity
    for k in range(2):
        np.testing.assert_allclose(recs[k].data["acc1"], acc_g[k] * G0 * s_acc, rtol=1e-15)
        np.testing.assert_allclose(recs[k].data["force"], force_n[k] * s_f, rtol=1e-15)
        np.testing.assert_allclose(recs[k].scaled("acc1"), acc_g[k] * G0, rtol=1e-14)
    meta = recs[0].meta["imported"]
    assert meta["channels"] == {"force": "hits.uff:F", "acc1": "hits.uff:A1"}
    assert meta["units"] == {"force": "N", "acc1": "g"}


# -------------------------------------------------------------- WAV, MAT, CSV
def test_wav_samples_are_fractions_of_the_full_scale_given(tmp_path):
    x = np.array([[0, 16384], [-32768, 8192], [1000, -1000]] * 100, dtype=np.int16)
    path = tmp_path / "rec.wav"
    wavfile.write(path, 10000, x)
    res = import_records([path], "default", "cfrp", tmp_path / "run.h5", "1=force,2=acc1", units_text="force=2.5V,acc1=2.5V",
                         pretrigger=10)
    assert res.rate_hz == 10000.0 and res.pretrigger == 10 and res.samples == 300
    rec = services.shots(tmp_path / "run.h5", "hammer")[0]
    np.testing.assert_array_equal(rec.data["force"], x[:, 0] / 32768.0 * 2.5)    # volts at the input
    np.testing.assert_array_equal(rec.data["acc1"], x[:, 1] / 32768.0 * 2.5)


def test_wav_without_unit_is_refused_with_the_full_scale_hint(tmp_path):
    path = tmp_path / "rec.wav"
    wavfile.write(path, 10000, np.zeros(100, np.float32))
    with pytest.raises(UserError, match=r"rec\.wav: 1: no unit in the file; expected --units force=UNIT.*full scale"):
        import_records([path], "default", "cfrp", tmp_path / "run.h5", "1=force")


def test_mat_columns_and_rate_variable(tmp_path):
    rng = np.random.default_rng(2)
    m = rng.normal(size=(500, 2))
    path = tmp_path / "hit.mat"
    savemat(path, {"fs": 10000.0, "data": m})
    res = import_records([path], "default", "cfrp", tmp_path / "run.h5", "data/1=force,data/2=acc2",
                         units_text="force=N,acc2=m/s^2", pretrigger=0)
    assert (res.rate_hz, res.samples) == (10000.0, 500)
    rec = services.shots(tmp_path / "run.h5", "hammer")[0]
    np.testing.assert_allclose(rec.scaled("force"), m[:, 0], rtol=1e-15)
    np.testing.assert_allclose(rec.scaled("acc2"), m[:, 1], rtol=1e-15)


def write_csv(path: Path, header: list[str], cols: list[np.ndarray], comment: str = "") -> None:
    with path.open("w", newline="") as fh:
        if comment:
            fh.write(f"# {comment}\n")
        w = csv.writer(fh)
        w.writerow(header)
        for row in zip(*cols):
            w.writerow([repr(float(v)) for v in row])


def test_csv_time_column_gives_rate_and_pretrigger_header_gives_units(tmp_path):
    t = (np.arange(400) - 40) * 100.0          # us at 10 kHz, trigger at sample 40
    f, a = np.sin(t / 50.0), np.cos(t / 70.0)
    path = tmp_path / "hit.csv"
    write_csv(path, ["time_us", "force [N]", "acc (m/s^2)"], [t, f, a], comment="exported by a scope")
    res = import_records([path], "default", "cfrp", tmp_path / "run.h5", "force [N]=force,acc=acc3")
    assert (res.rate_hz, res.samples, res.pretrigger) == (10000.0, 400, 40)
    assert res.units == {"force": "N", "acc3": "m/s^2"}
    rec = services.shots(tmp_path / "run.h5", "hammer")[0]
    np.testing.assert_allclose(rec.scaled("acc3"), a, rtol=1e-15)


def test_several_files_on_a_common_trigger_make_one_shot_and_crop_aligns_them(tmp_path):
    """Two files, one channel each, both timed from the common trigger but starting at
    different times: refused as they are, aligned on the trigger with --crop."""
    rate = 10000.0
    sig = np.sin(np.arange(-300, 1000) / 7.0)             # one signal, sample k at time k / rate
    f1, f2 = tmp_path / "a.csv", tmp_path / "b.csv"
    write_csv(f1, ["t", "v"], [np.arange(-100, 900) / rate, sig[200:1200]])   # 100 samples before
    write_csv(f2, ["t", "v"], [np.arange(-300, 800) / rate, sig[0:1100]])      # 300 samples before
    args = ([f1, f2], "default", "cfrp", tmp_path / "run.h5", "a:v=force,b:v=acc1")
    with pytest.raises(UserError, match=r"b\.csv: v: 1100 samples with 300 before the trigger, but a\.csv: v has "
                                        r"1000 with 100.*--crop"):
        import_records(*args, units_text="force=N,acc1=m/s^2")
    res = import_records(*args, units_text="force=N,acc1=m/s^2", crop=True)
    assert res.shots == ["hammer_0001"] and (res.samples, res.pretrigger) == (900, 100)
    rec = services.shots(tmp_path / "run.h5", "hammer")[0]
    np.testing.assert_allclose(rec.scaled("acc1"), rec.scaled("force"), rtol=1e-15)   # same samples, same times
    np.testing.assert_allclose(rec.scaled("force"), sig[200:1100], rtol=1e-15)


def test_one_file_per_hit_makes_one_shot_each(tmp_path):
    files = []
    for k in range(3):
        p = tmp_path / f"hit{k}.csv"
        write_csv(p, ["force_N", "acc1_g"], [np.full(300, k + 1.0), np.full(300, -k - 1.0)])
        files.append(p)
    res = import_records(files, "default", "cfrp", tmp_path / "run.h5", "force_N=force,acc1_g=acc1", rate_hz=1e4)
    assert res.shots == ["hammer_0001", "hammer_0002", "hammer_0003"]
    recs = services.shots(tmp_path / "run.h5", "hammer")
    assert [float(r.scaled("force")[0]) for r in recs] == [1.0, 2.0, 3.0]
    assert [float(r.scaled("acc1")[0]) for r in recs] == pytest.approx([-G0, -2 * G0, -3 * G0], rel=1e-15)
    assert any("pre-trigger 200 samples from the rig file" in n for n in res.notes)


# -------------------------------------------------------------- mismatches: one line, exit 2
@pytest.fixture
def hit_csv(tmp_path) -> Path:
    p = tmp_path / "hit.csv"
    write_csv(p, ["time", "force_N", "acc_g"], [np.arange(100) / 10000.0, np.zeros(100), np.zeros(100)])
    return p


@pytest.mark.parametrize("argv, message", [
    (["--map", "force_N=force,acc_g=mfc1"], r"--map: the mapped channels belong to devices \['vib', 'waves'\]"),
    (["--map", "force_N=hammer"], r"--map force_N: value 'hammer': unknown rig channel; expected one of \['force'"),
    (["--map", "nope=force"], r"--map: value 'nope': no such channel in the files; expected one of acc_g, force_N"),
    (["--map", "acc_g=force"], r"hit\.csv: acc_g: unit 'g' measures acceleration but force is a force channel"),
    (["--map", "force_N=force", "--units", "force=kN"], r"unit 'N' in the file, 'kN' given for force"),
    (["--map", "force_N=force", "--rate", "48000"], r"hit\.csv: force_N: sample rate 10000 Hz in the file, 48000 Hz given"),
    (["--map", "force_N=force", "--kind", "wave"], r"--kind: value 'wave': the mapped channels are on device 'vib'"),
])
def test_mismatches_are_one_line_exit_2(hit_csv, tmp_path, capsys, argv, message):
    import re
    code = main(["import", str(hit_csv), "--rig", "default", "--specimen", "cfrp", "--out", str(tmp_path / "r.h5"),
                 *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert re.search(message, err), err
    assert not (tmp_path / "r.h5").exists()       # nothing written before the checks pass


def test_rate_other_than_the_rigs_is_refused(hit_csv, tmp_path):
    rig = rig_file(tmp_path, DEFAULT_RIG.replace("rate_hz = 10000.0", "rate_hz = 48000.0"))
    with pytest.raises(UserError, match=r"hit\.csv: force_N: sample rate 10000 Hz differs from the 48000 Hz of device "
                                        r"'vib'; expected the rig's rate"):
        import_records([hit_csv], str(rig), "cfrp", tmp_path / "r.h5", "force_N=force")


def test_rate_within_the_files_precision_is_the_rigs(tmp_path):
    """UFF58 keeps the increment to 6 digits: 1/48000 s -> 2.08333e-05 s (48000.08 Hz)."""
    text = DEFAULT_RIG.replace("rate_hz = 10000.0", "rate_hz = 48000.0")
    rig = rig_file(tmp_path, text)
    path = tmp_path / "h.uff"
    pyuff.UFF(str(path)).write_sets([uff58("F", np.ones(480), 48000.0, 0.0, "N")], mode="add")
    res = import_records([path], str(rig), "cfrp", tmp_path / "run.h5", "F=force", pretrigger=0)
    assert res.rate_hz == 48000.0


def test_units_and_headers():
    assert parse_unit("mV") == ("voltage", 1e-3) and parse_unit("2.5V") == ("voltage", 2.5)
    assert parse_unit("g") == ("acceleration", G0) and parse_unit("lbf") == ("force", 4.4482216152605)
    assert parse_unit("furlong") is None
    assert split_header("amplitude_mV") == ("amplitude", "mV") and split_header("time_us") == ("time", "us")
    assert split_header("force [kN]") == ("force", "kN") and split_header("my_channel") == ("my_channel", None)


def test_import_appends_to_a_run_of_the_same_rig_and_channels(sim, tmp_path):
    run = tmp_path / "run.h5"
    run.write_bytes(sim.read_bytes())
    one = tmp_path / "force.csv"
    write_csv(one, ["force_N"], [np.zeros(20000)])
    with pytest.raises(UserError, match="the hammer channels/timing differ from those already recorded"):
        import_records([one], "default", "cfrp", run, "force_N=force", pretrigger=200)
    four = tmp_path / "all.csv"
    write_csv(four, ["force_N", "a1", "a2", "a3"], [np.zeros(20000)] * 4)
    res = import_records([four], "default", "cfrp", run, "force_N=force,a1=acc1,a2=acc2,a3=acc3",
                         units_text="acc1=m/s^2,acc2=m/s^2,acc3=m/s^2", pretrigger=200)
    assert res.shots == ["hammer_0004"]
    with pytest.raises(UserError, match="differs from the specimen this file was recorded with"):
        import_records([four], "default", "aluminium", run, "force_N=force,a1=acc1,a2=acc2,a3=acc3",
                       units_text="acc1=m/s^2,acc2=m/s^2,acc3=m/s^2", pretrigger=200)
