"""The Setup tab's test plan, driven through its widgets (pytest-qt, offscreen): the plan
opens with its summary and figure, and *Use this layout* puts the planned rig into the rig
editor. Screenshots go to tests/artifacts/ (gitignored)."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402

ART = Path(__file__).resolve().parents[3] / "artifacts"
#: a guard against a hung job, not a speed requirement (the wait ends on the job's signal)
BUDGET = 900_000


def test_plan_box_plans_and_loads_the_layout_into_the_rig_editor(main_window, qtbot):
    win = main_window
    setup = win.setup
    setup.specimen_box.load_builtin("aluminium")
    box = setup.plan_box
    box.want_edit.setText("E,G")
    box.target_edit.setText("1%")
    qtbot.mouseClick(box.plan_btn, Qt.LeftButton)
    job = win.job
    assert job is not None
    with qtbot.waitSignal(job.ended, timeout=BUDGET):
        pass
    qtbot.waitUntil(lambda: box.dialog is not None and box.dialog.isVisible(), timeout=BUDGET)
    dlg = box.dialog
    text = dlg.text.toPlainText()
    assert "VERDICT" in text and "recommended layout" in text
    assert not dlg.figure.pixmap().isNull()
    ART.mkdir(exist_ok=True)
    assert win.grab().save(str(ART / "setup_plan.png"))
    assert dlg.grab().save(str(ART / "plan_dialog.png"))
    rec = box.result.doc["recommended"]
    qtbot.mouseClick(dlg.use_btn, Qt.LeftButton)
    rig = tomllib.loads(setup.rig_box.editor.toPlainText())
    assert rig["hammer"]["x"] == pytest.approx(rec["hammer"]["x"], abs=1e-4)
    accs = [c for c in rig["devices"]["vib"]["channels"] if c.get("kind") == "accelerometer"]
    assert [(c["x"], c["y"]) for c in accs] == [pytest.approx((a["x"], a["y"]), abs=1e-4)
                                                 for a in rec["accelerometers"]]
    assert setup.rig() is not None and setup.rig_box.modified()
    dlg.close()
