"""labid identify on Badiane et al.'s measured spruce plates against the authors' own constants.

The peaks are those labid picked from the authors' hammer records (bench/gap_real.py,
issue 16's import); the reference constants, geometry and density are the authors'
published identification of the same plates (repository David-Badiane/Data-driven-
characterization-of-spruce-tonewood-plates, FRF2Params/csv_gPlates/Results/Results_N_nR10_12.csv,
first row: rho, Ex, Ey, Ez, Gxy, Gyz, Gxz, vxy, vyz, vxz, alpha, beta, L, W, T), obtained by
the authors' FE model + neural-network inversion of the FRFs. labid fits E1, E2, G12 (nu12,
G13, G23 and the geometry held at the authors' values) from a generic spruce start
(E1 10, E2 0.7, G12 0.6 GPa), sigma 1 % per peak, one accelerometer at an assumed corner
point (the response point is not published with the peaks).

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/badiane_authors.py
"""
from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.gap_real import PEAKS, SIGMA_REL  # noqa: E402
from labid.cli.main import main  # noqa: E402

#: the authors' Results_N first rows (SI): rho, Ex, Ey, Ez, Gxy, Gyz, Gxz, vxy, vyz, vxz, L, W, T
AUTHORS = {
    1: dict(rho=394.1, E1=7806267619.39118, E2=801411893.121048, E3=732487202.831029, G12=537989082.277525,
            G23=35784098.1770952, G13=629662228.443778, nu12=0.139078158339513, nu23=0.81090750865513,
            nu13=0.399796017046574, L=0.58, W=0.213, T=0.005),
    5: dict(rho=405.777442647464, E1=9012584052.55657, E2=906370139.722527, E3=472829185.624929,
            G12=887955489.423887, G23=22979587.7027611, G13=435255476.459494, nu12=0.228745527773513,
            nu23=0.646510240428067, nu13=0.722927121017746, L=0.58, W=0.2172, T=0.0046),
    9: dict(rho=426.3, E1=11479871744.8637, E2=545533330.576246, E3=400872618.618883, G12=740104701.904243,
            G23=25037762.9094724, G13=544400073.727895, nu12=0.357678071716888, nu23=0.704390235897506,
            nu13=0.488237500043241, L=0.581, W=0.218, T=0.005),
}
START = "E1=10e9,E2=0.7e9,G12=0.6e9"


def specimen(a: dict, plate: int) -> str:
    return f'''name = "spruce plate {plate} (Badiane et al., the authors' geometry and constants)"
[plate]
length = {a["L"]}
width = {a["W"]}
[materials.spruce]
density = {a["rho"]}
E1 = {a["E1"]}
E2 = {a["E2"]}
nu12 = {a["nu12"]}
G12 = {a["G12"]}
G13 = {a["G13"]}
G23 = {a["G23"]}
E3 = {a["E3"]}
nu13 = {a["nu13"]}
nu23 = {a["nu23"]}
[layup]
material = "spruce"
angles_deg = [0]
ply_thickness = {a["T"]}
'''


def main_() -> int:
    print("| plate | peaks | labid fit | E1 GPa (authors) | E2 GPa (authors) | G12 GPa (authors) | unpaired peaks |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as td:
        for plate, a in AUTHORS.items():
            sp = Path(td) / f"plate{plate}.toml"
            sp.write_text(specimen(a, plate))
            f = PEAKS[plate]
            fp = Path(td) / f"plate{plate}.json"
            fp.write_text(json.dumps({"specimen": str(sp), "modal": {
                "frequencies_hz": f, "sigma_hz": [SIGMA_REL * v for v in f]},
                "rig": {"accelerometers": [{"x": 0.03, "y": 0.03}]}}))
            out = Path(td) / f"id{plate}.json"
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                code = main(["identify", str(fp), "--params", "E1,E2,G12", "--start", START, "--json", str(out),
                             "--quiet"])
            if code != 0 or not out.exists():
                print(f"| {plate} | {len(f)} | exit {code} | | | | |")
                continue
            r = json.loads(out.read_text())
            p, fit = r["parameters"], r["fit"]
            un = sum(1 for x in r.get("pairing") or [] if x.get("mode_index") is None)

            def cell(n):
                v, s = p[n]["value"], p[n]["std"]
                return f"{v / 1e9:.3g} +- {s / 1e9:.2g} ({a[n] / 1e9:.3g}, {100 * (v / a[n] - 1):+.0f} %)"
            verdict = "consistent" if fit["consistent"] else "INCONSISTENT"
            print(f"| {plate} | {len(f)} | {verdict}, chi2/nu {fit['chi2_per_dof']:.2g} | {cell('E1')} | "
                  f"{cell('E2')} | {cell('G12')} | {un} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
