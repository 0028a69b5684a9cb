"""A TOML text editor that shows a validation message next to the line at fault."""
from __future__ import annotations

import re

from PySide6.QtGui import QColor, QFont, QTextCursor, QTextFormat
from PySide6.QtWidgets import QLabel, QPlainTextEdit, QTextEdit


def key_line(text: str, key: str | None) -> int | None:
    """0-based line of ``text`` defining the dotted ``key`` (best effort), or None.

    'materials.T300.E2' -> the ``E2 =`` line after ``[materials.T300]``;
    'devices.vib' -> the ``[devices.vib]`` header; 'plies[2].angle_deg' -> the
    third ``[[plies]]`` table's ``angle_deg`` line.
    """
    if not key:
        return None
    lines = text.splitlines()
    parts = [p for p in re.split(r"\.(?![^\[]*\])", key) if p]
    # the table part: longest prefix that appears as a header
    header_re = re.compile(r"^\s*\[\[?\s*([^\]]+?)\s*\]\]?")
    headers = [(i, m.group(1)) for i, ln in enumerate(lines) if (m := header_re.match(ln))]

    def index_of(name: str) -> tuple[str, int | None]:
        m = re.match(r"(.*)\[(\d+)\]$", name)
        return (m.group(1), int(m.group(2))) if m else (name, None)

    start, end = 0, len(lines)
    used = 0
    for n in range(len(parts), 0, -1):
        name, idx = index_of(".".join(parts[:n]))
        hits = [i for i, h in headers if h == name]
        if hits:
            i = hits[idx] if idx is not None and idx < len(hits) else hits[0]
            start = i
            later = [j for j, _ in headers if j > i]
            end = later[0] if later else len(lines)
            used = n
            break
    rest = parts[used:]
    if not rest:
        return start if used else None
    leaf = index_of(rest[-1])[0]
    pat = re.compile(rf"^\s*{re.escape(leaf)}\s*=|[{{,]\s*{re.escape(leaf)}\s*=")
    for i in range(start, end):
        if pat.search(lines[i]):
            return i
    # an inline table 'parent = { ... }' or the table header itself
    if len(rest) > 1:
        parent = index_of(rest[0])[0]
        for i in range(start, end):
            if re.match(rf"^\s*{re.escape(parent)}\s*=", lines[i]):
                return i
    return start if used else None


class TomlEditor(QPlainTextEdit):
    """Plain-text TOML editor; ``show_error(message, key)`` marks the line at fault
    and places the message right of it (a red label inside the editor)."""

    def __init__(self, parent=None):
        super().__init__(parent)
        f = QFont("monospace")
        f.setStyleHint(QFont.TypeWriter)
        f.setPointSize(9)
        self.setFont(f)
        self.setLineWrapMode(QPlainTextEdit.NoWrap)
        self.error_label = QLabel(self.viewport())
        self.error_label.setStyleSheet(
            "QLabel { background: #fde2e2; color: #a00000; border: 1px solid #d08080;"
            " padding: 1px 4px; }")
        self.error_label.setWordWrap(True)
        self.error_label.hide()
        self.error_line: int | None = None
        self.textChanged.connect(self.clear_error)
        self.verticalScrollBar().valueChanged.connect(lambda _: self._place())

    def clear_error(self) -> None:
        if self.error_line is not None or self.error_label.isVisible():
            self.error_line = None
            self.error_label.hide()
            self.setExtraSelections([])

    def show_error(self, message: str, key: str | None) -> int | None:
        """Mark the line defining ``key`` (or the first line) and show ``message`` by it."""
        line = key_line(self.toPlainText(), key)
        self.show_error_at(0 if line is None else line, message)
        return line

    def show_error_at(self, line: int, message: str) -> None:
        """Mark 0-based ``line`` and show ``message`` right of it."""
        self.error_line = max(0, min(line, self.document().blockCount() - 1))
        block = self.document().findBlockByNumber(self.error_line)
        sel = QTextEdit.ExtraSelection()
        sel.format.setBackground(QColor("#ffd0d0"))
        sel.format.setProperty(QTextFormat.FullWidthSelection, True)
        cur = QTextCursor(block)
        sel.cursor = cur
        self.setExtraSelections([sel])
        self.blockSignals(True)
        self.setTextCursor(cur)
        self.blockSignals(False)
        self.centerCursor()
        self.error_label.setText(message)
        self.error_label.show()
        self._place()

    def _place(self) -> None:
        if self.error_line is None:
            return
        block = self.document().findBlockByNumber(self.error_line)
        geo = self.blockBoundingGeometry(block).translated(self.contentOffset())
        text_w = self.fontMetrics().horizontalAdvance(block.text()) + 24
        vw = self.viewport().width()
        x = min(text_w, max(0, vw - 260))
        self.error_label.setMaximumWidth(max(200, vw - x - 4))
        self.error_label.adjustSize()
        y = int(geo.top())
        if x + self.error_label.width() > vw:    # no room right of the line: below it
            x, y = 4, int(geo.bottom())
        self.error_label.move(int(x), y)
        self.error_label.raise_()

    def resizeEvent(self, e) -> None:  # noqa: N802
        super().resizeEvent(e)
        self._place()
