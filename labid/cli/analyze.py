"""``labid analyze``: peak picking and CWT group velocities from the raw records of a run.

Writes the features file (CONTRACT section 2; default ``RUN.features.json``
next to the run; ``analysis.run`` is the run file relative to it) and stores
features, picks and curves in the run file (``/results/analysis``). The
``--json`` result is the features document.
"""
from __future__ import annotations

import re

from ..base import progress
from .. import services
from .options import MAX_WAVELET, add_json_option, bounded
from ..base.errors import UserError
from ..base.summary import modes_table, stream

_PAIR = re.compile(r"^\s*([0-9.eE+-]+)\s*[,:-]\s*([0-9.eE+-]+)\s*$")


def register(sub) -> None:
    p = sub.add_parser("analyze", help="resonance peaks and CWT group velocities of a run -> features",
                       description=__doc__.splitlines()[0])
    p.add_argument("run", metavar="RUN.h5", help="run file written by labid acquire")
    p.add_argument("--out", default=None, metavar="FEATURES.json",
                   help="features file to write (default: RUN.features.json beside the run)")
    p.add_argument("--modal-fmax", type=bounded(float, 0.0, 1e10, "a frequency in Hz"), default=None, metavar="HZ",
                   help="top of the resonance search band (default 0.4 x sample rate)")
    p.add_argument("--exp-window", type=bounded(float, 0.0, 1e6, "a time constant in s"), default=None, metavar="TAU_S",
                   help="exponential window time constant on the hammer records (damping corrected)")
    p.add_argument("--wavelet", default=None, metavar="B,C",
                   help="complex Morlet bandwidth and centre (default: 2,1 isotropic; 2,5 laminate)")
    p.add_argument("--wave-band", default=None, metavar="FMIN,FMAX",
                   help="CWT frequency band in Hz (default fmax/20..fmax, fmax 50 kHz / 200 kHz)")
    p.add_argument("--nominal", action="store_true",
                   help="assign arrivals to the nominal wavelet frequency, as in the paper "
                        "(default: reassigned and bias-corrected, docs/wavelet-bias.md)")
    p.add_argument("--with-s0", action="store_true",
                   help="(default now) S0 group velocities go into the features whenever measured")
    p.add_argument("--without-s0", action="store_true",
                   help="keep the S0 group velocities out of the features (always stored in the run)")
    p.add_argument("--pair-residue", default=None, metavar="OTHER.h5",
                   help="the run of the other mode of a collocated actuator pair (same sensors): the copy of "
                        "that mode left in this run's records is measured at the far sensor and removed")
    p.add_argument("--iterate", type=int, nargs="?", const=4, default=0, metavar="N",
                   help="pick <-> identify: identify the constants, redo the wave picks with them, until "
                        "the picks and the constants stop moving (at most N rounds, default 4); recorded in "
                        "analysis.iterations")
    p.add_argument("--iterate-params", default=None, metavar="P1,P2,..",
                   help="the constants identified in each round (default: identify's choice)")
    add_json_option(p)
    p.set_defaults(func=run)


def _pair(text: str, key: str, hi: float = float("inf")) -> tuple[float, float]:
    m = _PAIR.match(text)
    try:
        a, b = (float(m.group(1)), float(m.group(2))) if m else (None, None)
    except ValueError:
        a = b = None
    if a is None or not (0 < a <= hi and 0 < b <= hi):
        raise UserError(f"value {text!r}: expected two positive numbers 'A,B' of at most {hi:g}", key=key)
    return a, b


def run(args) -> dict:
    if args.modal_fmax is not None and not args.modal_fmax > 0:
        raise UserError(f"value {args.modal_fmax!r}: expected a positive frequency in Hz", key="--modal-fmax")
    if args.exp_window is not None and not args.exp_window > 0:
        raise UserError(f"value {args.exp_window!r}: expected a positive time constant in s", key="--exp-window")
    wavelet = _pair(args.wavelet, "--wavelet", 20.0) if args.wavelet else None    # before any work
    if wavelet and wavelet[0] * wavelet[1] > MAX_WAVELET:
        raise UserError(f"value {args.wavelet!r}: bandwidth x centre {wavelet[0] * wavelet[1]:g}; expected at most "
                        f"{MAX_WAVELET:g} (the transform's memory grows with it)", key="--wavelet")
    band = _pair(args.wave_band, "--wave-band", 1e10) if args.wave_band else None
    if band and not band[0] < band[1]:
        raise UserError(f"value {args.wave_band!r}: expected FMIN < FMAX", key="--wave-band")
    settings = services.AnalysisSettings(
        modal_fmax_hz=args.modal_fmax, exp_tau_s=args.exp_window,
        wavelet=wavelet,
        wave_band_hz=band, assign="nominal" if args.nominal else "instantaneous",
        report_s0=not args.without_s0, pair_residue_run=args.pair_residue)
    out_path = args.out or str(services.features_path(args.run))
    if progress.enabled():      # a terminal: say what the next seconds are for
        progress.note(f"labid analyze: {args.run}: resonance peaks and CWT group velocities")
    if args.iterate < 0 or args.iterate > 20:
        raise UserError(f"value {args.iterate}: expected 1 to 20 rounds", key="--iterate")
    names = [n.strip() for n in args.iterate_params.split(",") if n.strip()] if args.iterate_params else None
    feats = services.run_analysis(args.run, settings, out=args.out, iterate=args.iterate,
                                  iterate_params=names).features
    w = stream(args)
    if w is not None:
        m = feats.get("modal") or {}
        fr = m.get("frequencies_hz", [])
        waves = feats.get("waves", []) or []
        waves = [waves] if isinstance(waves, dict) else waves
        n_w = sum(len(x.get("frequency_hz", [])) for x in waves)
        if fr:
            w.write(modes_table(fr, sigma_hz=m.get("sigma_hz")))
        for x in waves:
            f = x["frequency_hz"]
            dropped = ", ".join(f"{k} x{n}" for k, n in sorted(x.get("dropped", {}).items(), key=lambda t: -t[1]))
            w.write(f"{x['mode']} {x['direction_deg']:g} deg: {len(f)} velocities, "
                    f"{f[0] / 1e3:.3g}-{f[-1] / 1e3:.3g} kHz" + (f"; dropped: {dropped}" if dropped else "") + "\n")
        for mm in feats.get("analysis", {}).get("nominal_mismatch", []):
            w.write("warning: " + mm["message"] + "\n")
        iterated = bool(feats.get("analysis", {}).get("iterations"))
        for note in feats.get("analysis", {}).get("notes", []):
            if note.startswith("pick <-> identify"):
                w.write(note + "\n")
            if iterated and not note.startswith("after identification"):
                continue                         # the first round's drops: superseded
            note = note.split(": ", 1)[1] if note.startswith("after identification") else note
            if note.startswith("no velocity") or "not reported" in note:
                w.write("dropped: " + note + "\n")
            if note.startswith("more shots"):
                w.write(note + "\n")
        if args.without_s0:
            w.write("S0: kept out of the features (--without-s0); stored in the run file only\n")
        w.write(f"features: {out_path} ({len(fr)} resonances, {n_w} group-velocity points)\n")
        w.write(f"stored in: {args.run} (/results/analysis)\n")
        w.write("next: labid identify " + out_path + "\n")
    return feats
