"""Test-wide settings: headless Qt and matplotlib, labid's own BLAS threading
(one thread per process unless LABID_THREADS or OMP_NUM_THREADS say otherwise)."""
import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("MPLBACKEND", "Agg")

from labid import threads  # noqa: E402

threads.configure()
