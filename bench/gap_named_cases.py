"""The issue-28 cases one by one, from the independent generator (bench/blind_independent.py).

Run:  OMP_NUM_THREADS=1 nice .venv/bin/python bench/gap_named_cases.py [--only NAME,...]

Each case is what the issue lists (a clean 10-mode plate with six constants, springs whose
lifted rigid modes are not listed, a hidden accelerometer mass, a far sensor 3 mm off, one
wave point, a 2 deg misalignment on 12 modes at 0.1 % noise, a density gradient, a taper, a
mild anticlastic curvature, a path error over a flat band), diagnosed as a lab would
(``labid.workflows.diagnosis.run_diagnosis``). Prints a markdown table for bench/RESULTS.md
with the verdict, its confusable group, magnitudes, the oracle chi^2 (what the noise-free data
leave after identify's constants-only fit: below 30 the effect is not in the data, and `none`
is right), the gap and CPU time.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.bench_gap_independent import VISIBLE, oracle  # noqa: E402
from bench.blind_independent import draw  # noqa: E402
from labid.base import progress  # noqa: E402
from labid.workflows.diagnosis import run_diagnosis  # noqa: E402

CFRP_WAVES = (("A0", 0.0, 8), ("A0", 90.0, 8), ("S0", 0.0, 6))
IN_PLANE = (("E1", "E2", "G12"), None)
#: name: (seed, kind, forced draw options (``fit``: constants fitted, prior), expected verdicts)
CASES = {
    "clean, 10 modes, six constants (ML)": (3, "clean", dict(
        specimen="cfrp", data="modal", n_modes=10, noise=0.002,
        fit=(("E1", "E2", "nu12", "G12", "G13", "G23"), None)), {"none"}),
    "springs 150 N/m, rigid modes not listed": (5, "support_stiffness", dict(
        specimen="cfrp", n_modes=10, noise=0.002, magnitude=150.0), {"support_stiffness"}),
    "4 g hidden at each accelerometer": (7, "sensor_mass", dict(specimen="cfrp", n_modes=10, noise=0.002,
                                                                magnitude=0.004), {"sensor_mass"}),
    "far sensor 3 mm, waves only (A0 0/90 + S0, 20-200 kHz)": (9, "path_length", dict(
        specimen="cfrp", data="waves", noise=0.002, magnitude=0.003, wave_sets=CFRP_WAVES,
        fit=(("E1", "nu12", "G13", "G23"), None)), {"path_length"}),
    "far sensor 3 mm, 12 modes + A0 0/90 + S0 (20-200 kHz)": (9, "path_length", dict(
        specimen="cfrp", data="combined", n_modes=12, noise=0.002, magnitude=0.003, wave_sets=CFRP_WAVES,
        fit=IN_PLANE), {"path_length"}),
    "far sensor 6 mm, 12 modes + S0 0 deg 20-60 kHz (flat)": (10, "path_length", dict(
        specimen="cfrp", data="combined", n_modes=12, noise=0.002, magnitude=0.006,
        wave_sets=(("S0", 0.0, 8),), band=(2e4, 6e4), fit=IN_PLANE), {"path_length", "timing_offset"}),
    "one wave point, four constants": (11, "clean", dict(
        specimen="cfrp", data="waves", noise=0.002, wave_sets=(("A0", 0.0, 1),),
        fit=(("E1", "nu12", "G13", "G23"), 0.3)), {"insufficient_data"}),
    "misalignment 2 deg, 12 modes, 0.1 %": (13, "misalignment", dict(specimen="cfrp", n_modes=12, noise=0.001,
                                                                     magnitude=2.0), {"misalignment"}),
    "misalignment 2 deg, 12 modes, 0.1 % (seed 2)": (14, "misalignment", dict(
        specimen="cfrp", n_modes=12, noise=0.001, magnitude=2.0), {"misalignment"}),
    "density gradient 8 %, CFRP 20 modes": (15, "density_gradient", dict(
        specimen="cfrp", n_modes=20, noise=0.001, magnitude=0.08), {"density_gradient", "thickness_taper"}),
    "density gradient 10 %, aluminium 20 modes": (16, "density_gradient", dict(
        specimen="aluminium", n_modes=20, noise=0.001, magnitude=0.10), {"density_gradient"}),
    "thickness taper 6 %, CFRP 20 modes": (17, "thickness_taper", dict(
        specimen="cfrp", n_modes=20, noise=0.001, magnitude=0.06), {"thickness_taper"}),
    "anticlastic curvature 0.03 /m, 12 modes": (19, "curvature", dict(
        specimen="cfrp", n_modes=12, noise=0.002, magnitude=0.03), {"unattributed", "support_stiffness"}),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", default=None)
    a = ap.parse_args(argv)
    progress.set_quiet(True)
    names = list(CASES) if not a.only else [n for n in CASES if any(o in n for o in a.only.split(","))]
    print("| case | verdict | confusable group | magnitude found (true) | oracle chi^2 | gap before -> after | CPU s |")
    print("|---|---|---|---|---|---|---|")
    for name in names:
        seed, kind, force, expect = CASES[name]
        case = draw(seed, kind, **force)
        t = time.process_time()
        res = run_diagnosis(case.features, names=case.params, prior=case.prior)
        cpu = time.process_time() - t
        lam = oracle(case)
        v = res["verdict"]
        e = next((x for x in res["effects"] if x["name"] == kind), None)
        grp = res["confusable_groups"][0] if res["confusable_groups"] else None
        gtxt = "" if grp is None else " ~ ".join(grp["effects"] + grp["outside_library"])
        mag = f"{e['magnitude']:.4g} +- {e['std']:.2g} ({case.magnitude:.4g})" if e and e.get("std") else "-"
        ok = v in expect or (grp is not None and kind in grp["effects"]) or (v == "none" and lam < VISIBLE)
        g = res["gap"]
        print(f"| {name} | {v}{'' if ok else ' (WRONG)'} | {gtxt} | {mag} | {lam:.1f} | "
              f"{g['before']:.2f} -> {g['after']:.2f} (chi2 {g['chi2_before']:.1f} / {g['threshold_chi2']:.1f}) | "
              f"{cpu:.1f} |", flush=True)
        for note in res["diagnosis_notes"]:
            if note.startswith("under ") and "from the start" in note:
                print(f"|  | flag: {note[:200]} | | | | | |")
        if v == "insufficient_data":
            print(f"|  | too few: {res['advice'][0]} | | | | | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
