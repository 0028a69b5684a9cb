"""Benchmark: complex Morlet CWT of a 10,000-sample record over 100 frequencies.

Target (issue 5): <= 30 ms. Compares engine.waves.cwt(method='fft') (analytic
Morlet filter bank, one FFT of the record, one batched inverse FFT) with
pywt.cwt(method='fft'), for the paper's two wavelets. Also times the full
per-record pipeline (CWT + arrival picking + bias correction).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_waves.py
"""
from __future__ import annotations

import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import pywt
import scipy

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from engine import waves  # noqa: E402


def best_of(fn, repeat=7, number=1):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        ts.append((time.perf_counter() - t0) / number)
    return min(ts), float(np.median(ts))


def main() -> None:
    fs, n, nf = 1e6, 10_000, 100
    rng = np.random.default_rng(0)
    x = rng.normal(size=n)
    rows = []
    for wl, fmax in ((waves.PAPER_ALUMINIUM, 50e3), (waves.PAPER_CFRP, 200e3)):
        freqs = np.linspace(fmax / nf, fmax, nf)
        for method, prec in (("fft", "single"), ("fft", "double"), ("pywt", "double")):
            waves.cwt(x, fs, freqs, wl, method=method, precision=prec)  # warm-up (and filter-bank cache)
            b, m = best_of(lambda: waves.cwt(x, fs, freqs, wl, method=method, precision=prec),
                           repeat=5 if method == "pywt" else 9)
            rows.append((wl.name, f"{freqs[0] / 1e3:g}-{fmax / 1e3:g} kHz", f"{method} ({prec})", b * 1e3, m * 1e3))

        waves.cwt_decimated(x, fs, freqs, wl)
        b, m = best_of(lambda: waves.cwt_decimated(x, fs, freqs, wl), repeat=9)
        step = waves.cwt_decimated(x, fs, freqs, wl)[1]
        rows.append((wl.name, f"{freqs[0] / 1e3:g}-{fmax / 1e3:g} kHz", f"cwt_decimated (every {step} samples)",
                     b * 1e3, m * 1e3))

        def pipeline():
            W = waves.cwt(x, fs, freqs, wl)
            a = waves.arrival_times(W, fs, freqs, wl, min_snr_db=-100, min_rel_db=-100)
            waves.correct_dispersion_bias(a)

        pipeline()
        b, m = best_of(pipeline)
        rows.append((wl.name, f"{freqs[0] / 1e3:g}-{fmax / 1e3:g} kHz", "fft + arrivals", b * 1e3, m * 1e3))
    print("Machine:", platform.processor() or platform.machine(), f"{os.cpu_count()} cores;",
          f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__},"
          f" PyWavelets {pywt.__version__}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}")
    print(f"Record {n} samples at {fs / 1e6:g} MHz, {nf} frequencies.\n")
    print("| wavelet | band | method | best (ms) | median (ms) |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.1f} | {r[4]:.1f} |")


if __name__ == "__main__":
    main()
