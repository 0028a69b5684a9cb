"""``labid gui [RUN.h5]``: the lab panel (PySide6 + pyqtgraph)."""
from __future__ import annotations

import gc

from .errors import UserError


def register(sub) -> None:
    p = sub.add_parser("gui", help="the lab panel", description=__doc__.splitlines()[0])
    p.add_argument("run", nargs="?", metavar="RUN.h5", help="run file to open (views restored)")
    p.set_defaults(func=run)


def run(args) -> None:
    # Qt is an optional dependency: it (and the panel built on it) is imported here, so that
    # a missing PySide6 is one clear line and no other command pays for it
    try:
        from PySide6.QtWidgets import QApplication
    except ImportError as e:
        raise UserError(f"PySide6 is not available ({e}); expected the Qt bindings to be installed") from None
    from .gui.main_window import MainWindow
    app = QApplication.instance() or QApplication(["labid"])
    win = MainWindow(args.run)
    win.show()
    app.exec()
    # tear the widgets down while the interpreter is intact (PySide6/pyqtgraph can
    # crash when the garbage collector meets them during finalisation)
    win.deleteLater()
    del win
    app.processEvents()
    gc.collect()
    return None
