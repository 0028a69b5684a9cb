"""Benchmark of the simulated rig and the run store (samples per second).

Run: ``OMP_NUM_THREADS=1 .venv/bin/python bench/bench_acquisition.py``.
Prints a markdown section for bench/RESULTS.md:

* synthesis: first shot (engine results computed: plate modes / SAFE
  transients) and repeated shots (cached), in samples/s summed over channels,
  and the real-time factor (record duration / synthesis time);
  the wave device at 5 MHz with 2 channels is the requirement (> 1x real time);
* storage: ``RunStore.append_shot`` (flushed, gzip) in samples/s and MB/s of
  raw float64, and reading all shots back.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import h5py

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine as _machine  # noqa: E402

from labid.inputs.rig import read_rig_text, rig_from_text  # noqa: E402
from labid.store import RunStore  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from mock_hw.rig import SimulatedDevice  # noqa: E402


def machine() -> str:
    return _machine(f"h5py {h5py.version.version} (HDF5 {h5py.version.hdf5_version})")


def bench_device(rig, spec, role: str, n_shots: int) -> tuple[dict, list]:
    dev = SimulatedDevice(rig, spec, role, seed=1)
    d = rig.device(role)
    dev.configure(d.channels, d.timing, d.trigger)
    t0 = time.perf_counter()
    dev.arm()
    recs = [dev.read()]
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(n_shots):
        dev.arm()
        recs.append(dev.read())
    per = (time.perf_counter() - t0) / n_shots
    n = d.timing.samples * len(d.channels)
    dur = d.timing.samples / d.timing.rate_hz
    return dict(role=role, rate=d.timing.rate_hz, channels=len(d.channels), samples=d.timing.samples,
                first_s=first, per_shot_s=per, samples_per_s=n / per, realtime=dur / per), recs


def bench_store(recs, kind: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "run.h5"
        with RunStore(p) as s:
            s.append_shot(recs[0], kind)           # table creation outside the timing
            t0 = time.perf_counter()
            for r in recs[1:]:
                s.append_shot(r, kind)
            dt = time.perf_counter() - t0
        size = p.stat().st_size
        t0 = time.perf_counter()
        with RunStore(p, "r") as s:
            back = s.shots(kind)
        rt = time.perf_counter() - t0
    n = sum(a.size for a in recs[1].data.values()) * (len(recs) - 1)
    raw = sum(a.nbytes for r in recs for a in r.data.values())
    return dict(kind=kind, shots=len(recs) - 1, samples_per_s=n / dt, mb_per_s=8 * n / dt / 1e6,
                read_samples_per_s=n * len(back) / (len(recs) - 1) / rt, ratio=raw / size)


def main() -> None:
    spec = load_specimen("cfrp")
    text, _ = read_rig_text("default")
    text5 = text.replace("rate_hz = 2.0e6", "rate_hz = 5.0e6").replace("max_rate_hz = 4.0e6", "max_rate_hz = 5.0e6") \
        .replace("samples = 4096", "samples = 10000").replace("pretrigger = 400", "pretrigger = 1000")
    rig = rig_from_text(text5, "default rig, wave device at 5 MHz")
    rows, stores = [], []
    r, recs = bench_device(rig, spec, "hammer", 20)
    rows.append(r)
    stores.append(bench_store(recs, "hammer"))
    try:
        r, recs = bench_device(rig, spec, "wave", 50)
        rows.append(r)
        stores.append(bench_store(recs, "wave"))
    except (ImportError, AttributeError) as e:
        print(f"(wave device skipped: {e})")
    print("## Acquisition: simulated rig and run store (bench/bench_acquisition.py)\n")
    print(f"Machine: {machine()}\n")
    print("Synthesis (`mock_hw.rig.SimulatedDevice`, default rig; wave device set to 5 MHz, "
          "10000 samples):\n")
    print("| device | rate (Hz) | channels x samples | first shot (s) | per shot, cached (ms) | "
          "samples/s | x real time |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['role']} | {r['rate']:.3g} | {r['channels']} x {r['samples']} | {r['first_s']:.2f} | "
              f"{1e3 * r['per_shot_s']:.2f} | {r['samples_per_s']:.3g} | {r['realtime']:.1f} |")
    print("\nStorage (`labid.store.RunStore`, each shot flushed, gzip-1 + shuffle, float64 volts):\n")
    print("| kind | shots | append samples/s | append MB/s (raw) | read samples/s | compression |")
    print("| --- | --- | --- | --- | --- | --- |")
    for s in stores:
        print(f"| {s['kind']} | {s['shots']} | {s['samples_per_s']:.3g} | {s['mb_per_s']:.1f} | "
              f"{s['read_samples_per_s']:.3g} | {s['ratio']:.2f}x |")


if __name__ == "__main__":
    main()
