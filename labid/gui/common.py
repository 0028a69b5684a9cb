"""Helpers shared by the views: the notice banner, plot style."""
from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtWidgets import QLabel

pg.setConfigOptions(antialias=True, foreground="k", background="w")


class Banner(QLabel):
    """A one-line notice at the top of a view (info, or warning in amber)."""

    def __init__(self, text: str = ""):
        super().__init__(text)
        self.setWordWrap(True)
        self.info(text)

    def info(self, text: str) -> None:
        self.setText(text)
        self.setStyleSheet("QLabel { background: #eef4fb; border: 1px solid #b8cce4; padding: 4px; }")
        self.setVisible(bool(text))

    def warn(self, text: str) -> None:
        self.setText(text)
        self.setStyleSheet("QLabel { background: #fff4d6; border: 1px solid #e0b040; padding: 4px;"
                           " color: #6a4a00; }")
        self.setVisible(bool(text))


def plot(title: str = "", x: tuple[str, str] = ("", ""), y: tuple[str, str] = ("", "")) -> pg.PlotWidget:
    w = pg.PlotWidget(title=title)
    w.setBackground("w")
    w.showGrid(x=True, y=True, alpha=0.3)
    if x[0]:
        w.setLabel("bottom", x[0], x[1])
    if y[0]:
        w.setLabel("left", y[0], y[1])
    w.getAxis("left").setWidth(62)
    w.getAxis("left").enableAutoSIPrefix(False)    # no 'x1e+09' on log axes
    return w


def empty_note(w: pg.PlotWidget, text: str) -> None:
    """A grey note in the middle of an empty plot (after ``clear()``)."""
    item = pg.TextItem(text, color="#777777", anchor=(0.5, 0.5))
    w.addItem(item)
    vb = w.getPlotItem().vb
    (x0, x1), (y0, y1) = vb.viewRange()
    item.setPos(0.5 * (x0 + x1), 0.5 * (y0 + y1))
