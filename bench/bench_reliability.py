"""Cost of crash-safe results (issue 15): ``RunStore.write_result`` copies the run file,
writes the group into the copy, syncs and renames it over the run. This measures that
cost against the run file's size (shots of 3 channels x 20,000 samples, float64, gzip).

    PYTHONPATH=. python bench/bench_reliability.py [--shots 10,100,300]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine  # noqa: E402
from drivers.protocol import ChannelConfig, Record, Timing, Trigger  # noqa: E402
from labid.store import RunStore  # noqa: E402

CH = tuple(ChannelConfig(n, k, f"ai{i}") for i, (n, k) in enumerate(
    (("force", "force"), ("acc1", "accelerometer"), ("acc2", "accelerometer"))))


def record(i: int, n: int = 20_000) -> Record:
    rng = np.random.default_rng(i)
    return Record(data={c.name: rng.standard_normal(n) * 1e-2 for c in CH}, channels=CH,
                  timing=Timing(10_000.0, n, 200), trigger=Trigger("force", 0.02, "rising"),
                  overload={}, timestamp=1.7e9 + i, backend="bench", meta={"i": i})


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--shots", default="10,100,300")
    args = ap.parse_args()
    print(machine())
    print("| shots | file MB | write_result wall s | CPU s | MB/s copied |")
    print("|---|---|---|---|---|")
    result = {"peaks": {"frequency_hz": np.linspace(10, 2000, 40)}, "features": {"json": "{}" * 2000}}
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "run.h5"
        done = 0
        for n in (int(x) for x in args.shots.split(",")):
            with RunStore(p) as st:
                for i in range(done, n):
                    st.append_shot(record(i), "hammer")
            done = n
            size = p.stat().st_size / 1e6
            walls, cpus = [], []
            for _ in range(3):
                t, c = time.perf_counter(), time.process_time()
                with RunStore(p) as st:
                    st.write_result("analysis", result)
                walls.append(time.perf_counter() - t)
                cpus.append(time.process_time() - c)
            w = float(np.median(walls))
            print(f"| {n} | {size:.1f} | {w:.3f} | {float(np.median(cpus)):.3f} | {size / w:.0f} |")


if __name__ == "__main__":
    main()
