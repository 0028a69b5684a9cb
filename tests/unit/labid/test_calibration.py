"""Sensor calibration: the sheet the rig file names, TEDS through a fake nidaqmx layer (its
constants and error classes are the real package's), the calibration stored with every
shot, overdue calibrations warned about once per session."""
from __future__ import annotations

import datetime as dt
import types
from importlib import resources
from pathlib import Path

import nidaqmx.constants as C
import nidaqmx.errors as E
import pytest

from drivers.nidaq import read_teds
from labid import services
from labid.cli.main import main
from labid.base.errors import UserError
from labid.inputs import calibration as calib
from labid.inputs.rig import load_rig, rig_from_text
from labid.store import RunStore

G0 = 9.80665    # standard gravity, m/s^2 (definition)
DEFAULT_RIG = resources.files("labid.data").joinpath("rig_default.toml").read_text()
HEADER = "channel,serial,sensitivity,unit,calibration_date,due_date\n"
TODAY = dt.date.today()
PAST, FUTURE = (TODAY - dt.timedelta(days=30)).isoformat(), (TODAY + dt.timedelta(days=300)).isoformat()


def lab(tmp_path: Path, rows: str, rig_text: str = DEFAULT_RIG) -> Path:
    (tmp_path / "sheet.csv").write_text(HEADER + rows)
    rig = tmp_path / "rig.toml"
    rig.write_text('calibration = "sheet.csv"\n' + rig_text)
    return rig


def test_sheet_units_to_volts_per_si_unit():
    cal = calib.parse_sheet(HEADER + "acc1,SN1,10.2,mV/g,2025-01-01,2026-01-01\nforce,F1,2.25,mV/N,,\n"
                            "mfc1,M1,1,V/V,,\n", "s.csv", load_rig("default"))
    assert cal.entries["acc1"].sensitivity == pytest.approx(10.2e-3 / G0, rel=1e-15)
    assert cal.entries["force"].sensitivity == pytest.approx(2.25e-3, rel=1e-15)
    assert cal.entries["mfc1"].sensitivity == 1.0
    assert cal.entries["acc1"].due == dt.date(2026, 1, 1) and cal.entries["force"].due is None


@pytest.mark.parametrize("row, message", [
    ("accX,S,10,mV/g,,", r"s\.csv: line 2\.channel: value 'accX': not a channel of the rig"),
    ("force,S,10,mV/g,,", r"line 2\.unit: value 'mV/g': a sensitivity to acceleration for the force channel"),
    ("acc1,S,10,pC/g,,", r"line 2\.unit: value 'pC/g': expected a sensitivity unit such as mV/g"),
    ("acc1,S,-1,mV/g,,", r"line 2\.sensitivity: value '-1': expected a positive sensitivity"),
    ("acc1,S,10,mV/g,01/02/2025,", r"line 2\.calibration_date: value '01/02/2025': expected a date YYYY-MM-DD"),
    ("acc1,S,10,mV/g,2025-02-01,2024-02-01", r"line 2\.due_date: due date 2024-02-01 before the calibration date"),
])
def test_sheet_mistakes_are_one_line(row, message):
    import re
    with pytest.raises(UserError) as e:
        calib.parse_sheet(HEADER + row + "\n", "s.csv", load_rig("default"))
    assert re.search(message, str(e.value)) and "\n" not in str(e.value)


def test_missing_column_and_bad_reference():
    with pytest.raises(UserError, match=r"s\.csv: header: missing column\(s\) \['due_date'\]; expected the header"):
        calib.parse_sheet("channel,serial,sensitivity,unit,calibration_date\n", "s.csv")
    with pytest.raises(UserError, match=r"r\.toml: calibration: value 3: expected the path of a calibration sheet"):
        rig_from_text("calibration = 3\n" + DEFAULT_RIG, "r.toml")


def test_sheet_is_found_beside_the_rig_file_and_overrides(tmp_path):
    rig = load_rig(lab(tmp_path, f"acc2,SN2,9.8,mV/g,2025-01-01,{FUTURE}\n"))
    assert rig.calibration == "sheet.csv"
    cal_rig, cal = calib.calibrate(rig)
    assert cal.sheet == str(tmp_path / "sheet.csv")
    acc2 = cal_rig.device("hammer").channel("acc2")
    assert acc2.sensitivity == pytest.approx(9.8e-3 / G0, rel=1e-15)
    assert cal_rig.device("hammer").channel("acc1").sensitivity == rig.device("hammer").channel("acc1").sensitivity
    assert any("acc2: sensitivity" in n and "calibration sheet" in n for n in cal.notes)


def test_acquired_shots_carry_the_calibration_and_overdue_is_warned_once(tmp_path, capsys):
    rig = lab(tmp_path, f"acc1,SN1,10.2,mV/g,2024-01-01,{PAST}\nforce,F9,2.3,mV/N,2025-01-01,{FUTURE}\n")
    run = tmp_path / "run.h5"
    assert main(["acquire", "--rig", str(rig), "--specimen", "cfrp", "--out", str(run), "--hits", "1",
                 "--waves", "0"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: calibration of acc1 (serial SN1) was due on") == 1
    assert "force: sensitivity 0.0023 from the calibration sheet (serial F9" in err
    rec = services.shots(run, "hammer")[0]
    assert rec.channel("acc1").sensitivity == pytest.approx(10.2e-3 / G0, rel=1e-15)
    assert rec.channel("force").sensitivity == pytest.approx(2.3e-3, rel=1e-15)
    stored = services.run_calibration(run)
    assert stored["sheet_csv"] == (tmp_path / "sheet.csv").read_text()
    assert stored["channels"]["acc1"] == {"serial": "SN1", "sensitivity": pytest.approx(10.2e-3 / G0),
                                          "calibration_date": "2024-01-01", "due_date": PAST, "source": "sheet"}
    assert stored["overdue"] == [f"acc1 (serial SN1) was recorded after its calibration due date {PAST}"]
    with RunStore(run, "r") as st:
        assert st.config_text("calibration_csv").startswith(HEADER)
    from labid.report.certificate import build_report
    html = build_report(run)       # the report states the calibration and, first, the overdue channel
    assert f"Calibration overdue:</b> acc1 (serial SN1) was recorded after its calibration due date {PAST}" in html
    assert "F9" in html and "2025-01-01" in html
    # the same session (process): the panel or the next command does not warn again
    status = services.calibration_status(str(rig))
    assert status["overdue"] and services.warn_calibration(status, write=lambda s: None) == []


def test_imported_shots_carry_the_calibration(tmp_path):
    import numpy as np
    rig = lab(tmp_path, f"force,F9,2.3,mV/N,2025-01-01,{FUTURE}\n")
    path = tmp_path / "f.csv"
    path.write_text("force_N\n" + "\n".join(["1.0"] * 300) + "\n")   # longer than the rig's pre-trigger
    res = services.import_records([path], str(rig), "cfrp", tmp_path / "run.h5", "force_N=force", rate_hz=1e4)
    rec = services.shots(tmp_path / "run.h5", "hammer")[0]
    np.testing.assert_allclose(rec.data["force"], 2.3e-3, rtol=1e-15)    # 1 N x 2.3 mV/N at the input
    assert rec.meta["calibration"]["channels"]["force"][0] == "F9"
    assert res["calibration"]["entries"][0]["serial"] == "F9"


# ------------------------------------------------------------------ TEDS through nidaqmx
class FakePhysical:
    def __init__(self, nx, name):
        self.nx, self.name = nx, name

    def configure_teds(self, file_path=None):
        self.nx.log.append(("configure_teds", self.name))
        if self.name not in self.nx.sensors:
            raise E.DaqError("No TEDS sensor detected", -200709)

    def __getattr__(self, key):
        return self.nx.sensors[self.name][key]


class FakeTedsTask:
    def __init__(self, nx):
        self.nx = nx
        self.ai_channels = self

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.nx.log.append(("close",))

    def add_teds_ai_accel_chan(self, physical, units=None):
        self.nx.log.append(("add_teds_ai_accel_chan", physical, units))
        s = self.nx.sensors[physical]
        return types.SimpleNamespace(ai_accel_sensitivity=s["mv"], ai_accel_sensitivity_units=s["units"])

    def add_teds_ai_force_iepe_chan(self, physical, units=None):
        self.nx.log.append(("add_teds_ai_force_iepe_chan", physical, units))
        s = self.nx.sensors[physical]
        return types.SimpleNamespace(ai_force_iepe_sensor_sensitivity=s["mv"],
                                     ai_force_iepe_sensor_sensitivity_units=s["units"])


class FakeNidaqmx:
    """The part of ``nidaqmx`` TEDS reading uses: system.PhysicalChannel, Task, constants, errors."""

    def __init__(self, sensors):
        self.sensors, self.log = sensors, []
        self.constants, self.errors = C, E
        self.system = types.SimpleNamespace(PhysicalChannel=lambda name: FakePhysical(self, name))
        self.Task = lambda name="": FakeTedsTask(self)


def sensor(serial, mv, units):
    return dict(teds_mfg_id=43, teds_model_num=1234, teds_serial_num=serial, teds_version_num=1,
                teds_version_letter="A", mv=mv, units=units)


def test_read_teds_sensitivities_in_si():
    nx = FakeNidaqmx({"cDAQ1Mod1/ai1": sensor(555, 10.2, C.AccelSensitivityUnits.MILLIVOLTS_PER_G),
                      "cDAQ1Mod1/ai0": sensor(77, 10.0, C.ForceIEPESensorSensitivityUnits.MILLIVOLTS_PER_POUND)})
    acc = read_teds("cDAQ1Mod1/ai1", "accelerometer", nidaqmx_module=nx)
    assert (acc.serial, acc.model, acc.version) == (555, 1234, "1A")
    assert acc.sensitivity == pytest.approx(10.2e-3 / G0, rel=1e-15)
    assert ("add_teds_ai_accel_chan", "cDAQ1Mod1/ai1", C.AccelUnits.METERS_PER_SECOND_SQUARED) in nx.log
    force = read_teds("cDAQ1Mod1/ai0", "force", nidaqmx_module=nx)
    assert force.sensitivity == pytest.approx(10.0e-3 / 4.4482216152605, rel=1e-15)   # 10 mV/lbf in V/N
    assert read_teds("cDAQ1Mod1/ai3", "accelerometer", nidaqmx_module=nx) is None      # no TEDS sensor


def test_teds_fills_what_the_sheet_lacks_and_a_swapped_sensor_is_reported(tmp_path):
    nx = FakeNidaqmx({"cDAQ1Mod1/ai1": sensor(555, 10.2, C.AccelSensitivityUnits.MILLIVOLTS_PER_G),
                      "cDAQ1Mod1/ai2": sensor(999, 10.0, C.AccelSensitivityUnits.MILLIVOLTS_PER_G),
                      "cDAQ1Mod1/ai3": sensor(31, 10.0, C.AccelSensitivityUnits.MILLIVOLTS_PER_G)})
    rig = load_rig(lab(tmp_path, f"acc2,SN2,9.9,mV/g,2025-01-01,{FUTURE}\nacc3,31,5.0,mV/g,2025-01-01,{FUTURE}\n"))
    cal_rig, cal = calib.calibrate(rig, calib.nidaq_teds(nx))
    dev = cal_rig.device("hammer")
    assert dev.channel("acc1").sensitivity == pytest.approx(10.2e-3 / G0, rel=1e-15)   # TEDS
    assert dev.channel("acc2").sensitivity == pytest.approx(9.9e-3 / G0, rel=1e-15)    # the sheet wins
    assert dev.channel("acc3").sensitivity == pytest.approx(5.0e-3 / G0, rel=1e-15)
    assert cal.entries["acc1"].source == "teds" and cal.entries["acc2"].source == "sheet"
    assert any("acc2: TEDS serial 999 but the calibration sheet says 'SN2'" in n for n in cal.notes)
    assert not any("acc2: TEDS sensitivity" in n for n in cal.notes)      # 10.0 vs 9.9 mV/g: within 2 %
    assert any("acc3: TEDS sensitivity" in n and "the sheet's is used" in n for n in cal.notes)
    assert not any("acc3: TEDS serial" in n for n in cal.notes)


def test_panel_says_an_overdue_calibration_when_a_run_opens(tmp_path, qtbot):
    from labid.gui.main_window import MainWindow

    rig = lab(tmp_path, f"acc1,SN7,10.2,mV/g,2024-01-01,{PAST}\nforce,F7,2.3,mV/N,2025-01-01,{FUTURE}\n")
    run = tmp_path / "run.h5"
    assert main(["acquire", "--rig", str(rig), "--specimen", "cfrp", "--out", str(run), "--hits", "1",
                 "--waves", "0", "--quiet"]) == 0
    w = MainWindow()
    qtbot.addWidget(w)
    assert w.open_run(str(run))
    text, error = w.messages[-1]
    assert error and "calibration overdue: acc1 (serial SN7)" in text and PAST in text
