"""Setup tab: specimen and rig files (load, edit, validate, save), backend, serial instruments."""
from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path

from PySide6.QtCore import QTimer, Signal
from PySide6.QtWidgets import (QButtonGroup, QComboBox, QFileDialog, QFormLayout, QGridLayout,
                               QGroupBox, QHBoxLayout, QLabel, QLineEdit, QPushButton,
                               QRadioButton, QSpinBox, QVBoxLayout, QWidget)

from .. import services
from ..base import atomic
from ..base.errors import UserError
from ..inputs.rig import Rig, rig_from_text
from ..inputs.specimen import BUILTIN as SPECIMENS, Specimen, specimen_from_dict
from .plan_box import PlanBox
from .tomledit import TomlEditor

OK_STYLE = "color: #006000;"
ERR_STYLE = "color: #a00000; font-weight: bold;"


def _toml_error(e: tomllib.TOMLDecodeError, src: str) -> UserError:
    m = re.search(r"line (\d+)", str(e))
    err = UserError(f"malformed TOML ({e}); expected a TOML file", file=src)
    err.line = int(m.group(1)) - 1 if m else 0  # type: ignore[attr-defined]
    return err


def specimen_from_text(text: str, src: str) -> Specimen:
    """Parse and validate specimen TOML text (UserError naming file and key)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise _toml_error(e, src) from None
    return specimen_from_dict(doc, src)


class FileBox(QGroupBox):
    """One TOML file: source, editor, validate/save, message next to the field at fault."""

    validated = Signal(object)

    def __init__(self, title: str, builtins: dict[str, str], parse, parent=None):
        super().__init__(title, parent)
        self.builtins, self.parse = builtins, parse
        self.path: str | None = None          # file on disk, None for a built-in
        self.source = ""                      # label used in messages ('builtin:cfrp' or path)
        self.saved_text = ""
        self.combo = QComboBox()
        self.combo.addItems([f"built-in: {k}" for k in builtins] + ["file…"])
        self.open_btn = QPushButton("Open…")
        self.save_btn = QPushButton("Save")
        self.saveas_btn = QPushButton("Save as…")
        self.check_btn = QPushButton("Validate")
        self.editor = TomlEditor()
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.status.setMinimumHeight(3 * self.status.fontMetrics().height() + 6)
        top = QHBoxLayout()
        top.addWidget(self.combo, 1)
        for b in (self.open_btn, self.check_btn, self.save_btn, self.saveas_btn):
            top.addWidget(b)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addWidget(self.editor, 1)
        lay.addWidget(self.status)
        self.combo.activated.connect(self._choose)
        self.open_btn.clicked.connect(self._open_dialog)
        self.save_btn.clicked.connect(lambda: self.save())
        self.saveas_btn.clicked.connect(self._saveas_dialog)
        self.check_btn.clicked.connect(self.validate)
        self.editor.textChanged.connect(self._edited)

    # -- sources -----------------------------------------------------------
    def load_builtin(self, name: str) -> None:
        text = resources.files("labid.data").joinpath(self.builtins[name]).read_text()
        self.path, self.source = None, f"builtin:{name}"
        self.combo.setCurrentIndex(list(self.builtins).index(name))
        self._set_text(text)

    def load_file(self, path: str) -> bool:
        """Read ``path`` into the editor; a missing/unreadable file shows a message."""
        try:
            text = Path(path).read_text()
        except (OSError, UnicodeDecodeError) as e:
            self._message(f"{path}: cannot read ({getattr(e, 'strerror', None) or e})", False)
            return False
        self.path, self.source = str(path), str(path)
        self.combo.setCurrentIndex(self.combo.count() - 1)
        self._set_text(text)
        return True

    def load_text(self, text: str, source: str) -> None:
        """Text from elsewhere (a run file); saved only on request."""
        self.path = source if source and not source.startswith(("builtin:", "<")) else None
        self.source = source
        self._set_text(text)

    def _set_text(self, text: str) -> None:
        self.editor.setPlainText(text)
        self.saved_text = text
        self.validate()

    def _choose(self, i: int) -> None:
        if i < len(self.builtins):
            self.load_builtin(list(self.builtins)[i])
        else:
            self._open_dialog()

    def _open_dialog(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, f"Open {self.title()}", "", "TOML (*.toml);;All (*)")
        if p:
            self.load_file(p)

    def _saveas_dialog(self) -> None:
        p, _ = QFileDialog.getSaveFileName(self, f"Save {self.title()}", self.path or "", "TOML (*.toml)")
        if p:
            self.save(p)

    # -- state ---------------------------------------------------------------
    def text(self) -> str:
        return self.editor.toPlainText()

    def modified(self) -> bool:
        return self.text() != self.saved_text

    def _edited(self) -> None:
        self.status.setText("edited (not validated)" + (" · unsaved" if self.modified() else ""))
        self.status.setStyleSheet("")

    def _message(self, text: str, ok: bool) -> None:
        self.status.setText(text)
        self.status.setStyleSheet(OK_STYLE if ok else ERR_STYLE)

    def validate(self):
        """Parse the editor text; on error mark the field at fault. Returns the object or None."""
        src = self.path or self.source or "<editor>"
        try:
            obj = self.parse(self.text(), src)
        except UserError as e:
            line = getattr(e, "line", None)
            m = re.search(r"at line (\d+)", e.detail)
            if line is None and e.key is None and m:
                line = int(m.group(1)) - 1
            if line is not None:
                self.editor.show_error_at(line, e.detail)
            else:
                self.editor.show_error(e.detail, e.key)
            self._message(str(e), False)
            self.validated.emit(None)
            return None
        self.editor.clear_error()
        self._message(self.describe(obj) + (" · unsaved" if self.modified() else ""), True)
        self.validated.emit(obj)
        return obj

    def describe(self, obj) -> str:
        return f"valid: {getattr(obj, 'name', '')}"

    def save(self, path: str | None = None) -> bool:
        """Write the editor text to ``path`` (default: the file it came from)."""
        p = path or self.path
        if not p:
            self._saveas_dialog()
            return self.path is not None and not self.modified()
        try:
            atomic.write_text(p, self.text())          # temp + rename: never half a file (issue 27)
        except UserError as e:
            self._message(str(e), False)
            return False
        self.path, self.source, self.saved_text = str(p), str(p), self.text()
        self.combo.setCurrentIndex(self.combo.count() - 1)
        self.validate()
        return True


class SpecimenBox(FileBox):
    def __init__(self, parent=None):
        super().__init__("Specimen", SPECIMENS, specimen_from_text, parent)

    def describe(self, s: Specimen) -> str:
        lam = s.laminate
        return (f"valid: {s.name} · {s.length * 1e3:.0f} x {s.width * 1e3:.0f} mm, "
                f"{len(lam.plies)} plies, {lam.thickness * 1e3:.3g} mm, {s.mass * 1e3:.0f} g")


class RigBox(FileBox):
    def __init__(self, parent=None):
        super().__init__("Rig", {"default": "rig_default.toml"}, rig_from_text, parent)

    def describe(self, r: Rig) -> str:
        devs = ", ".join(f"{d.name} ({d.role}, {d.timing.rate_hz:g} Hz, {len(d.channels)} ch)"
                         for d in r.devices)
        return f"valid: {r.name} · {devs}"


class SetupView(QWidget):
    """Specimen + rig files, backend (mock / NI-DAQmx) and serial instruments."""

    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.specimen_box = SpecimenBox()
        self.rig_box = RigBox()
        # backend
        self.mock_radio = QRadioButton("simulated rig (mock)")
        self.ni_radio = QRadioButton("NI-DAQmx hardware")
        self.mock_radio.setChecked(True)
        grp = QButtonGroup(self)
        grp.addButton(self.mock_radio)
        grp.addButton(self.ni_radio)
        self.effects_edit = QLineEdit()
        self.effects_edit.setPlaceholderText("e.g. sensor_mass=0.003,temperature=10")
        self.seed_spin = QSpinBox()
        self.seed_spin.setRange(0, 2**31 - 1)
        self.backend_status = QLabel("")
        self.backend_status.setWordWrap(True)
        bk = QGroupBox("Backend")
        bl = QFormLayout(bk)
        row = QHBoxLayout()
        row.addWidget(self.mock_radio)
        row.addWidget(self.ni_radio)
        bl.addRow(row)
        bl.addRow("injected effects (mock)", self.effects_edit)
        bl.addRow("seed (mock)", self.seed_spin)
        bl.addRow(self.backend_status)
        # serial instruments
        self.env_port = QLineEdit()
        self.env_port.setPlaceholderText("/dev/ttyUSB0 (empty: none)")
        self.hammer_port = QLineEdit()
        self.hammer_port.setPlaceholderText("/dev/ttyUSB1 (empty: none)")
        self.connect_btn = QPushButton("Connect / refresh")
        self.env_status = QLabel("not connected")
        self.hammer_status = QLabel("not connected")
        for lab in (self.env_status, self.hammer_status):
            lab.setWordWrap(True)
        self.temperature_label = QLabel("— °C")
        self.temperature_label.setStyleSheet("font-size: 16pt; font-weight: bold;")
        self.temperature_c: float | None = None
        sr = QGroupBox("Serial instruments")
        sl = QGridLayout(sr)
        sl.addWidget(QLabel("environment probe"), 0, 0)
        sl.addWidget(self.env_port, 0, 1)
        sl.addWidget(self.env_status, 1, 0, 1, 2)
        sl.addWidget(QLabel("hammer unit"), 2, 0)
        sl.addWidget(self.hammer_port, 2, 1)
        sl.addWidget(self.hammer_status, 3, 0, 1, 2)
        sl.addWidget(self.connect_btn, 4, 0)
        sl.addWidget(self.temperature_label, 4, 1)
        self.poll = QTimer(self)
        self.poll.setInterval(5000)
        self.poll.timeout.connect(self.refresh_instruments)
        self.connect_btn.clicked.connect(self.refresh_instruments)
        self._polling = False

        self.plan_box = PlanBox(self)   # issue 25: labid plan on the editors' files
        right = QVBoxLayout()
        right.addWidget(bk)
        right.addWidget(sr)
        right.addWidget(self.plan_box)
        right.addStretch(1)
        lay = QHBoxLayout(self)
        lay.addWidget(self.specimen_box, 5)
        lay.addWidget(self.rig_box, 5)
        rw = QWidget()
        rw.setLayout(right)
        rw.setMaximumWidth(360)
        lay.addWidget(rw, 3)
        self.specimen_box.load_builtin("cfrp")
        self.rig_box.load_builtin("default")
        self.ni_radio.toggled.connect(lambda on: self.check_backend() if on else self._backend_message("", True))

    # -- what the other views need -------------------------------------------
    @property
    def backend(self) -> str:
        return "nidaqmx" if self.ni_radio.isChecked() else "mock"

    def set_backend(self, name: str) -> None:
        (self.ni_radio if name == "nidaqmx" else self.mock_radio).setChecked(True)

    def specimen(self) -> Specimen | None:
        return self.specimen_box.validate()

    def rig(self) -> Rig | None:
        return self.rig_box.validate()

    def effects(self):
        """Simulated-rig effects from the effects field (UserError on a bad value)."""
        text = self.effects_edit.text().strip()
        if not text:
            return None
        if self.backend != "mock":
            raise UserError("effects can only be injected into the simulated rig; choose the mock backend",
                            key="effects")
        return services.parse_effects(text, key="effects")

    # -- backend check ----------------------------------------------------------
    def _backend_message(self, text: str, ok: bool) -> None:
        self.backend_status.setText(text)
        self.backend_status.setStyleSheet(OK_STYLE if ok else ERR_STYLE)

    def check_backend(self) -> None:
        """Configure the rig's devices on NI-DAQmx (as an acquisition would), off the GUI
        thread, and say in the panel whether that works (missing driver, absent device...)."""
        rig, spec = self.rig(), self.specimen()
        if rig is None or spec is None:
            self._backend_message("fix the specimen/rig files first", False)
            return
        def work(progress, should_stop):
            return services.check_daq(rig, spec)

        def done(names):
            self._backend_message(f"NI-DAQmx: {', '.join(names)} configured", True)

        def failed(msg):
            self._backend_message(msg, False)
            self.main.message(msg, error=True)

        self._backend_message("checking NI-DAQmx…", True)
        self.main.start_job("NI-DAQmx check", work, done, on_failed=failed, exclusive=False)

    # -- serial instruments ---------------------------------------------------
    def refresh_instruments(self) -> None:
        """Query both instruments off the GUI thread; start polling the temperature."""
        if self._polling:
            return
        env, ham = self.env_port.text().strip(), self.hammer_port.text().strip()
        if not env and not ham:
            self.env_status.setText("no port given")
            self.poll.stop()
            return
        self._polling = True

        def work(progress, should_stop):
            return services.read_instruments(env, ham)

        self.main.start_job("serial instruments", work, self._instruments_done, exclusive=False,
                            on_failed=self._instruments_failed)

    def _instruments_failed(self, msg: str) -> None:
        self._polling = False
        self.env_status.setText(msg)
        self.env_status.setStyleSheet(ERR_STYLE)
        self.main.message(msg, error=True)

    def _instruments_done(self, out: dict) -> None:
        self._polling = False
        problems = []
        env = out.get("env")
        if env is not None:
            if env["ok"]:
                self.temperature_c = float(env["temperature_c"])
                self.env_status.setText(f"● {env['ident']} · humidity {env['humidity_pct']:.1f} %")
                self.env_status.setStyleSheet(OK_STYLE)
                self.temperature_label.setText(f"{self.temperature_c:.2f} °C")
            else:
                self.env_status.setText("● " + env["message"])
                self.env_status.setStyleSheet(ERR_STYLE)
                self.temperature_label.setText("— °C")
                problems.append(env["message"])
        ham = out.get("hammer")
        if ham is not None:
            if ham["ok"]:
                self.hammer_status.setText(f"● {ham['ident']} · {'ready' if ham['ready'] else 'recharging'}"
                                           f" · {ham['count']} hits · level {ham['level']} %")
                self.hammer_status.setStyleSheet(OK_STYLE)
            else:
                self.hammer_status.setText("● " + ham["message"])
                self.hammer_status.setStyleSheet(ERR_STYLE)
                problems.append(ham["message"])
        if problems:
            self.main.message(problems[0], error=True)
        if not self.poll.isActive():
            self.poll.start()

    # -- session state ------------------------------------------------------------
    def state(self) -> dict:
        return {"backend": self.backend, "effects": self.effects_edit.text(),
                "seed": int(self.seed_spin.value()), "env_port": self.env_port.text(),
                "hammer_port": self.hammer_port.text(),
                "specimen_source": self.specimen_box.source, "rig_source": self.rig_box.source,
                "temperature_c": float("nan") if self.temperature_c is None else self.temperature_c}

    def restore(self, st: dict, specimen_toml: str = "", rig_toml: str = "") -> None:
        if specimen_toml:
            self.specimen_box.load_text(specimen_toml, st.get("specimen_source", "<run file>"))
        if rig_toml:
            self.rig_box.load_text(rig_toml, st.get("rig_source", "<run file>"))
        self.set_backend(st.get("backend", "mock"))
        self.effects_edit.setText(st.get("effects", ""))
        self.seed_spin.setValue(int(st.get("seed", 0)))
        self.env_port.setText(st.get("env_port", ""))
        self.hammer_port.setText(st.get("hammer_port", ""))
