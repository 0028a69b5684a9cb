"""Issue 24, sessions 25-26 (h41, h42): the edge break's S0 bias along 0 deg and the record synthesis.

The edge break's S0 picks along 0 deg on the plate 40 % stiffer than the file were +1.4 / +1.6 %
off at 66 / 91 kHz with sigmas ~0.4 % (bench_unknown_plate.py ``edge``, session 25). This bench
builds the reflection-free, noise-free S0 strain at the rig's two sensors (20 / 40 cm along the
force) from the INDEPENDENT model's transfer (bench/independent/legendre_safe.py, load 'inplane';
no engine.safe), for the rig's 1 us lead-break step, in these ways:

* 'ideal': the transfer's own time response, the source 200 us into a long FFT period (nothing cut);
* 'far field': the same with the strain kernel's H1(kr) replaced by its large-kr form (exact pick);
* 'rig chain': the rig's own synthesis ``mock_hw.waves._wave_fine`` (session 26: the source
  ``SOURCE_PAD_S`` into the FFT period, causality cut at that pad + 0.95 r / c_max);
* 'old chain': the same function with the pad set to 0 (the synthesis before session 26: the
  source at the period's first sample, the cut at 0.95 r / c_max);
* 'numpy': each signal also by a zero-phase Butterworth band-pass (+-15 %) and the Hilbert
  envelope's peak (scipy only), as a second estimate beside labid's CWT ridge (cmor2-1, the
  wavelet labid chose at 43-73 kHz).

Each pair velocity 0.2 m / (t_40 - t_20) is compared with the true plate's group velocity
(legendre_safe). ``records``: 36 breaks of the edge-0 rig (plate 1/0.6, independent model, trigger
-3 mV so that every shot triggers both ways) analysed by labid and by the numpy envelope, with the
rig's chain and with the old one (``source_pad(0)``); ``quiet``: the same with 0.1 uV noise.
Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_edge_causal.py [records] [quiet]
"""
from __future__ import annotations

import contextlib
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import signal, special

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from bench.bench_unknown_plate import EDGE_BAND, ORDER, independent_transfer, records, reference  # noqa: E402
from bench.independent.legendre_safe import branches, layers_of, plate_of  # noqa: E402
from engine import waves  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.inputs.specimen import load_specimen  # noqa: E402
from labid.workflows.analysis import wave_features  # noqa: E402
from mock_hw import waves as mock_waves  # noqa: E402
from mock_hw import rig as mock_rig  # noqa: E402
from mock_hw.rig import truth_laminate  # noqa: E402

HERE = Path(__file__).resolve().parent
FS, FMAX, RISE = 2e6, 400e3, 1e-6           # the rig's rate, synthesis band and lead rise (cfrp_pencil_edge_0)
R1, R2 = 0.20, 0.40
N_CHAIN = 2 * 4096 + 16                      # the rig's fine record length / OVERSAMPLE (samples 4096)
T0 = 200e-6                                  # the source's time in the compared signals (s)
F = np.array([43e3, 55e3, 66e3, 75e3, 91e3, 110e3, 134e3, 158e3])


def s0_only(lam, r, f, **kw):
    """legendre_safe's S0 transfer alone, in ``engine.safe.mode_transfer``'s signature."""
    return {"S0": independent_transfer(lam, r, f, **kw)["S0"]}


@contextlib.contextmanager
def source_pad(t_pad: float):
    """mock_hw's synthesis with its source ``t_pad`` into the FFT period (0: the chain before
    session 26, the source at the period's first sample); restored on exit."""
    old = mock_waves.SOURCE_PAD_S
    mock_waves.SOURCE_PAD_S = t_pad
    mock_waves._wave_fine.cache_clear()
    mock_rig._cached_template.cache_clear()
    try:
        yield
    finally:
        mock_waves.SOURCE_PAD_S = old
        mock_waves._wave_fine.cache_clear()
        mock_rig._cached_template.cache_clear()


def signals(lam, direction, n, t0, chain=None, far_field=False):
    """S0 strain per newton at R1 and R2 for the rig's lead break (``mock_hw.waves.source_force``,
    a 1 us raised-cosine step), n samples at FS with the source at t0.

    chain None: 'ideal', the transfer's own periodic time response (nothing cut); chain = t_pad:
    the rig's own synthesis ``mock_hw.waves._wave_fine`` (one ray, no aperture, no delay) with the
    source t_pad into its FFT period (0: the old chain), its fine grid taken every OVERSAMPLE-th
    sample, placed at t0 after zeros (the record's pre-trigger). far_field (ideal only): H1(kr) of
    the strain kernel replaced by its large-kr form sqrt(2 / (pi kr)) exp(i(kr - 3 pi / 4))."""
    force = mock_waves.source_force(("pencil", RISE))
    out = []
    for r in (R1, R2):
        if chain is not None:
            with source_pad(chain), mock_waves.transfer_model("legendre S0", s0_only):
                os_ = mock_waves.OVERSAMPLE
                y = mock_waves._wave_fine(lam, ((r, float(direction), 1.0),), ("pencil", RISE), FS,
                                          os_ * N_CHAIN, 0.0, FMAX, 0.0, 0.0,
                                          ("inplane", 0.0, (("top", 0.5), ("bottom", 0.5))), "top",
                                          "legendre S0")[::os_]
            z, i0 = np.zeros(n), int(round(t0 * FS))
            z[i0:i0 + min(y.size, n - i0)] = y[:n - i0]
            out.append(z)
            continue
        f = np.fft.rfftfreq(n, 1 / FS)
        band = (f > 0) & (f <= FMAX)
        fb = f[band]
        taper = np.where(fb <= 0.9 * FMAX, 1.0, 0.5 * (1 + np.cos(np.pi * (fb - 0.9 * FMAX) / (0.1 * FMAX))))
        H = 0.5 * sum(independent_transfer(lam, r, fb, direction_deg=direction, load="inplane", source_face=face)["S0"]
                      for face in ("top", "bottom"))
        if far_field:
            k = branches(plate_of(layers_of(lam.plies, direction), ORDER), FMAX * 1.05).at(2, 2 * np.pi * fb)[0]
            with np.errstate(invalid="ignore", divide="ignore"):
                fac = np.sqrt(2 / (np.pi * k * r)) * np.exp(1j * (k * r - 0.75 * np.pi)) / special.hankel1(1, k * r)
            H = np.where(np.isfinite(fac), H * fac, 0.0)
        X = np.zeros(f.size, complex)
        X[band] = np.conj(H) * taper * force.spectrum(fb) * np.exp(-2j * np.pi * fb * t0)
        out.append(np.fft.irfft(X, n) * FS)
    return out


def peak_time(a, lo, hi):
    """Time (s) of the largest sample of a[lo:hi], refined by a parabola through log a."""
    k = lo + int(np.argmax(a[lo:hi]))
    la, lb, lc = np.log(a[k - 1:k + 2])
    return (k + 0.5 * (la - lc) / (la - 2 * lb + lc)) / FS


def pair_errors(x1, x2, t0, ref, c):
    """Relative errors (%) of the CWT-ridge and the numpy-envelope pair velocities."""
    g1 = (int((t0 + 0.5 * R1 / c) * FS), int((t0 + 2 * R1 / c) * FS))
    g2 = (int((t0 + 0.5 * R2 / c + 0.5 * R1 / c) * FS), int((t0 + 2 * R2 / c) * FS))
    wl = waves.Wavelet.from_name("cmor2-1")
    W1, W2 = (np.abs(waves.cwt(x, FS, F, wl, precision="double")) for x in (x1, x2))
    cwt = [(R2 - R1) / (peak_time(W2[i], *g2) - peak_time(W1[i], *g1)) for i in range(F.size)]
    env = []
    for fc in F:
        sos = signal.butter(2, [0.85 * fc, 1.15 * fc], "bandpass", fs=FS, output="sos")
        e1, e2 = (np.abs(signal.hilbert(signal.sosfiltfilt(sos, x))) for x in (x1, x2))
        env.append((R2 - R1) / (peak_time(e2, *g2) - peak_time(e1, *g1)))
    return 100 * (np.array(cwt) / ref - 1), 100 * (np.array(env) / ref - 1)


def records_case(large, n=36) -> None:
    """labid's S0 picks and the numpy envelope on the rig's records, as synthesised and padded."""
    text = (HERE / "rigs" / "cfrp_pencil_edge_0.toml").read_text().replace("level_v = -0.005", "level_v = -0.003")
    rig = rig_from_text(text, "bench/rigs/cfrp_pencil_edge_0.toml (trigger -3 mV)")
    rig = replace(rig, sim=replace(rig.sim, truth_scale=(("*", 1 / 0.6),)))
    lam = truth_laminate(large.laminate, rig.sim.truth_scale)
    for name, ctx in (("rig chain (session 26)", contextlib.nullcontext()), ("old chain (pad 0)", source_pad(0.0))):
        with ctx:
            recs = records(rig, large, n, 0, "independent")
        feats, *_ = wave_features(recs, rig, large, EDGE_BAND, [])
        for w in (w for w in feats if w["mode"] == "S0"):
            f, v, s = (np.array(w[k]) for k in ("frequency_hz", "group_velocity_m_s", "sigma_m_s"))
            ref = reference(lam, 0.0, f)["S0"]
            print(f"  records {name}, labid S0 0 deg: " + ", ".join(
                f"{a / 1e3:.0f} kHz {100 * (b / r - 1):+.2f} % (sigma {100 * e / r:.2f})" for a, b, e, r in zip(f, v, s, ref)))
        x1, x2 = (np.mean([np.asarray(r.data[c], float) for r in recs], axis=0) for c in ("x1", "x2"))
        pre, ref = recs[0].t0_index, reference(lam, 0.0, F)["S0"]
        g1, g2 = (pre - 80, pre + 80), (pre + 10, pre + 160)
        for rel in (0.15, 0.30):
            out = []
            for fc, r in zip(F, ref):
                sos = signal.butter(2, [fc * (1 - rel), fc * (1 + rel)], "bandpass", fs=FS, output="sos")
                e1, e2 = (np.abs(signal.hilbert(signal.sosfiltfilt(sos, x))) for x in (x1, x2))
                out.append(100 * ((R2 - R1) / (peak_time(e2, *g2) - peak_time(e1, *g1)) / r - 1))
            print(f"  records {name}, numpy envelope +-{100 * rel:.0f} %: " + " ".join(f"{v:+6.2f}" for v in out))


def main() -> None:
    print(f"machine: {machine()}")
    large = load_specimen(str(HERE / "rigs" / "cfrp_large.toml"))
    c0 = time.process_time()
    print("S0 pair velocity 20 / 40 cm vs the true plate (legendre_safe), %: " + "  ".join(f"{f / 1e3:.0f}k" for f in F))
    for scale, label in ((1 / 0.6, "plate 1/0.6 (file 40 % soft)"), (1 / 1.4, "plate 1/1.4 (file 40 % stiff)")):
        lam = truth_laminate(large.laminate, (("*", scale),))
        for direction in (0.0, 90.0):
            ref = reference(lam, direction, F)["S0"]
            c = float(np.mean(ref))
            for name, chain, ff in (("ideal", None, False), ("far field", None, True),
                                    ("rig chain", mock_waves.SOURCE_PAD_S, False), ("old chain", 0.0, False)):
                x1, x2 = signals(lam, direction, 1 << 14, T0, chain, ff)
                e_cwt, e_env = pair_errors(x1, x2, T0, ref, c)
                for how, e in (("CWT cmor2-1", e_cwt), ("numpy envelope", e_env)):
                    print(f"  {label}, {direction:g} deg, {name:9s}, {how:14s}: " + " ".join(f"{v:+6.2f}" for v in e),
                          flush=True)
    if "records" in sys.argv[1:]:
        records_case(large)
    print(f"CPU {time.process_time() - c0:.1f} s")


if __name__ == "__main__":
    main()
