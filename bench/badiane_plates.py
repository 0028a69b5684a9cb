"""labid identify and diagnose on Badiane et al.'s spruce plates against the authors' constants (h4).

Data: bench/import_real/badiane_plates.json (sources, commit ids and how the peaks were picked are
in it). The authors' identified constants of plates 1, 3-10 (Results_N_nR10_12.csv; plate 2 has
none in the repository), measured peak lists for plates 1, 5, 9 only (labid's picks from the
authors' hammer records; the other records could not be brought here), and the peaks of the
authors' own FE model FRF of plate 9 at their constants (FRF_Results_9...csv), a model-vs-model
check: labid's plate model fitted to the authors' model's resonances should return the authors'
E1, E2, G12 if both models agree.

Each case: ``labid identify --params E1,E2,G12`` (the authors' geometry, density and other
constants held; start E1 10, E2 0.7, G12 0.6 GPa; sigma 1 % per peak; one accelerometer at the
assumed (0.03, 0.03) m: neither the records nor the repository's csv files state the points),
then ``labid diagnose`` with the same options from that estimate (``--estimate``).

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/badiane_plates.py
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.badiane_authors import START, specimen  # noqa: E402
from labid.cli.main import main  # noqa: E402

DATA = ROOT / "bench" / "import_real" / "badiane_plates.json"
SIGMA_REL = 0.01
NAMES = ("E1", "E2", "G12")


def parabola_peak(triplet: list) -> float:
    """Peak frequency (Hz): vertex of the parabola through (log f, log|H|) at three grid points."""
    x = [math.log(f) for f, _, _ in triplet]
    y = [math.log(math.hypot(re, im)) for _, re, im in triplet]
    d1, d2 = (y[1] - y[0]) / (x[1] - x[0]), (y[2] - y[1]) / (x[2] - x[1])
    a = (d2 - d1) / (x[2] - x[0])
    return math.exp(0.5 * (x[0] + x[1]) - d1 / (2 * a) if a else x[1])


def cases(data: dict) -> list[tuple[str, int, list[float], str]]:
    """(label, plate, peaks Hz, which authors' version holds the fixed constants) for every plate with
    the authors' constants and a peak list. Measured peaks: the index's default version ("authors",
    as bench/badiane_authors.py); the model FRF: the version it was computed with."""
    out = []
    for key, d in data["plates"].items():
        if d.get("authors") and d.get("measured_peaks_hz"):
            out.append(("measured", int(key), d["measured_peaks_hz"], "authors"))
        if d.get("authors") and d.get("model_frf"):
            out.append(("authors' model FRF", int(key),
                        [round(parabola_peak(t), 2) for t in d["model_frf"]["triplets_f_re_im"]],
                        "authors_other_version"))
    return out


def labid_modes(spec: Path, n: int, td: str) -> list[float]:
    """labid's free-free frequencies (Hz) of a specimen file (``labid modes``)."""
    out = Path(td) / "modes.json"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        main(["modes", str(spec), "--n", str(n), "--json", str(out), "--quiet"])
    r = json.loads(out.read_text())
    return r["frequencies_hz"]


def run(cmd: list[str], out: Path) -> tuple[int, dict, float]:
    t = time.process_time()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(cmd + ["--json", str(out), "--quiet"])
    return code, (json.loads(out.read_text()) if out.exists() else {}), time.process_time() - t


def main_() -> int:
    data = json.loads(DATA.read_text())
    print("| plate | peaks from | n | identify | E1 GPa (authors', CV %) | E2 GPa (authors', CV %) | "
          "G12 GPa (authors', CV %) | diagnose | where (first) | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as td:
        notes = []
        for label, plate, f, version in cases(data):
            auth = data["plates"][str(plate)][version]
            other = data["plates"][str(plate)].get("authors_other_version" if version == "authors" else "authors")
            c, cv = auth["constants_si"], auth["second_row"]
            sp = Path(td) / f"p{plate}.toml"
            sp.write_text(specimen(c, plate))
            fp = Path(td) / f"p{plate}{len(label)}.json"
            fp.write_text(json.dumps({"specimen": str(sp), "modal": {
                "frequencies_hz": f, "sigma_hz": [SIGMA_REL * v for v in f]},
                "rig": {"accelerometers": [{"x": 0.03, "y": 0.03}]}}))
            opts = ["--params", ",".join(NAMES), "--start", START]
            idj = Path(td) / f"id{plate}{len(label)}.json"
            code, r, cpu1 = run(["identify", str(fp)] + opts, idj)
            if code not in (0, 3) or not r:
                print(f"| {plate} | {label} | {len(f)} | exit {code} | | | | | | {cpu1:.1f} |")
                continue
            p, fit = r["parameters"], r["fit"]
            flags = fit.get("flags") or []
            un = sum(1 for x in r.get("pairing") or [] if x.get("mode_index") is None)
            verdict = ("consistent" if fit["consistent"] else "INCONSISTENT") + f", chi2/nu {fit['chi2_per_dof']:.2g}"
            if un:
                verdict += f", {un} unpaired"
            if flags:
                verdict += ", flags: " + "; ".join(str(x) for x in flags)

            def cell(n: str) -> str:
                v, s = p[n]["value"], p[n]["std"]
                z = (v - c[n]) / s if s else float("inf")
                idf = "" if p[n].get("identified", True) else " NOT identified"
                return (f"{v / 1e9:.3g} +- {s / 1e9:.2g} ({c[n] / 1e9:.3g}, {cv[n]:.3g}; "
                        f"{100 * (v / c[n] - 1):+.0f} %, {z:+.1f} std){idf}")
            dj = Path(td) / f"dg{plate}{len(label)}.json"
            dcode, dg, cpu2 = run(["diagnose", str(fp)] + opts + ["--estimate", str(idj)], dj)
            dv = dg.get("verdict", f"exit {dcode}")
            where = (dg.get("where") or [""])[0]
            print(f"| {plate} | {label} | {len(f)} | {verdict} | {cell('E1')} | {cell('E2')} | {cell('G12')} | "
                  f"{dv} | {where} | {cpu1 + cpu2:.1f} |")
            print(f"|  | peaks Hz: {', '.join(f'{x:g}' for x in f)} | | | | | | | | |")
            vs = f"held and compared: commit {auth['commit'][:7]}"
            if other:
                vs += f"; against commit {other['commit'][:7]}: " + ", ".join(
                    f"{n} {100 * (p[n]['value'] / other['constants_si'][n] - 1):+.0f} % "
                    f"({(p[n]['value'] - other['constants_si'][n]) / p[n]['std']:+.1f} std)" for n in NAMES)
            print(f"|  | {vs} | | | | | | | | |")
            if label != "measured":
                m = sorted(labid_modes(sp, 2 * len(f), td))
                near = [min(m, key=lambda x: abs(x - v)) for v in f]
                notes.append(f"plate {plate}: labid modes at commit {auth['commit'][:7]}'s constants vs the peaks of "
                             f"the authors' model FRF: " + ", ".join(f"{v:g}->{x:.2f} ({100 * (x / v - 1):+.1f} %)"
                                                                      for v, x in zip(f, near)))
        for line in notes:
            print("\n" + line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
