"""The machine line every benchmark records with its results."""
from __future__ import annotations

import os
import platform
import subprocess

import numpy as np
import scipy


def machine(extra: str = "") -> str:
    """CPU model, cores, Python/numpy/scipy versions, thread setting and load average."""
    try:
        cpu = next(ln.split(":", 1)[1].strip() for ln in subprocess.run(
            ["lscpu"], capture_output=True, text=True).stdout.splitlines() if ln.startswith("Model name"))
    except (OSError, StopIteration):
        cpu = platform.processor()
    parts = [f"{cpu}, {os.cpu_count()} cores", f"Python {platform.python_version()}, numpy {np.__version__}, "
             f"scipy {scipy.__version__}" + (f", {extra}" if extra else ""),
             f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}",
             f"load average at start {', '.join(f'{x:.1f}' for x in os.getloadavg())}"]
    return "; ".join(parts)
