"""Gap diagnosis on published measured peak lists of free plates (issue 13).

Badiane et al.'s spruce plates 1, 5 and 9 (hammer tests of free wooden plates, the authors'
CSV records imported and peak-picked by ``labid import`` + ``labid analyze``; the peaks below
are those recorded in bench/RESULTS.md "Import of published records (issue 16)"), with the
specimen files of ``bench/import_real/`` (geometry and density from the authors'
geomParams.csv; nominal spruce constants). Each plate's first peaks, sigma 1 % (as a new user
would state it), one accelerometer at the rig file's assumed point (0.03, 0.03) m, mass unknown
(not in the model). Runs ``labid diagnose --params E1,E2,G12`` and ``labid identify --params
E1,E2,G12`` on each and prints verdict, gap, chi^2 and the where/pairing findings.

Run:  OMP_NUM_THREADS=1 .venv/bin/python bench/gap_real.py
"""
from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from labid.cli.main import main  # noqa: E402

#: peaks (Hz) picked by labid analyze from the authors' records (bench/RESULTS.md, issue 16)
PEAKS = {
    1: [47.14, 70.58, 120.48, 132.93, 174.36, 199.70, 243.48, 263.02, 333.30, 383.35],
    5: [58.83, 70.06, 129.48, 178.53, 185.39, 242.57, 245.69, 265.48],
    9: [56.79, 80.82, 140.25, 162.75, 192.46, 195.56, 221.05, 276.08],
}
SIGMA_REL = 0.01
NAMES = "E1,E2,G12"


def features(plate: int) -> dict:
    f = PEAKS[plate]
    return {"specimen": str(ROOT / "bench" / "import_real" / f"badiane_plate{plate}.toml"),
            "modal": {"frequencies_hz": f, "sigma_hz": [SIGMA_REL * v for v in f]},
            "rig": {"accelerometers": [{"x": 0.03, "y": 0.03}]}}


def run(cmd: list[str]) -> tuple[int, dict, float]:
    t = time.process_time()
    with tempfile.TemporaryDirectory() as td:
        out = Path(td) / "r.json"
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = main(cmd + ["--json", str(out), "--quiet"])
        res = json.loads(out.read_text()) if out.exists() else {}
    return code, res, time.process_time() - t


def main_() -> int:
    print("| plate | peaks | identify chi^2/n (paired peaks) | identify fit | diagnose verdict | gap before -> after | "
          "chi^2 / threshold | top candidate | where (first) | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as td:
        for plate in PEAKS:
            fp = Path(td) / f"plate{plate}.json"
            fp.write_text(json.dumps(features(plate)))
            _, ident, _ = run(["identify", str(fp), "--params", NAMES])
            chi = None
            if ident.get("blocks"):      # with the stated 1 % sigmas (before any Birge scaling)
                chi = sum(sum(((p_ - o) / (SIGMA_REL * o)) ** 2 for p_, o in zip(b["predicted"], b["observed"]))
                          for b in ident["blocks"].values())
            code, res, cpu = run(["diagnose", str(fp), "--params", NAMES])
            if code != 0:
                print(f"| {plate} | {len(PEAKS[plate])} | | | exit {code} | | | | | {cpu:.1f} |")
                continue
            g = res["gap"]
            top = res["effects"][0] if res["effects"] else None
            tops = f"{top['name']} {top['magnitude']:.3g} {top['unit']}" if top else ""
            where = res["where"][0] if res["where"] else ""
            chin = f"{chi / len(PEAKS[plate]):.2f}" if chi is not None else "?"
            fit = ident.get("fit") or {}
            un = sum(1 for r in ident.get("pairing") or [] if r.get("mode_index") is None)
            fits = ("consistent" if fit.get("consistent") else "INCONSISTENT") + (f", {un} peaks unpaired" if un else "")
            print(f"| {plate} | {len(PEAKS[plate])} | {chin} | {fits} | {res['verdict']} | {g['before']:.2f} -> "
                  f"{g['after']:.2f} | {g['chi2_before']:.1f} / {g['threshold_chi2']:.1f} | {tops} | "
                  f"{where} | {cpu:.1f} |")
            if res.get("pairing"):
                print(f"|  | pairing: {'; '.join(res['pairing']['findings'][:3])} | | | | | | | | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
