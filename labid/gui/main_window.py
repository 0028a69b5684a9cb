"""The lab panel's main window: tabs, status bar, background jobs, session state.

State shared by the views is the run file: each view reads what the workflow
objects wrote there (``/results/...``) and the window stores its own session
state under ``/results/gui`` (``labid.services.save_session``), so reopening a
run restores the views. Every access to the run file and the workflows goes
through ``labid.services``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from PySide6.QtCore import QTimer, Signal
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QFileDialog, QLabel, QMainWindow, QProgressBar, QPushButton, QTabWidget)

from .. import services
from ..base.errors import UserError
from ..base.jsonio import to_jsonable
from ..report.certificate import write_report
from ..base.summary import next_step
from .acquisition_view import AcquisitionView
from .checks_view import ChecksView
from .gap_view import GapView
from .identification_view import IdentificationView
from .modes_view import ModesView
from .setup_view import SetupView
from .snapshot import Snapshot, load as load_snapshot
from .waves_view import WavesView
from .worker import Job

TABS = ("Setup", "Acquisition", "Modes", "Waves", "Identification", "Gap", "Hammer checks")
#: exclusive jobs after which the session state is saved in the run file
AUTOSAVE_AFTER = ("acquisition", "analysis", "identification", "diagnosis")


class MainWindow(QMainWindow):
    """``MainWindow(run_path=None)``: the lab panel; ``run_path`` opens an existing run."""

    #: emitted with the run's path once it is open and the views restored
    run_opened = Signal(str)

    def __init__(self, run_path: str | None = None, background: bool = False):
        super().__init__()
        self.setWindowTitle("labid — lab panel")
        self.resize(1366, 768)
        self.run_path: str | None = None
        self.job: Job | None = None
        self._side_jobs: set[Job] = set()
        self.messages: list[tuple[str, bool]] = []
        self._mem_results: dict[str, dict] = {}
        #: the run file read once (``gui.snapshot``), shared by the views until the run changes
        self._snap: Snapshot | None = None

        self.setup = SetupView(self)
        self.acquisition = AcquisitionView(self)
        self.modes = ModesView(self)
        self.waves = WavesView(self)
        self.identification = IdentificationView(self)
        self.gap = GapView(self)
        self.checks = ChecksView(self)     # last: the stored tab indices of earlier sessions stay valid
        self.views = {"setup": self.setup, "acquisition": self.acquisition, "modes": self.modes,
                      "waves": self.waves, "identification": self.identification, "gap": self.gap,
                      "checks": self.checks}
        self.tabs = QTabWidget()
        for title, w in zip(TABS, self.views.values()):
            self.tabs.addTab(w, title)
        self.setCentralWidget(self.tabs)

        sb = self.statusBar()
        self.status_label = QLabel("ready")
        self.run_label = QLabel("no run file")
        self.cancel_btn = QPushButton("Cancel job")
        self.cancel_btn.setVisible(False)
        self.cancel_btn.clicked.connect(self.cancel_job)
        self.step_label = QLabel("")
        self.step_label.setStyleSheet("color: #1f4e79;")
        self.progress_bar = QProgressBar()
        self.progress_bar.setMaximumWidth(160)
        self.progress_bar.setVisible(False)
        sb.addWidget(self.status_label, 1)
        sb.addPermanentWidget(self.progress_bar)
        sb.addPermanentWidget(self.step_label)
        sb.addPermanentWidget(self.run_label)
        sb.addPermanentWidget(self.cancel_btn)

        m = self.menuBar().addMenu("&File")
        for text, key, slot in (("&Open run…", QKeySequence.Open, self._open_dialog),
                                ("&Save session", QKeySequence.Save, self.save_session),
                                ("Write &report…", None, self._report_dialog),
                                ("&Quit", QKeySequence.Quit, self.close)):
            a = QAction(text, self)
            if key is not None:
                a.setShortcut(key)
            a.triggered.connect(slot)
            m.addAction(a)
        if run_path:
            self.open_run(run_path, background=background)
        else:
            self.update_step()

    # -- messages ------------------------------------------------------------------
    def message(self, text: str, error: bool = False) -> None:
        """One line in the status bar (red for a problem)."""
        self.messages.append((text, error))
        self.status_label.setText(text)
        self.status_label.setToolTip(text)
        self.status_label.setStyleSheet("color: #b00000; font-weight: bold;" if error else "")

    # -- jobs ----------------------------------------------------------------------------
    def busy(self) -> bool:
        return self.job is not None

    def start_job(self, name: str, fn: Callable, on_done: Callable[[Any], None], *,
                  on_progress: Callable[[Any], None] | None = None,
                  on_failed: Callable[[str], None] | None = None, exclusive: bool = True) -> Job | None:
        """Run ``fn(progress, should_stop)`` in a background thread.

        ``exclusive`` jobs (acquisition, analysis, identification, diagnosis)
        run one at a time and can be cancelled from the status bar.
        """
        if exclusive and self.job is not None:
            self.message(f"{self.job.name} is running; wait for it or cancel it", error=True)
            return None
        job = Job(name, fn)
        if on_progress:
            job.progress.connect(on_progress)

        def ok(result):
            if job.cancelled and exclusive and name not in ("acquisition",):
                self.message(f"{name}: cancelled (result discarded)")
                if on_failed:
                    on_failed("cancelled")
                return
            on_done(result)

        def bad(msg: str):
            self.message(f"{name}: {msg}", error=msg != "cancelled")
            if on_failed:
                on_failed(msg)

        job.succeeded.connect(ok)
        job.failed.connect(bad)

        def ended():
            if exclusive and self.job is job:
                self.job = None
                self.cancel_btn.setVisible(False)
            self._side_jobs.discard(job)
            # released once every slot of 'ended' has run (a test's waitSignal among them)
            QTimer.singleShot(0, job.release)
            if exclusive and name in AUTOSAVE_AFTER:
                self.save_session(quiet=True)

        job.ended.connect(ended)
        if exclusive:
            self.job = job
            self.cancel_btn.setVisible(True)
            self.message(f"{name}: running…")
        self._side_jobs.add(job)
        job.start()
        return job

    def idle(self) -> bool:
        """True when no job of this window (exclusive or side: opening, SAFE curves) is running."""
        return self.job is None and not self._side_jobs

    def cancel_job(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.message(f"{self.job.name}: cancelling…")

    # -- the run file -----------------------------------------------------------------------
    def set_run_path(self, path: str, reload: bool = True) -> None:
        if str(path) != self.run_path:
            self._snap = None
        self.run_path = str(path)
        self.run_label.setText(f"run: {Path(path).name}")
        self.acquisition.run_edit.setText(str(path))
        if reload:
            self.run_changed()

    def open_run(self, path: str, background: bool = False) -> bool:
        """Open an existing run file and restore the views; a bad file shows a message.
        The file is read once (``gui.snapshot.load``); ``background``: in a worker thread with
        progress in the status bar (File > Open, ``labid gui RUN.h5``), the views restored when
        it is read (``run_opened`` path: ``self.opening`` is the job until then)."""
        if self.busy():
            self.message(f"{self.job.name} is running; open the run when it has finished", error=True)
            return False
        if not background:
            try:
                snap = load_snapshot(path)
            except UserError as e:
                self.message(str(e), error=True)
                return False
            self._apply_opened(path, snap)
            return True

        def work(progress, should_stop):
            return load_snapshot(path, progress)

        def failed(msg: str) -> None:       # the job's one line is already in the status bar
            self.opening = None
            self.progress_bar.setVisible(False)

        def done(snap: Snapshot) -> None:
            self.opening = None
            self.progress_bar.setVisible(False)
            self._apply_opened(path, snap)

        self.progress_bar.setRange(0, 0)
        self.progress_bar.setVisible(True)
        # a side job: the status bar's progress instead of Cancel; refused above while an
        # exclusive job (acquisition, fit) runs
        self.opening = self.start_job("opening run", work, done, on_progress=self._open_progress,
                                      on_failed=failed, exclusive=False)
        return self.opening is not None

    #: the job reading a run opened in the background (None when none is)
    opening: Job | None = None

    def _open_progress(self, p) -> None:
        k, n, what = p
        self.progress_bar.setRange(0, n)
        self.progress_bar.setValue(k)
        self.status_label.setText(f"opening run: reading {what} ({k + 1}/{n})…")

    def _apply_opened(self, path: str, snap: Snapshot) -> None:
        """Restore the views from a run read once (GUI thread)."""
        rd = snap.run
        state = services.session_state(rd)
        self.set_run_path(path, reload=False)
        self._snap = snap
        self.setup.restore(state.get("setup", {}), rd.specimen_toml, rd.rig_toml)
        for key, view in self.views.items():
            if key != "setup" and hasattr(view, "restore"):
                view.restore(state.get(key, {}))
        self._reload_views()
        if "tab" in state:
            self.tabs.setCurrentIndex(int(state["tab"]))
        overdue = self._overdue_calibrations(path, snap.overdue)
        if overdue:  # once per session per channel, as the CLI does
            self.message(f"opened {path}; calibration overdue: " + "; ".join(overdue), error=True)
        else:
            self.message(f"opened {path}")
        self.run_opened.emit(str(path))

    def snapshot(self) -> Snapshot | None:
        """The run file as the views show it, read once (``gui.snapshot``) and kept until the
        run changes (``run_changed``, a stored result); None without a readable run file."""
        if self._snap is None and self.run_path and Path(self.run_path).exists():
            try:
                self._snap = load_snapshot(self.run_path)
            except (UserError, OSError):
                return None
        return self._snap

    @staticmethod
    def _overdue_calibrations(path: str, lines: list[str]) -> list[str]:
        """Channels of the run recorded past their calibration's due date, not yet warned about."""
        return services.warn_calibration({"overdue": lines, "sheet": path}, prefix="labid gui",
                                         write=lambda s: None)

    def run_changed(self) -> None:
        """The run file changed (new shots or results): read it once more, let every view reload."""
        self._snap = None
        self._reload_views()

    def _reload_views(self) -> None:
        for view in self.views.values():
            if hasattr(view, "reload"):
                view.reload()
        self.update_step()

    def update_step(self) -> None:
        """The current step of the run and the next one, in the status bar."""
        counts, names = {}, set(self._mem_results)
        snap = self.snapshot()
        if snap is not None:
            counts, names = snap.run.counts, names | set(snap.run.results)
        current, nxt = next_step(counts, names)
        self.step_label.setText(f"now: {current}  →  next: {nxt}")

    # -- results shared by the views ------------------------------------------------------------
    def read_results(self, name: str):
        """The results group ``name`` of the run file (JSON copy preferred), or None."""
        if name in self._mem_results:
            return self._mem_results[name]
        snap = self.snapshot()
        return None if snap is None else snap.run.results.get(name)

    def store_results(self, name: str, data: dict) -> bool:
        """Write ``data`` under /results/<name> (structured + a JSON copy)."""
        try:
            return self._store_results(name, data)
        finally:
            self.update_step()

    def _store_results(self, name: str, data: dict) -> bool:
        if not self.run_path:
            self._mem_results[name] = to_jsonable(data)
            self.message(f"{name}: kept in memory only (no run file)", error=True)
            return False
        self._mem_results.pop(name, None)
        self._snap = None                   # read again when a view next asks
        try:
            services.store_result(self.run_path, name, data)
        except (UserError, OSError) as e:
            self._mem_results[name] = to_jsonable(data)
            self.message(f"{name}: not saved in the run file: {e}", error=True)
            return False
        return True

    def features(self) -> dict | None:
        """The measured features (CONTRACT section 2) of the run, or None."""
        snap = self.snapshot()
        return (snap.features or None) if snap is not None else None

    def specimen_for_features(self, doc: dict):
        """The specimen a features document refers to (inline, path or built-in), else
        the one of the run / the Setup tab."""
        spec = services.specimen_for_features(doc)
        if spec is not None:
            return spec
        spec = self.setup.specimen()
        if spec is None:
            raise UserError("the specimen on the Setup tab is not valid; fix it first")
        return spec

    # -- analysis (labid.services.run_analysis, as 'labid analyze') -------------------------------
    def analyze(self) -> None:
        """Run the analysis of the run file (as 'labid analyze') in a background job."""
        if not self.run_path:
            self.message("analysis: no run file", error=True)
            return
        run = self.run_path
        temperature = self.setup.temperature_c

        def work(progress, should_stop):
            return services.run_analysis(run, temperature_c=temperature)

        self.start_job("analysis", work, self._analysis_done)

    def _analysis_done(self, out) -> None:
        self._snap = None
        show_analysis(self, out)
        self.message("analysis done: " + analysis_summary(out))
        for v in (self.identification, self.gap):
            v.reload()
        self.update_step()

    def save_modal_picks(self, peaks) -> bool:
        if not self.run_path:
            return False
        self._snap = None
        try:
            services.save_picks(self.run_path, peaks)
        except (UserError, OSError, ValueError) as e:
            self.message(f"save picks: {e}", error=True)
            return False
        self.message(f"{len(peaks)} picks saved in {self.run_path}")
        for v in (self.identification, self.gap):
            v.reload()
        return True

    def session_state(self) -> dict:
        st = {"tab": int(self.tabs.currentIndex())}
        for key, view in self.views.items():
            if hasattr(view, "state"):
                st[key] = view.state()
        return st

    def save_session(self, quiet: bool = False) -> bool:
        """Store the session state in the run file (``/results/gui``). ``quiet``: an
        automatic save (after a job, on closing): only a failure is reported."""
        if quiet and (not self.run_path or not Path(self.run_path).exists() or self.busy()):
            return False
        if not self.run_path:
            self.message("no run file to save the session in; choose one on the Acquisition tab", error=True)
            return False
        if self.busy():
            self.message(f"{self.job.name} is running; save the session when it has finished", error=True)
            return False
        try:
            services.save_session(self.run_path, self.session_state())
        except UserError as e:
            self.message(str(e), error=True)
            return False
        except OSError as e:
            self.message(f"{self.run_path}: cannot write the session ({e})", error=True)
            return False
        if not quiet:
            self.message(f"session saved in {self.run_path}")
        return True

    # -- dialogs --------------------------------------------------------------------------------
    def _open_dialog(self) -> None:
        p, _ = QFileDialog.getOpenFileName(self, "Open run", "", "HDF5 run (*.h5);;All (*)")
        if p:
            self.open_run(p, background=True)

    def _report_dialog(self) -> None:
        if not self.run_path:
            self.message("no run file", error=True)
            return
        p, _ = QFileDialog.getSaveFileName(self, "Report", str(Path(self.run_path).with_suffix(".html")),
                                           "HTML (*.html)")
        if p:
            self.write_report(p)

    def write_report(self, out: str) -> Job | None:
        run = self.run_path

        def work(progress, should_stop):
            return write_report(run, out)

        return self.start_job("report", work, lambda path: self.message(f"report written: {path}"))

    def shutdown_jobs(self, wait_ms: int = 15000) -> None:
        """Cancel every job of this window and disconnect it, so that nothing it still
        delivers reaches a widget being deleted. The exclusive job (an acquisition keeps
        its shots) gets up to ``wait_ms`` to finish its shot and close the run file."""
        jobs = list(self._side_jobs) + ([self.job] if self.job is not None else [])
        for job in jobs:
            job.cancel()
        if self.job is not None:
            self.job.wait(wait_ms)
        for job in jobs:
            job.release()
        self.job = None
        self._side_jobs.clear()
        self.cancel_btn.setVisible(False)
        for view in self.views.values():
            if getattr(view, "job", None) is not None:
                view.job = None

    def closeEvent(self, e) -> None:  # noqa: N802
        self.shutdown_jobs()
        self.save_session(quiet=True)
        super().closeEvent(e)


def show_analysis(main: MainWindow, an) -> None:
    """Show a fresh ``labid.workflows.analysis.Analysis`` in the Modes and Waves tabs."""
    main.modes.set_modal(an.spectrum, an.peaks) if an.spectrum is not None else main.modes.reload()
    main.waves.set_analysis(an)


def analysis_summary(an) -> str:
    """One line on what an analysis found."""
    f = an.features
    n_modes = len((f.get("modal") or {}).get("frequencies_hz", []))
    n_w = sum(len(w.get("frequency_hz", [])) for w in f.get("waves") or [])
    return f"{n_modes} resonances, {n_w} group-velocity points"
