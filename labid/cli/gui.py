"""``labid gui [RUN.h5]``: the lab panel (PySide6 + pyqtgraph)."""
from __future__ import annotations

import gc
import os
import signal
import sys

from ..base.errors import UserError

#: Qt platforms that need no display server
_HEADLESS = ("offscreen", "minimal", "vnc", "eglfs", "linuxfb")


def check_display(env=None, platform: str | None = None) -> None:
    """UserError in one line when the panel has no display to show on (Linux/BSD: neither
    DISPLAY nor WAYLAND_DISPLAY set and no headless QT_QPA_PLATFORM), with the offscreen hint."""
    env = os.environ if env is None else env
    platform = sys.platform if platform is None else platform
    if platform.startswith(("win", "darwin", "cygwin")):
        return
    qpa = env.get("QT_QPA_PLATFORM", "").split(":")[0]
    if qpa in _HEADLESS or env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return
    raise UserError("no display (DISPLAY and WAYLAND_DISPLAY are unset); expected a desktop session, "
                    "or QT_QPA_PLATFORM=offscreen for a headless check")


def register(sub) -> None:
    p = sub.add_parser("gui", help="the lab panel", description=__doc__.splitlines()[0])
    p.add_argument("run", nargs="?", metavar="RUN.h5", help="run file to open (views restored)")
    p.set_defaults(func=run)


def run(args) -> None:
    check_display()
    # Qt is an optional dependency: it (and the panel built on it) is imported here, so that
    # a missing PySide6 is one clear line and no other command pays for it
    try:
        from PySide6.QtWidgets import QApplication
    except ImportError as e:
        raise UserError(f"PySide6 is not available ({e}); expected the Qt bindings to be installed") from None
    from ..gui.main_window import MainWindow
    from ..gui.signals import CloseOnSignals
    app = QApplication.instance() or QApplication(["labid"])
    win = MainWindow()
    win.show()
    win.run_opened.connect(lambda path: (sys.stderr.write(f"labid gui: opened {path}\n"), sys.stderr.flush()))
    if args.run:            # read in a worker thread, with progress (issue 26)
        win.open_run(args.run, background=True)
    signals = CloseOnSignals(app, win)      # Ctrl-C and SIGTERM close the window cleanly
    app.exec()
    signals.restore()
    if signals.received() is not None:
        sys.stderr.write(f"labid gui: closed on {signal.Signals(signals.received()).name}\n")
    # tear the widgets down while the interpreter is intact (PySide6/pyqtgraph can
    # crash when the garbage collector meets them during finalisation)
    win.deleteLater()
    del win
    app.processEvents()
    gc.collect()
    # the exit code of labid.cli.main's other commands on SIGTERM (143) and Ctrl-C (130)
    args.exit_code = {signal.SIGTERM: 143, signal.SIGINT: 130}.get(signals.received(), 0)
    return None
