"""The GUM uncertainty budget of an identification (``uncertainty_budget``, as ``labid
identify`` prints it and the report shows it): a table with one row per source (the fit's
type A, each type-B input of the specimen's ``[uncertainty]``) giving the standard
uncertainty it contributes to each constant (its share of u_c² in the tooltip), then the
combined u_c and the expanded U = k u_c (k = 2), one column per constant; values in the
constant's prefix (``labid.base.summary.constant_cells``).
"""
from __future__ import annotations

import math

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHeaderView, QLabel, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget

from ..base.summary import constant_cells


def _num(v, default: float = math.nan) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return default


class BudgetView(QWidget):
    """A note line and the budget table."""

    def __init__(self, parent=None):
        super().__init__(parent)
        lay = QVBoxLayout(self)
        self.label = QLabel("")
        self.label.setWordWrap(True)
        self.table = QTableWidget(0, 1)
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(self.table.fontMetrics().height() + 6)
        lay.addWidget(self.label)
        lay.addWidget(self.table, 1)

    def show_budget(self, budget, names: list[str], error: str | None = None) -> None:
        """The GUM budget of a result (``uncertainty_budget``): a row per source with the
        standard uncertainty it contributes to each constant, then u_c and U = k u_c."""
        consts = budget.get("constants") if isinstance(budget, dict) else None
        consts = consts if isinstance(consts, dict) else {}
        names = [n for n in names if isinstance(consts.get(n), dict)]
        if not names:
            self.table.setRowCount(0)
            self.table.setColumnCount(1)
            self.table.setHorizontalHeaderLabels(["source"])
            self.table.setVisible(False)
            self.label.setText(f"not computed: {error}" if error else
                                      "no GUM budget in this result (press Identify, or run labid identify)")
            return
        k = _num(budget.get("coverage_factor"), 2.0)
        sources = list(dict.fromkeys(s for n in names for s in (consts[n].get("contributions") or {})))
        self.table.setVisible(True)
        self.table.setColumnCount(1 + len(names))
        self.table.setHorizontalHeaderLabels(["source"] + names)
        self.table.setRowCount(len(sources) + 2)
        inputs = {x.get("name"): x for x in budget.get("inputs") or [] if isinstance(x, dict)}

        def put(i, j, text, tip=""):
            item = QTableWidgetItem(text)
            item.setFlags(item.flags() & ~Qt.ItemIsEditable)
            if j:
                item.setTextAlignment(Qt.AlignRight | Qt.AlignVCenter)
            if tip:
                item.setToolTip(tip)
            if i >= len(sources):
                f = item.font()
                f.setBold(True)
                item.setFont(f)
            self.table.setItem(i, j, item)

        for i, src in enumerate(sources):
            x = inputs.get(src) or {}
            label = src + (" (default)" if x.get("source") == "default" else "")
            tip = (f"standard uncertainty of the input: {_num(x.get('u')):.3g} {x.get('unit', '')}"
                   f" ({x.get('source', '')})" if x else "the fit's own (type A) standard uncertainty")
            put(i, 0, label, tip)
            for j, n in enumerate(names, 1):
                c = (consts[n].get("contributions") or {}).get(src)
                if not isinstance(c, dict):
                    put(i, j, "—")
                    continue
                share = _num(c.get("share"))
                put(i, j, constant_cells(n, consts[n].get("value"), c.get("u"))[1],
                    f"{100 * share:.1f} % of u_c²" if math.isfinite(share) else "")
        r = len(sources)
        put(r, 0, "combined u_c")
        put(r + 1, 0, f"expanded U (k={k:g})")
        for j, n in enumerate(names, 1):
            c = consts[n]
            put(r, j, constant_cells(n, c.get("value"), c.get("u_combined"))[1],
                f"type A {constant_cells(n, c.get('value'), c.get('u_type_a'))[1]}, "
                f"type B {constant_cells(n, c.get('value'), c.get('u_type_b'))[1]}")
            rel = _num(c.get("U_rel"))
            put(r + 1, j, constant_cells(n, c.get("value"), c.get("U"))[1],
                f"{100 * rel:.2g} % of the value" if math.isfinite(rel) else "")
        notes = [str(x) for x in budget.get("notes") or []]
        self.label.setText(f"standard uncertainty contributed by each source (its share of u_c² in "
                                  f"the tooltip); U = k·u_c, k = {k:g}" + "".join(f"; {x}" for x in notes))
        self.label.setToolTip(f"coverage: {budget.get('coverage', '?')}; {budget.get('method', '')}")

