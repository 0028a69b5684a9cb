"""Identification tab (placeholder until its back-end lands)."""
from __future__ import annotations

from PySide6.QtWidgets import QVBoxLayout, QWidget

from .common import Banner, backend


class IdentificationView(QWidget):
    def __init__(self, main, parent=None):
        super().__init__(parent)
        self.main = main
        self.banner = Banner()
        lay = QVBoxLayout(self)
        lay.addWidget(self.banner)
        lay.addStretch(1)
        self.reload()

    def reload(self) -> None:
        if backend("labid.identification") is None:
            self.banner.warn("not available yet: the labid.identification workflow has not landed in this build")

    def state(self) -> dict:
        return {}

    def restore(self, st: dict) -> None:
        pass
