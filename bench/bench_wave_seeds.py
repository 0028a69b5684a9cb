"""S0 near 300 kHz over noise seeds: noise or bias (issue 24, session 28).

The sweep of tone bursts (bench/rigs/cfrp_pzt_sweep_2dir_far.toml, 2 shots per burst, the file
-40 %: plate x 1/0.6) and the edge breaks along 0 deg (bench/rigs/cfrp_pencil_edge_0.toml, 36
breaks, the file +40 %: plate x 1/1.4), each over several noise seeds, plus their noise-free
variants (0.1 uV of noise: the error left is the bias). Records: 'independent' (the plate transfer
of bench/independent/legendre_safe.py through the rig's record chain); reference = the TRUE plate's
group velocity from the same independent model (``bench_unknown_plate.reference``).

Every run writes its points to /tmp/h54_seeds/<case>_<seed|quiet|clean>.json and a raw line per
point to <case>_<seed|quiet|clean>.txt (checkpoints: a run already on disk is not run again). ``table`` groups
the points of every seed per curve and per frequency region (the noise-free run's points, each
point to the nearest within 6 %) and prints: the mean error, its standard error, the mean reported
sigma, the rms of the z-scores (error / reported sigma), the noise-free errors ('quiet': noise
0.1 uV as bench_unknown_plate's *_quiet cases; 'clean': also a 24-bit ADC), and per seed how many
points are within 1 %.

Cases: sweep, edge (+40 %), edgesoft (-40 %), edge90, edge90soft, edgelong, edgelongsoft (the 20 / 60 cm
edge rig bench/rigs/cfrp_pencil_edge_0_long.toml, session 28), edgegain, edgegainsoft (the
20 / 40 cm rig with the long rig's 20 dB preamps), edgelongraw, edgelongrawsoft (the 20 / 60 cm rig without its preamps).

Run: OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_wave_seeds.py run [CASE ...] [quiet|clean] [fmax=HZ] [SEEDS...]
     .venv/bin/python bench/bench_wave_seeds.py table [sweep|edge|edgef600 ...]
     .venv/bin/python bench/bench_wave_seeds.py summary [CASE ...]   (one line per curve over the seeds)
     OMP_NUM_THREADS=1 nice .venv/bin/python bench/bench_wave_seeds.py shots BURST_HZ SEED [N] [WAVELET]
(fmax=HZ: the rig's [simulation] wave_fmax_hz replaced; the runs' files are then <case>f<kHz>_*)
"""
from __future__ import annotations

import json
import re
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench._machine import machine  # noqa: E402
from bench_unknown_plate import EDGE_BAND, HERE, curve_vs_truth, records, reference  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from labid.workflows import wave_analysis as analysis  # noqa: E402  (the wave part: its _merge_sweep hook)
from labid.workflows.analysis import AnalysisSettings, wave_features  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402

OUT = Path(os.environ.get("H54_SEEDS", "/tmp/h54_seeds"))
SWEEP = "cfrp_pzt_sweep_2dir_far.toml"
EDGE = "cfrp_pencil_edge_0.toml"
EDGE_LONG = "cfrp_pencil_edge_0_long.toml"    # MFCs 20 / 60 cm (session 28, h58)


def _rig(name: str, variant: str, fmax: float | None = None):
    """The rig file; 'quiet': noise 0.1 uV (bench_unknown_plate's *_quiet); 'clean': also a 24-bit
    ADC (the sweep's 12 bits over +-2 V step by 0.98 mV against its 4-7 mV S0 at 40 cm: without
    noise to dither it the rounding is a deterministic distortion, not a bias of the pick)."""
    text = (HERE / "rigs" / name.split("+")[0].split("-gain")[0]).read_text()
    if variant in ("quiet", "clean"):
        text = text.replace("noise_v = 1.0e-3", "noise_v = 1.0e-7").replace("noise_v = 2.0e-4", "noise_v = 1.0e-7")
    if variant == "clean":
        text = text.replace("adc_bits = 12", "adc_bits = 24").replace("adc_bits = 16", "adc_bits = 24")
    if "+gain20" in name:     # the 20 dB preamp of the 20 / 60 cm rig on another rig (an A/B of the baseline)
        text = text.replace("volts_per_strain = 2.0e5", "volts_per_strain = 2.0e6").replace(
            "level_v = -0.005", "level_v = -0.05")
    if "-gain20" in name:     # the 20 / 60 cm rig without its preamps (the band check on one raw shot)
        text = text.replace("volts_per_strain = 2.0e6", "volts_per_strain = 2.0e5").replace(
            "level_v = -0.05", "level_v = -0.005")
    if fmax:     # the simulator's band (its records' spectrum is tapered to 0 over its top 10 %)
        text = re.sub(r"wave_fmax_hz = [0-9.e+]+", f"wave_fmax_hz = {fmax:.6g}", text)
    return rig_from_text(text, f"bench/rigs/{name}" + ("" if variant == "noisy" else f" ({variant})"))


#: case -> (rig file, shots, truth scale, settings)
CASES = {"sweep": (SWEEP, 10, 1 / 0.6, AnalysisSettings()), "edge": (EDGE, 36, 1 / 1.4, EDGE_BAND),
         # the other edge cases of bench_unknown_plate (already within 1 % on seed 0), to check a
         # change of the simulator's band on them
         "edgesoft": (EDGE, 36, 1 / 0.6, EDGE_BAND), "edge90": ("cfrp_pencil_edge_90.toml", 12, 1 / 1.4, EDGE_BAND),
         "edge90soft": ("cfrp_pencil_edge_90.toml", 12, 1 / 0.6, EDGE_BAND),
         # the 20 / 60 cm baseline along 0 deg (names without '_': table() globs '<case>_*')
         "edgelong": (EDGE_LONG, 36, 1 / 1.4, EDGE_BAND), "edgelongsoft": (EDGE_LONG, 36, 1 / 0.6, EDGE_BAND),
         # the 20 / 40 cm rig with the long rig's 20 dB preamps: what the baseline alone buys
         "edgegain": (EDGE + "+gain20", 36, 1 / 1.4, EDGE_BAND), "edgegainsoft": (EDGE + "+gain20", 36, 1 / 0.6, EDGE_BAND),
         # the 20 / 60 cm rig without its preamps
         "edgelongraw": (EDGE_LONG + "-gain20", 36, 1 / 1.4, EDGE_BAND),
         "edgelongrawsoft": (EDGE_LONG + "-gain20", 36, 1 / 0.6, EDGE_BAND)}


def measure(case: str, seed: int, variant: str, fmax: float | None = None) -> dict:
    """One run: the independent records of the true plate analysed with the file as nominal."""
    name, n, scale, settings = CASES[case]
    spec = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = _rig(name, variant, fmax)
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", scale),)))
    true_lam = truth_laminate(spec.laminate, rig.sim.truth_scale)
    c0, t0 = time.process_time(), time.perf_counter()
    recs = records(rig, spec, n, seed, "independent")
    bursts = []
    merge_sweep = analysis._merge_sweep

    def traced(parts, notes, *rest):
        for fc, (feats, *_rest) in parts:
            for w in feats:
                bursts.append({"burst_hz": fc, "mode": w["mode"], "direction_deg": w["direction_deg"],
                               "frequency_hz": list(w["frequency_hz"]),
                               "group_velocity_m_s": list(w["group_velocity_m_s"]),
                               "sigma_m_s": list(w["sigma_m_s"])})
        return merge_sweep(parts, notes, *rest)
    analysis._merge_sweep = traced
    try:
        feats, *_ = wave_features(recs, rig, spec, settings, [])
    finally:
        analysis._merge_sweep = merge_sweep
    points = []
    for w in feats:
        f, v, s, ref = curve_vs_truth(true_lam, w)
        points += [{"mode": w["mode"], "direction_deg": w["direction_deg"], "f": float(a), "v": float(b),
                    "ref": float(r), "sigma": float(e), "err": float(b / r - 1), "z": float((b - r) / e)}
                   for a, b, e, r in zip(f, v, s, ref)]
    for b in bursts:
        f = np.array(b["frequency_hz"])
        b["ref"] = list(map(float, reference(true_lam, b["direction_deg"], f)[b["mode"]])) if f.size else []
    return {"case": case, "seed": seed, "variant": variant, "fmax": fmax, "quiet": variant != "noisy", "shots": n, "file_off": 1 / scale - 1,
            "cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - t0,
            "load": os.getloadavg()[0], "utc": time.strftime("%H:%M", time.gmtime()),
            "points": points, "bursts": bursts}


def _tag(case, seed, variant, fmax=None):
    return (f"{case}" + (f"f{fmax / 1e3:.0f}" if fmax else "") + f"_{seed if variant == 'noisy' else variant}")


def run(case: str, seed: int, variant: str, fmax: float | None = None) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    tag = _tag(case, seed, variant, fmax)
    if (OUT / f"{tag}.json").exists():
        print(f"{tag}: on disk, skipped", flush=True)
        return
    r = measure(case, seed, variant, fmax)
    lines = [f"# {tag}: {r['shots']} shots, file {100 * r['file_off']:+.0f} %, {r['cpu_s']:.1f} s CPU, "
             f"{r['wall_s']:.1f} s wall, load {r['load']:.1f} at {r['utc']} UTC",
             "# mode dir_deg f_kHz v_m_s ref_m_s err_% sigma_% z"]
    lines += [f"{p['mode']} {p['direction_deg']:g} {p['f'] / 1e3:.2f} {p['v']:.2f} {p['ref']:.2f} "
              f"{100 * p['err']:+.3f} {100 * p['sigma'] / p['ref']:.3f} {p['z']:+.2f}" for p in r["points"]]
    lines += [f"burst {b['burst_hz'] / 1e3:.0f} {b['mode']} {b['direction_deg']:g} {f / 1e3:.2f} "
              f"{100 * (v / rf - 1):+.3f} {100 * s / rf:.3f}"
              for b in r["bursts"] for f, v, s, rf in zip(b["frequency_hz"], b["group_velocity_m_s"],
                                                          b["sigma_m_s"], b["ref"])]
    (OUT / f"{tag}.txt").write_text("\n".join(lines) + "\n")
    (OUT / f"{tag}.json").write_text(json.dumps(r))
    print(lines[0], flush=True)


def _curves(points):
    out: dict = {}
    for p in points:
        out.setdefault((p["mode"], p["direction_deg"]), []).append(p)
    return out


def table(case: str) -> list[str]:
    """The seeds' points of ``case`` per curve and frequency region (markdown rows)."""
    runs = [json.loads(p.read_text()) for p in sorted(OUT.glob(f"{case}_*.json"))]   # case: e.g. 'edgef600'
    for r in runs:
        r.setdefault("variant", "quiet" if r["quiet"] else "noisy")
    ref = {r["variant"]: r for r in runs if r["variant"] != "noisy"}
    noisy = sorted((r for r in runs if not r["quiet"]), key=lambda r: r["seed"])
    if not noisy:
        return [f"{case}: no noisy run on disk"]
    seeds = [r["seed"] for r in noisy]
    base = ref.get("clean") or ref.get("quiet")
    out = [f"**{case}** (file {100 * noisy[0]['file_off']:+.0f} %, {noisy[0]['shots']} shots; seeds {seeds}; "
           f"CPU per run {min(r['cpu_s'] for r in noisy):.0f}-{max(r['cpu_s'] for r in noisy):.0f} s)", "",
           "| curve | region (kHz) | n (seeds) | mean err % | s.e. % | mean sigma % | z rms | mean z | "
           "clean err % | quiet err % | within 1 % |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    allc: dict = {}
    for r in noisy:
        for k, pts in _curves(r["points"]).items():
            allc.setdefault(k, []).extend({**p, "seed": r["seed"]} for p in pts)

    def near(pts, c):
        """the error of the point of ``pts`` nearest c if within 6 %, else None"""
        if not pts:
            return None
        p = min(pts, key=lambda p: abs(np.log(p["f"] / c)))
        return p["err"] if abs(np.log(p["f"] / c)) <= 0.06 else None
    for k in sorted(allc):
        pts = allc[k]
        # regions: the clean (else quiet) run's points; a noisy point joins the nearest within
        # 6 %, else starts a region of its own
        centres = sorted(p["f"] for p in _curves(base["points"]).get(k, [])) if base else []
        for p in sorted(pts, key=lambda p: p["f"]):
            c = min(centres, key=lambda c: abs(np.log(p["f"] / c)), default=None)
            if c is None or abs(np.log(p["f"] / c)) > 0.06:
                centres = sorted(centres + [p["f"]])
        reg: dict = {c: [] for c in centres}
        for p in pts:
            reg[min(centres, key=lambda c: abs(np.log(p["f"] / c)))].append(p)
        refs = {v: _curves(r["points"]).get(k, []) for v, r in ref.items()}
        for c in centres:
            g = reg[c]
            nf = [near(refs.get(v), c) for v in ("clean", "quiet")]
            nf = " | ".join("-" if x is None else f"{100 * x:+.2f}" for x in nf)
            if not g:
                out.append(f"| {k[0]} {k[1]:g} | {c / 1e3:.0f} | 0 | | | | | | {nf} | |")
                continue
            e = np.array([p["err"] for p in g])
            s = np.array([p["sigma"] / p["ref"] for p in g])
            z = np.array([p["z"] for p in g])
            fr = [p["f"] for p in g]
            se = f"{100 * e.std(ddof=1) / np.sqrt(e.size):.2f}" if e.size > 1 else "-"
            inside = sum(abs(x) <= 0.01 for x in e)
            out.append(f"| {k[0]} {k[1]:g} | {min(fr) / 1e3:.0f}-{max(fr) / 1e3:.0f} | {e.size} "
                       f"({len({p['seed'] for p in g})}) | {100 * e.mean():+.2f} | {se} | "
                       f"{100 * s.mean():.2f} | {np.sqrt(np.mean(z ** 2)):.2f} | {z.mean():+.2f} | {nf} | "
                       f"{inside} / {e.size} |")
    out += ["", "per seed, points within 1 %: " + "; ".join(
        f"seed {r['seed']}: " + ", ".join(
            f"{m} {d:g} {sum(abs(p['err']) <= 0.01 for p in pts)} / {len(pts)}"
            for (m, d), pts in sorted(_curves(r["points"]).items()))
        for r in noisy)]
    for v, r in sorted(ref.items()):
        out += ["", f"{v}: " + ", ".join(
            f"{m} {d:g} {sum(abs(p['err']) <= 0.01 for p in pts)} / {len(pts)} "
            f"({100 * min(p['err'] for p in pts):+.2f} .. {100 * max(p['err'] for p in pts):+.2f} %)"
            for (m, d), pts in sorted(_curves(r["points"]).items())) + f" ({r['cpu_s']:.0f} s CPU)"]
    return out


def summary(case: str) -> str:
    """One line per curve of ``case`` over its noisy seeds: points within 1 %, seeds with every
    point within 1 %, the error range, the rms of the z-scores, the reported sigma's range."""
    runs = sorted((json.loads(p.read_text()) for p in OUT.glob(f"{case}_*.json")), key=lambda r: r["seed"])
    noisy = [r for r in runs if not r["quiet"]]
    out = []
    for k in sorted({k for r in noisy for k in _curves(r["points"])}):
        per = [_curves(r["points"]).get(k, []) for r in noisy]
        pts = [p for ps in per for p in ps]
        e = np.array([p["err"] for p in pts]) * 100
        z = np.array([p["z"] for p in pts])
        s = np.array([p["sigma"] / p["ref"] for p in pts]) * 100
        out.append(f"{case} {k[0]} {k[1]:g} deg, seeds {[r['seed'] for r in noisy]}: "
                   f"{int(np.sum(np.abs(e) <= 1))} / {e.size} points within 1 %, "
                   f"{sum(bool(ps) and all(abs(p['err']) <= 0.01 for p in ps) for ps in per)} / {len(per)} seeds all "
                   f"within (points per seed {min(map(len, per))}-{max(map(len, per))}); err {e.min():+.2f} .. "
                   f"{e.max():+.2f} %, z rms {np.sqrt(np.mean(z ** 2)):.2f}, sigma {s.min():.2f} .. {s.max():.2f} % "
                   f"(median {np.median(s):.2f})" if e.size else f"{case} {k[0]} {k[1]:g}: no point")
    return "\n".join(out) or f"{case}: no noisy run on disk"


def shots(fb: float, seed: int, n: int = 12, wl_name: str = "all") -> None:
    """Per-shot S0 0 deg picks of ONE burst of the sweep rig (file -40 %; the rig with that burst
    alone, so only its records are synthesised): per analysis frequency of each wavelet measured
    on all shots, the shots' mean delay error against the true plate (0.4 m / legendre_safe's
    group velocity), its standard error, the shots' scatter, the mean sigma a shot reports and
    their ratio, the median far SNR and instantaneous frequency. The tracing follows
    bench_sweep_shots.py (h51 / h53, session 27); the hook is bench/s0_trace.py's, shared with it
    (session 29); raw lines to OUT / shots_<kHz>_<seed>.txt."""
    from bench.s0_trace import by_wavelet, s0_picks   # noqa: PLC0415 - this subcommand only
    from engine.waves import Wavelet   # noqa: PLC0415
    spec = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    rig = _rig(SWEEP, "noisy")
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", 1 / 0.6),)),
                  wave_source=replace(rig.wave_source, burst=rig.wave_source.burst.at(fb)))
    true = truth_laminate(spec.laminate, rig.sim.truth_scale)
    c0 = time.process_time()
    recs = records(rig, spec, n, seed, "independent")
    forced = Wavelet.from_name(wl_name, None)     # a wavelet named: the analysis uses it alone
    settings = AnalysisSettings(wavelet=(forced.bandwidth, forced.center)) if forced else AnalysisSettings()
    with s0_picks(wl_name) as log:
        feats = analysis._wave_features_one(recs, rig, spec, settings, [])[0]
    lines = [f"# burst {fb / 1e3:g} kHz, seed {seed}, {n} shots, {time.process_time() - c0:.1f} s CPU, "
             f"load {os.getloadavg()[0]:.1f} at {time.strftime('%H:%M', time.gmtime())} UTC"]
    for w in (w for w in feats if w["mode"] == "S0" and w["direction_deg"] == 0.0):
        f, v, sg = (np.array(w[k]) for k in ("frequency_hz", "group_velocity_m_s", "sigma_m_s"))
        ref = reference(true, 0.0, f)["S0"]
        lines.append("points: " + ", ".join(f"{a / 1e3:.1f} kHz {100 * (b / r - 1):+.2f} % (sigma {100 * e / r:.2f} %)"
                                            for a, b, e, r in zip(f, v, sg, ref)))
    for name, ent in by_wavelet(log).items():
        D, S, V, SNR, FI = (np.array([getattr(x, k) for x in ent]) for k in ("delay", "sigma", "valid", "snr_db", "finst"))
        F = ent[0].freqs
        exp = 0.4 / reference(true, 0.0, F)["S0"]
        lines.append(f"{name}, {D.shape[0]} shots: f kHz | n | mean delay err us (s.e.) | % of the delay | scatter us"
                     " | mean sigma us | scatter / sigma | far SNR dB | finst kHz")
        for i in np.flatnonzero(V.sum(axis=0) >= max(3, n // 2)):
            m = V[:, i]
            dd = D[m, i] - exp[i]
            sc = dd.std(ddof=1)
            lines.append(f"  {F[i] / 1e3:6.1f} | {m.sum():2d} | {1e6 * dd.mean():+6.3f} ({1e6 * sc / np.sqrt(m.sum()):.3f}) | "
                         f"{-100 * dd.mean() / exp[i]:+.2f} | {1e6 * sc:5.3f} | {1e6 * S[m, i].mean():5.3f} | "
                         f"{sc / S[m, i].mean():4.2f} | {np.median(SNR[m, i]):.1f} | {np.median(FI[m, i]) / 1e3:.1f}")
    OUT.mkdir(parents=True, exist_ok=True)
    print("\n".join(lines), flush=True)
    tag = f"shots_{fb / 1e3:.0f}_{seed}" + ("" if wl_name == "all" else f"_{wl_name}")
    (OUT / f"{tag}.txt").write_text("\n".join(lines) + "\n")


def main(argv) -> None:
    if argv and argv[0] == "shots":      # shots BURST_HZ SEED [N] [WAVELET]
        shots(float(argv[1]), int(argv[2]), int(argv[3]) if len(argv) > 3 else 12,
              argv[4] if len(argv) > 4 else "all")
        return
    if argv and argv[0] == "summary":
        for case in argv[1:] or list(CASES):
            print(summary(case))
        return
    if argv and argv[0] == "table":
        for case in argv[1:] or list(CASES):
            print("\n".join(table(case)) + "\n")
        return
    print(f"machine: {machine()}", flush=True)
    cases = [a for a in argv if a in CASES] or ["sweep", "edge"]
    variant = next((a for a in argv if a in ("quiet", "clean")), "noisy")
    seeds = [int(a) for a in argv if a.isdigit()] or list(range(5))
    fmax = next((float(a[5:]) for a in argv if a.startswith("fmax=")), None)
    for seed in (seeds if variant == "noisy" else [0]):
        for case in cases:
            run(case, seed, variant, fmax)


if __name__ == "__main__":
    main(sys.argv[1:])
