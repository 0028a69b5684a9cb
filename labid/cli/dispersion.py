"""``labid dispersion``: guided-wave dispersion curves of a specimen (SAFE).

Frequency grid ``f_i = i * F / N``, i = 1..N (CONTRACT section 3). Result
(``--json``): ``modes``, a list of ``{label, frequency_hz, phase_velocity_m_s,
group_velocity_m_s}`` (also ``wavenumber_rad_m`` and ``cutoff_hz``), in the
order A0, S0, SH0, then by cut-off. For each mode only the grid frequencies
where the mode exists are listed (no nulls); the lists of one mode have
equal lengths. Also ``specimen``, ``direction_deg``, ``fmax_hz``, ``n`` and the
discretisation (``order``, ``elements_per_ply``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.safe import SafeError, dispersion_from_model, safe_model

from ..base import atomic, progress
from .options import MAX_FREQUENCIES, add_json_option, bounded, count
from ..base.errors import UserError
from ..inputs.limits import check_fmax
from ..inputs.specimen import load_specimen
from ..base.summary import dispersion_table, eng, stream


def register(sub) -> None:
    p = sub.add_parser("dispersion", help="guided-wave dispersion curves (SAFE)",
                       description=__doc__.splitlines()[0])
    p.add_argument("spec", metavar="SPEC.toml",
                   help="specimen file, or a built-in name ('cfrp', 'aluminium')")
    p.add_argument("--fmax", type=bounded(float, 0.0, 1e12, "a frequency in Hz"), required=True, metavar="F",
                   help="highest frequency, Hz")
    p.add_argument("--n", type=count(MAX_FREQUENCIES, "a number of frequencies", 1), default=200, metavar="N",
                   help="number of frequencies (default 200)")
    p.add_argument("--direction-deg", type=bounded(float, -360.0, 360.0, "an angle in degrees"), default=0.0, metavar="D",
                   help="propagation direction from the x axis, degrees (default 0)")
    p.add_argument("--plot", metavar="PNG", default=None, help="write phase and group velocity plots")
    add_json_option(p)
    p.set_defaults(func=run)


def _check(args) -> None:
    if not (np.isfinite(args.fmax) and args.fmax > 0):
        raise UserError(f"value {args.fmax!r}: expected a positive frequency in Hz", key="--fmax")
    if not 1 <= args.n <= 100000:
        raise UserError(f"value {args.n!r}: expected a number of frequencies in 1..100000", key="--n")
    if not np.isfinite(args.direction_deg):
        raise UserError(f"value {args.direction_deg!r}: expected a finite angle in degrees",
                        key="--direction-deg")


def run(args) -> dict:
    _check(args)
    spec = load_specimen(args.spec)
    check_fmax(spec.laminate, args.fmax)          # what the SAFE model can hold (issue 15)
    f = np.arange(1, args.n + 1) * args.fmax / args.n
    if args.n >= 50 and progress.enabled():     # a few seconds of SAFE solves: say what for
        progress.note(f"labid dispersion: SAFE model of {spec.name}, {args.n} frequencies up to {args.fmax:g} Hz")
    try:
        model = safe_model(spec.laminate, args.direction_deg, fmax_hz=args.fmax)
        d = dispersion_from_model(model, f)
    except SafeError as e:
        raise UserError(str(e), file=spec.source) from None
    modes = []
    for m in d.modes:
        ok = np.isfinite(m.wavenumber_rad_m) & np.isfinite(m.group_velocity_m_s)
        modes.append({
            "label": m.label,
            "cutoff_hz": m.cutoff_hz,
            "frequency_hz": m.frequency_hz[ok].tolist(),
            "phase_velocity_m_s": m.phase_velocity_m_s[ok].tolist(),
            "group_velocity_m_s": m.group_velocity_m_s[ok].tolist(),
            "wavenumber_rad_m": m.wavenumber_rad_m[ok].tolist(),
        })
    if args.plot:
        _plot(d, spec.name, args.plot)
    out = stream(args)
    if out is not None:
        out.write(f"{spec.name}: guided-wave modes along {args.direction_deg:g}°, {args.n} frequencies "
                  f"{eng(f[0], 'Hz')} to {eng(args.fmax, 'Hz')} (SAFE, order {model.order}, {model.elements_per_ply} "
                  f"element(s) per ply)\n")
        out.write(dispersion_table(modes))
        written = [x for x in (args.plot, getattr(args, "json", None)) if x]
        out.write(("written: " + ", ".join(written)) if written else
                  "curves not saved: add --json FILE (numbers) or --plot FILE.png (figure)")
        out.write("\n")
    return {"specimen": spec.name, "direction_deg": args.direction_deg, "fmax_hz": args.fmax,
            "n": args.n, "order": model.order, "elements_per_ply": model.elements_per_ply,
            "modes": modes}


def _plot(d, title: str, path: str) -> None:
    # matplotlib only with --plot: 0.3 s of imports the curves alone do not need
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharex=True)
    for m in d.modes:
        f_khz = m.frequency_hz / 1e3
        ln, = axes[0].plot(f_khz, m.phase_velocity_m_s, lw=1.4, label=m.label)
        axes[1].plot(f_khz, m.group_velocity_m_s, lw=1.4, color=ln.get_color())
    axes[0].set_ylabel("phase velocity (m/s)")
    axes[1].set_ylabel("group velocity (m/s)")
    for ax in axes:
        ax.set_xlabel("frequency (kHz)")
        ax.grid(alpha=0.3)
        ax.set_xlim(0, d.frequency_hz.max() / 1e3)
        ax.set_ylim(bottom=0)
    axes[0].legend(fontsize=8, ncol=2)
    fig.suptitle(f"{title} — SAFE dispersion, direction {d.direction_deg:g}°")
    fig.tight_layout()
    fmt = Path(path).suffix[1:].lower() or "png"
    try:
        with atomic.replacing(path, key="--plot") as tmp:     # temp + rename: never half a PNG (issue 27)
            try:
                fig.savefig(tmp, dpi=110, format=fmt)
            except ValueError as e:                        # an unknown format
                raise UserError(f"cannot write a figure ({e})", file=path, key="--plot") from None
    finally:
        plt.close(fig)
