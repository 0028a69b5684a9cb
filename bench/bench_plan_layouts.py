"""The recommended layout against the built-in rig's, per specimen (issue 25).

    OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_plan_layouts.py

For the CFRP plate (330 x 330 mm), the wood-like plate (580 x 215 mm) and the aluminium plate
(1 x 1 m) of bench/bench_plan.py: ``labid plan`` with E1, E2, G12 wanted (aluminium E, G),
fitted alone, the others held with a 10 % prior (then known exactly, prior 0: the layout's own
effect), no waves. Printed: the worst predicted std of
the wanted constants for the built-in rig's layout (scaled onto the plate when it does not fit)
and for the recommended one, their ratio, which of the plan's key modes the built-in layout does
not see (a sensor or the tap near a nodal line), and the CPU of the plan. The same plans with
the simulated spread of identifications: bench/bench_plan.py (--layout rig for the built-in
layout).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._machine import machine  # noqa: E402
from bench.bench_plan import specimen  # noqa: E402
from labid import services  # noqa: E402


CRIT = sys.argv[1] if len(sys.argv) > 1 else "MV"


def main() -> int:
    print(machine(), flush=True)
    for prior in ("10%", "0"):
        print(f"== held constants' prior: {prior}")
        layouts(prior)
    return 0


def layouts(prior: str) -> None:
    for name in ("cfrp", "wood", "aluminium"):
        spec = specimen(name)
        iso = spec.laminate.plies[0].material.isotropic
        t0 = time.process_time()
        res = services.plan_test(spec, None, want=None if iso else "E1,E2,G12", fit="wanted", waves="no",
                                 criterion=CRIT, prior=prior)
        cpu = time.process_time() - t0
        d = res.to_dict()
        rec, rig = d["recommended"], d["rigs"][0]
        unseen = {u["mode"]: u for u in rig["unseen_at_nominal"]}
        missed = [f"{k['mode'] + 1} {k['family']} {k['frequency_hz']:.0f} Hz (response {unseen[k['mode']]['response']:.3f})"
                  for k in d["key_modes"] if k["mode"] in unseen]
        print(f"{spec.name}: worst wanted std built-in rig {100 * rig['worst_std_rel']:.3f} %, recommended "
              f"{100 * rec['worst_std_rel']:.3f} %, ratio {d['improvement_worst_std']:.2f}x; modes seen "
              f"{rig['modes_seen']['nominal']} -> {rec['modes_seen']['nominal']}; key modes the built-in layout "
              f"misses: {', '.join(missed) or 'none'}; plan CPU {cpu:.1f} s")
        for n, c in rec["constants"].items():
            r = rig["constants"][n]
            print(f"    {n:5s} built-in {100 * r['std_rel']:.3f} % (type A {100 * r['type_a_rel']:.3f} %)  "
                  f"recommended {100 * c['std_rel']:.3f} % (type A {100 * c['type_a_rel']:.3f} %), limited by "
                  f"{c['limited_by']['source']} ({100 * c['limited_by']['share']:.0f} %)")
        for note in d["notes"]:
            print(f"    note: {note}")
    # a lab's naive layout: sensors and tap on the centre line x = L/2 of the CFRP plate, where
    # every mode antisymmetric in x (the twisting modes among them) has a nodal line
    import tomlkit
    from labid.inputs.rig import read_rig_text, rig_from_text
    doc = tomlkit.parse(read_rig_text(None)[0])
    doc["hammer"]["x"], doc["hammer"]["y"] = 0.165, 0.10
    accs = [c for c in doc["devices"]["vib"]["channels"] if c["kind"] == "accelerometer"]
    for c, y in zip(accs, (0.05, 0.19, 0.28)):
        c["x"], c["y"] = 0.165, y
    rig = rig_from_text(tomlkit.dumps(doc), "centre-line rig")
    spec = specimen("cfrp")
    for want in ("E1,E2,G12", "E1,E2,G12,G13,G23"):
        res = services.plan_test(spec, rig, want=want, fit="wanted", waves="no", criterion=CRIT, prior=prior)
        d = res.to_dict()
        rec, r0 = d["recommended"], d["rigs"][0]
        unseen = {u["mode"] for u in r0["unseen_at_nominal"]}
        missed = [f"{k['mode'] + 1} {k['family']}" for k in d["key_modes"] if k["mode"] in unseen]
        print(f"{spec.name}, centre-line rig, want {want}: worst std {100 * r0['worst_std_rel']:.3f} % -> "
              f"{100 * rec['worst_std_rel']:.3f} %, ratio {d['improvement_worst_std']:.2f}x; modes seen "
              f"{r0['modes_seen']['nominal']} -> {rec['modes_seen']['nominal']}; key modes it misses: "
              f"{', '.join(missed) or 'none'}")
        for n, c in rec["constants"].items():
            print(f"    {n:5s} centre-line {100 * r0['constants'][n]['std_rel']:.3f} %  recommended "
                  f"{100 * c['std_rel']:.3f} %")


if __name__ == "__main__":
    sys.exit(main())
