"""The Setup tab's test plan (issue 25): ``labid plan`` on the specimen and rig in the editors.

*Plan the test* runs ``services.plan_test`` in a worker (the wanted constants and the target
from the two fields); the plan opens in its own window: the console summary and the figure
(plate, recommended accelerometers and tap, nodal lines of the key modes, wave source and
sensors; predicted stds against the user's rig). *Use this layout* puts the recommended rig
text into the rig editor (validated there, unsaved until saved).
"""
from __future__ import annotations

from PySide6.QtGui import QFont, QPixmap
from PySide6.QtWidgets import (QDialog, QFormLayout, QGroupBox, QHBoxLayout, QLabel, QLineEdit, QPlainTextEdit,
                               QPushButton, QScrollArea, QVBoxLayout)

from .. import services
from ..base.errors import UserError

__all__ = ["PlanBox", "PlanDialog"]


class PlanDialog(QDialog):
    """One plan: its summary text and figure; *Use this layout* loads its rig text into the editor."""

    def __init__(self, result, on_use, parent=None):
        super().__init__(parent)
        self.result = result
        self.setWindowTitle(f"Test plan: {result.doc['specimen']}")
        self.text = QPlainTextEdit(result.text())
        self.text.setReadOnly(True)
        font = QFont("Monospace")
        font.setStyleHint(QFont.TypeWriter)
        self.text.setFont(font)
        self.figure = QLabel()
        pix = QPixmap()
        pix.loadFromData(result.figure_png())
        self.figure.setPixmap(pix)
        scroll = QScrollArea()
        scroll.setWidget(self.figure)
        self.use_btn = QPushButton("Use this layout in the rig editor")
        close = QPushButton("Close")
        self.use_btn.clicked.connect(lambda: on_use(self))
        close.clicked.connect(self.accept)
        buttons = QHBoxLayout()
        buttons.addStretch(1)
        buttons.addWidget(self.use_btn)
        buttons.addWidget(close)
        lay = QVBoxLayout(self)
        lay.addWidget(scroll, 3)
        lay.addWidget(self.text, 2)
        lay.addLayout(buttons)
        self.resize(1150, 760)


class PlanBox(QGroupBox):
    """Plan the test of the specimen and rig of the Setup tab's editors."""

    def __init__(self, setup, parent=None):
        super().__init__("Test plan (labid plan)", parent)
        self.setup = setup
        self.want_edit = QLineEdit()
        self.want_edit.setPlaceholderText("all constants, e.g. E1,E2,G12")
        self.target_edit = QLineEdit("2%")
        self.plan_btn = QPushButton("Plan the test…")
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.status.setMinimumHeight(3 * self.status.fontMetrics().height() + 6)
        self.dialog: PlanDialog | None = None
        self.result = None
        lay = QFormLayout(self)
        lay.addRow("wanted constants", self.want_edit)
        lay.addRow("target u", self.target_edit)
        lay.addRow(self.plan_btn)
        lay.addRow(self.status)
        self.plan_btn.clicked.connect(self.run_plan)

    def run_plan(self) -> None:
        spec, rig = self.setup.specimen(), self.setup.rig()
        if spec is None or rig is None:
            self.status.setText("fix the specimen/rig files first")
            return
        want = self.want_edit.text().strip() or None
        target = self.target_edit.text().strip() or "2%"

        def work(progress, should_stop):
            return services.plan_test(spec, rig, progress=progress, should_stop=should_stop,
                                      want=want, target_u=target)

        self.status.setText("planning…")
        self.setup.main.start_job("test plan", work, self._done, on_progress=self._progress,
                                  on_failed=self._failed)

    def _progress(self, msg) -> None:
        self.status.setText(str(msg))

    def _failed(self, msg: str) -> None:
        self.status.setText(msg)

    def _done(self, result) -> None:
        self.result = result
        rec = result.doc["recommended"]
        self.status.setText(f"worst wanted std {100 * rec['worst_std_rel']:.3g} % "
                            f"({result.doc['improvement_worst_std']:.2f}x better than the rig in the editor)")
        self.dialog = PlanDialog(result, self._use, self)
        self.dialog.show()

    def _use(self, dialog: PlanDialog) -> None:
        try:
            text = dialog.result.rig_text()
        except UserError as e:
            self.setup.main.message(str(e), error=True)
            return
        box = self.setup.rig_box
        box.editor.setPlainText(text)
        box.validate()
        self.setup.main.message("rig editor: the planned layout (not saved yet)")
