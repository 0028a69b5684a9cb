"""Combined identification from an independent raw run, after pick <-> identify (issue 24).

The plate: the CFRP laminate of bench/rigs/cfrp_large.toml (1 m square, 1.6 mm), whose TRUE
moduli differ from the specimen file's (``[simulation] truth_scale``: G13 x 0.70, G23 x 1.40,
E1 x 0.95, E2 x 1.10, G12 x 1.15: the file's G13 is 43 % high, its G23 29 % low). The rig
(bench/rigs/cfrp_1m_full.toml): the built-in hammer test scaled to the plate (5 hits, 3
accelerometers), a pencil-lead break at the centre, MFC pairs 10 and 25 cm from it along
0 and 90 deg (3 shots).

Records: the hammer shots from the simulated rig (``mock_hw``: the plate FE at the rig's
reference mesh, not identify's); the wave shots 'independent': the rig's chain (noise,
filter, ADC, reflections, trigger) with the plate's transfer functions from
bench/independent/legendre_safe.py (hierarchical Legendre p-elements, no code of
engine.safe). ``labid analyze --iterate`` then ``labid identify`` (services), and the
constants against the truth.

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_independent_run.py [--simulated]
"""
from __future__ import annotations

import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from bench.bench_unknown_plate import independent_transfer  # noqa: E402
from labid import services  # noqa: E402
from labid.inputs.features import read_features  # noqa: E402
from labid.inputs.rig import load_rig  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from mock_hw import waves as mock_waves  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402

HERE = Path(__file__).resolve().parent
TRUTH = (("E1", 0.95), ("E2", 1.10), ("G12", 1.15), ("G13", 0.70), ("G23", 1.40))
NAMES = ("E1", "E2", "G12", "G13", "G23")


def main(argv) -> None:
    print(f"machine: {machine()}")
    spec = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = load_rig(str(HERE / "rigs" / "cfrp_1m_full.toml"))
    rig = replace(rig, sim=replace(rig.sim, truth_scale=TRUTH))
    truth = truth_laminate(spec.laminate, TRUTH).plies[0].material.params()
    nominal = spec.laminate.plies[0].material.params()
    model = "simulated" if "--simulated" in argv else "independent"
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run.h5"
        t, c = time.perf_counter(), time.process_time()
        if model == "independent":
            with mock_waves.transfer_model("legendre_safe", independent_transfer):
                services.acquire(run, rig, spec, hits=5, waves=3)
        else:
            services.acquire(run, rig, spec, hits=5, waves=3)
        print(f"acquisition ({model} wave records): {time.perf_counter() - t:.1f} s wall, "
              f"{time.process_time() - c:.1f} s CPU")
        results = {}
        for it in (0, 4):
            out = Path(tmp) / f"features_{it}.json"
            t, c = time.perf_counter(), time.process_time()
            an = services.run_analysis(run, out=out, iterate=it)
            ta, ca = time.perf_counter() - t, time.process_time() - c
            doc = read_features(out)
            t, c = time.perf_counter(), time.process_time()
            res = services.run_identification(doc, base_dir=tmp, src=str(out), names=list(NAMES)).to_dict()
            ti, ci = time.perf_counter() - t, time.process_time() - c
            results[it] = (an, doc, res)
            print(f"\n{'with' if it else 'without'} pick <-> identify: analysis {ta:.1f} s wall / {ca:.1f} s CPU, "
                  f"identification {ti:.1f} s wall / {ci:.1f} s CPU")
            for w in doc.get("waves", []):
                print(f"  {w['mode']} {w['direction_deg']:g} deg: {len(w['frequency_hz'])} points "
                      f"{min(w['frequency_hz']) / 1e3:.0f}-{max(w['frequency_hz']) / 1e3:.0f} kHz")
            for r in doc.get("analysis", {}).get("iterations", []):
                print(f"  round {r['iteration']}: added {r.get('added')}, lost {r.get('lost')}, largest change "
                      f"{r.get('max_shift_sigma', float('nan')):.2g} sigma; G13 {r['constants'].get('G13', 0) / 1e9:.3f}, "
                      f"G23 {r['constants'].get('G23', 0) / 1e9:.3f} GPa")
            print(f"  fit: {res['fit'].get('verdict') or ('identified' if res.get('identified') else 'not identified')}, "
                  f"consistent {res['fit'].get('consistent')}, chi2/nu {res['fit'].get('chi2_per_dof', float('nan')):.3g}, "
                  f"p {res['fit'].get('p_value', float('nan')):.2g}; per block chi2/n: " + ", ".join(
                      f"{k} {b['chi2'] / max(b['n'], 1):.2g}" for k, b in res.get("blocks", {}).items())
                  + "; against the stated sigmas (before any Birge scaling): " + ", ".join(
                  f"{k} {b['chi2'] * res.get('sigma_scale', {}).get(b['kind'], 1.0) ** 2 / max(b['n'], 1):.3g}"
                  for k, b in res.get("blocks", {}).items()))
            for wmsg in res.get("warnings", [])[:4]:
                print("   ", wmsg[:200])
            print(f"  {'constant':>8} {'file':>9} {'truth':>9} {'identified':>11} {'std':>8} {'error':>8} {'err/std':>7}")
            for n in NAMES:
                p = res["parameters"][n]
                err = p["value"] / truth[n] - 1
                print(f"  {n:>8} {nominal[n] / 1e9:9.3f} {truth[n] / 1e9:9.3f} {p['value'] / 1e9:11.3f} "
                      f"{p['std'] / 1e9:8.3f} {100 * err:+7.2f}% {abs(p['value'] - truth[n]) / p['std']:7.2f}")


if __name__ == "__main__":
    main(sys.argv[1:])
