"""Waves only when they pay, checked in simulation (issue 25).

    OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_plan_waves.py [--dir /tmp/plan_waves] [--seed 1]

1. ``labid plan cfrp --write-rig RIG.toml`` (every constant wanted, 2 % target): the plan's
   modal-only and with-waves predictions of G13 and G23, and the rig it writes (accelerometers,
   tap, pencil source and the legs' sensors).
2. ``labid acquire --rig RIG.toml --specimen cfrp`` (the simulated rig: modes of the reference
   mesh, SAFE wave records with edge reflections, noise, ADC: not the identification's models),
   ``labid analyze``, then ``labid identify --params E1,E2,nu12,G12,G13,G23`` on the combined
   features and on the modal features alone.

Printed: the plan's predictions, the number of A0 points it expected per leg against what the
analysis measured, the identified values against the truth (the specimen's nominal constants:
the simulated plate has them) with their stds, and the CPU of each command.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench._machine import machine  # noqa: E402

LABID = str(ROOT / ".venv" / "bin" / "labid")
TRUTH = {"E1": 136.7e9, "E2": 9.0e9, "nu12": 0.30, "G12": 5.0e9, "G13": 5.08e9, "G23": 3.16e9}
ALL = ",".join(TRUTH)


def labid(*args) -> float:
    """Run one command; its CPU (children's user + system), s."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([LABID, *args, "-q"], check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="/tmp/plan_waves")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    d = Path(args.dir)
    d.mkdir(parents=True, exist_ok=True)
    print(machine(), flush=True)
    cpu = {"plan": labid("plan", "cfrp", "--write-rig", str(d / "rig.toml"), "--json", str(d / "plan.json"))}
    plan = json.loads((d / "plan.json").read_text())
    run = d / "run.h5"
    run.unlink(missing_ok=True)
    cpu["acquire"] = labid("acquire", "--rig", str(d / "rig.toml"), "--specimen", "cfrp", "--out", str(run),
                           "--seed", str(args.seed))
    cpu["analyze"] = labid("analyze", str(run), "--out", str(d / "features.json"))
    feats = json.loads((d / "features.json").read_text())
    modal_only = {k: v for k, v in feats.items() if k != "waves"}
    (d / "features_modal.json").write_text(json.dumps(modal_only))
    cpu["identify combined"] = labid("identify", str(d / "features.json"), "--params", ALL, "--json",
                                     str(d / "ident.json"))
    cpu["identify modal"] = labid("identify", str(d / "features_modal.json"), "--params", ALL, "--json",
                                  str(d / "ident_modal.json"))
    ident = json.loads((d / "ident.json").read_text())
    ident_m = json.loads((d / "ident_modal.json").read_text())
    w = plan["waves"]
    print(f"plan: waves {'RECOMMENDED' if w['recommended'] else 'not recommended'}; fitted {plan['fitted']}")
    for leg in w.get("legs", []):
        got = [c for c in feats.get("waves", []) if abs(c["direction_deg"] - leg["direction_deg"]) < 1e-6]
        n_got = sum(len(c["frequency_hz"]) for c in got)
        print(f"  leg {leg['direction_deg']:g} deg, sensors {leg['near_m']:.3f} / {leg['far_m']:.3f} m: "
              f"{len(leg['points_hz'])} A0 points planned, {n_got} measured")
    print(f"{'':5s} {'plan modal':>11s} {'plan +waves':>12s} | {'sim modal':>20s} {'sim +waves':>22s}")
    for n in TRUTH:
        pm = plan["recommended_modal_only"]["constants"].get(n, {}).get("std_rel")
        pw = plan["recommended"]["constants"].get(n, {}).get("std_rel")
        cells = []
        for res in (ident_m, ident):
            p = res["parameters"][n]
            cells.append(f"{p['value'] / TRUTH[n] - 1:+7.2%} +- {p['std'] / p['value']:6.2%}")
        print(f"{n:5s} {pm if pm is None else f'{pm:11.2%}'} {pw if pw is None else f'{pw:12.2%}'} | "
              f"{cells[0]:>20s} {cells[1]:>22s}")
    print("CPU (s): " + ", ".join(f"{k} {v:.1f}" for k, v in cpu.items()))
    return 0


if __name__ == "__main__":
    t0 = time.time()
    rc = main()
    print(f"wall {time.time() - t0:.0f} s")
    sys.exit(rc)
