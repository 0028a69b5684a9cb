"""Regenerate the panel and report screenshots of docs/ from a real `labid demo` run.

    QT_QPA_PLATFORM=offscreen python docs/screenshots/regenerate.py [--demo-out DIR] [--run-demo]

Opens DIR/demo_run.h5 (default ``demo_out``; ``--run-demo`` runs ``labid demo --out DIR``
first) in the lab panel at 1366 x 768 and grabs every tab to ``docs/screenshots/<tab>.png``;
then writes the run's report (to a temporary folder) and, when ``chromium`` is on the
PATH, takes headless screenshots of it: ``report.png`` (the certificate's first page) and
``report-full.png`` (the whole report, appendices included). Run it from the folder that
holds DIR, so that the panel and the report show the path a user types (``demo_out/...``);
the window is not closed, so no session state is written into the demo's run file.
``--multistart N`` also runs an identification with N random starts from the panel on a
copy ``DIR/demo_run_multistart.h5`` (removed afterwards) and grabs
``identification-multistart.png``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
TABS = ("setup", "acquisition", "modes", "waves", "identification", "gap")


def grab_panel(run: Path) -> list[Path]:
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtWidgets import QApplication

    from labid.gui.main_window import MainWindow
    app = QApplication.instance() or QApplication(["labid"])
    win = MainWindow(str(run))
    win.resize(1366, 768)
    win.show()
    out = []
    for i, name in enumerate(TABS):
        win.tabs.setCurrentIndex(i)
        for _ in range(5):
            app.processEvents()
        p = HERE / f"{name}.png"
        win.grab().save(str(p))
        out.append(p)
    win.shutdown_jobs()
    win.deleteLater()
    app.processEvents()
    return out


def grab_multistart(src: Path, n_starts: int) -> list[Path]:
    """Identify from the demo run with ``n_starts`` random starts in the panel; grab the tab."""
    from PySide6.QtCore import QEventLoop
    from PySide6.QtWidgets import QApplication

    from labid.gui.main_window import MainWindow
    app = QApplication.instance() or QApplication(["labid"])
    run = src.with_name("demo_run_multistart.h5")
    shutil.copy(src, run)
    try:
        win = MainWindow(str(run))
        win.resize(1366, 768)
        win.show()
        win.tabs.setCurrentIndex(TABS.index("identification"))
        view = win.identification
        view.starts_spin.setValue(n_starts)
        view.identify()
        if view.job is not None:
            loop = QEventLoop()
            view.job.ended.connect(loop.quit)
            loop.exec()                       # until the job's 'ended' signal
        for _ in range(5):
            app.processEvents()
        p = HERE / "identification-multistart.png"
        win.grab().save(str(p))
        win.shutdown_jobs()
        win.deleteLater()
        app.processEvents()
        return [p]
    finally:
        run.unlink(missing_ok=True)


def shoot_report(run: Path, workdir: Path) -> list[Path]:
    from labid.report import write_report
    html = Path(write_report(run, workdir / "report.html"))
    browser = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if not browser:
        print("chromium not found: report screenshots skipped", file=sys.stderr)
        return []
    out = []
    for name, height in (("report.png", 1500), ("report-full.png", 6000)):
        p = HERE / name
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--window-size=1000,{height}", f"--screenshot={p}", html.as_uri()],
                       check=True, capture_output=True)
        out.append(p)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demo-out", default="demo_out", help="output folder of labid demo (default demo_out)")
    ap.add_argument("--run-demo", action="store_true", help="run labid demo --out DIR first")
    ap.add_argument("--multistart", type=int, default=0, metavar="N",
                    help="also grab the Identification tab after N random starts (a minute of CPU)")
    args = ap.parse_args()
    demo = Path(args.demo_out)
    if args.run_demo:
        from labid.cli import main as cli
        if cli(["demo", "--out", str(demo)]) != 0:
            return 1
    src = demo / "demo_run.h5"
    if not src.is_file():
        print(f"{src}: not found; run `labid demo --out {demo}` (or pass --run-demo)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as d:
        shots = grab_panel(src) + shoot_report(src, Path(d))
        if args.multistart:
            shots += grab_multistart(src, args.multistart)
        for p in shots:
            print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
