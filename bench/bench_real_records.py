"""Published raw plate records through the new rig options (issue 14).

The only raw plate records research found in text form (/work/research/waves/README.md):
Vallen Systeme's ``steel_plate`` example of the vallenae package (PyPI vallenae 0.14.0,
examples/steel_plate; GitHub vallen-systems/pyVallenAE): one acoustic-emission event
on a steel plate seen by four AE sensors at (0.6, 0.6), (0.15, 0.6), (0.15, 0.15),
(0.6, 0.15) m (sample.vaex), 5 MHz, one synchronous clock. Not published: the plate's
thickness, grade, outline, the source and its position. What the authors give: the hit
(threshold-crossing) times of sample.pridb (ch3 3.9927710 s, ch2 3.9927747, ch4
3.9928129, ch1 3.9928143 s) and, for their location example (ex5_location.py), a
nominal velocity of 5000 m/s (sample.vaex, "Velocity=5" mm/us).

What this script does with them:

1. the import a lab would do with the new rig options: a wave-only rig (a pencil-like
   source, position unknown until step 3), four sensors with their positions, one
   acquisition triggered on ch3 (a sensor: the source time is unknown); the records
   stored in a run file (``labid.store.RunStore``), time 0 at the ch3 hit;
2. arrival of the first packet per frequency and channel (complex Morlet, the first
   scalogram maximum standing 10 x above the noise of |W| in the first 300 us);
3. the source position, source time and velocity of that first packet fitted jointly to
   the 4 channels (grid search over (x, y), at each a least-squares line
   t_i = t0 + r_i / v), from the median first arrival of each channel over the band (per
   frequency the picks jump between packets: resonant sensors ring at 135-165 kHz), and
   the same fit to the authors' hit times;
4. compared with the authors' hit-time differences and with the location their 5000 m/s
   gives (LUCY, as in ex5_location.py).

Elastic constants: not possible from these records (thickness, density, outline and
source unknown; one packet only, of an unidentified mode, through resonant sensors).

Run: OMP_NUM_THREADS=1 .venv/bin/python bench/bench_real_records.py [OUT_DIR]
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench._machine import machine  # noqa: E402
from drivers.protocol import ChannelConfig, Record, Timing, Trigger  # noqa: E402
from engine import waves  # noqa: E402
from labid.inputs.rig import rig_from_text  # noqa: E402
from labid.store import RunStore  # noqa: E402

DATA = Path("/work/research/waves/vallenae_steel_plate")
SENSORS = {1: (0.6, 0.6), 2: (0.15, 0.6), 3: (0.15, 0.15), 4: (0.6, 0.15)}
HITS_S = {3: 3.9927710, 2: 3.9927747, 4: 3.9928129, 1: 3.9928143}    # sample.pridb, authors'
FS = 5e6


def read_channel(ch: int) -> tuple[np.ndarray, np.ndarray]:
    """(time in s relative to the ch3 hit, mV) of one CSV."""
    rows = [ln for ln in (DATA / f"steel_plate_ae_ch{ch}.csv").read_text().splitlines()
            if ln[:1].isdigit() or ln[:1] == "-"]
    a = np.array([[float(v) for v in ln.split(",")] for ln in rows])
    return a[:, 0] * 1e-6, a[:, 1]


def common_axis(recs: dict) -> tuple[np.ndarray, dict]:
    """The four records on one axis: the samples from the latest first time, same length."""
    t0 = max(t[0] for t, _ in recs.values())
    n = min(int(round((t[-1] - t0) * FS)) for t, _ in recs.values())
    out = {}
    for ch, (t, x) in recs.items():
        k = int(round((t0 - t[0]) * FS))
        out[ch] = x[k:k + n]
    return t0 + np.arange(n) / FS, out


RIG = """
name = "vallenae steel_plate example: 4 AE sensors, one event (imported)"
[wave_source]
kind = "pencil"            # not documented by the authors; a lead break is the likely source
x = {sx:.4f}                # fitted here (step 3), not published
y = {sy:.4f}
[simulation]
reflections = 0            # the outline is not published
[devices.vallen]
role = "wave"
product = "Vallen AMSY (imported records, int16 x 0.0030445 mV)"
max_rate_hz = 10.0e6
rate_hz = 5.0e6
samples = {n}
pretrigger = {pre}
adc_bits = 16
trigger = {{ channel = "ch3", level_v = 1.0e-4, slope = "rising" }}
{channels}
"""

CHANNEL = """[[devices.vallen.channels]]
name = "ch{ch}"
kind = "voltage"
sensitivity = 1.0
range_v = 0.1
coupling = "AC"
x = {x}
y = {y}
distance_m = {d:.4f}
resonance_hz = {f0:.4g}    # resonant AE sensor: its spectrum peaks here (computed from the record)
resonance_q = 5.0
"""


def first_arrivals(x: np.ndarray, t: np.ndarray, f: np.ndarray, wl: waves.Wavelet,
                   snr: float = 10.0) -> np.ndarray:
    """Time (s) of the first scalogram maximum in [-20, 300] us standing ``snr`` x above the
    white-noise level of |W| of the samples before -20 us (the earliest hit is at 0; the
    authors' threshold, 40 dB_AE = 100 uV, is ~20 x the 5 uV noise)."""
    W = waves.cwt(x, FS, f, wl)
    gate = (t > -20e-6) & (t < 300e-6)
    quiet = t < -20e-6
    noise = waves.white_noise_level(float(np.std(x[quiet])), FS, f, wl)
    out = np.full(f.size, np.nan)
    A = np.abs(W)
    for i in range(f.size):
        a = np.where(gate, A[i], 0.0)
        k = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] > a[2:]) & (a[1:-1] >= snr * noise[i]))
        if k.size:
            j = k[0] + 1
            la, lb, lc = np.log(np.maximum(A[i, j - 1:j + 2], 1e-300))
            den = la - 2 * lb + lc
            out[i] = t[j] + (0.5 * (la - lc) / den / FS if den < 0 else 0.0)
    return out


def joint_fit(times: dict) -> tuple[tuple[float, float], np.ndarray, np.ndarray, float]:
    """Source (x, y), velocity and source time (per column of the times), rms residual (s):
    grid search over (x, y), at each a least-squares line t_i = t0 + r_i / v."""
    chans = sorted(times)
    T = np.array([np.atleast_1d(times[c]) for c in chans])  # (4, n)
    best = None
    for sx in np.arange(0.0, 0.801, 0.005):
        for sy in np.arange(0.0, 0.801, 0.005):
            r = np.array([math.hypot(SENSORS[c][0] - sx, SENSORS[c][1] - sy) for c in chans])
            A = np.column_stack([np.ones(r.size), r])
            coef, res, *_ = np.linalg.lstsq(A, T, rcond=None)
            ss = float(np.sum((T - A @ coef) ** 2))
            if best is None or ss < best[0]:
                best = (ss, sx, sy, coef)
    ss, sx, sy, coef = best
    return (sx, sy), 1.0 / coef[1], coef[0], math.sqrt(ss / T.size)


def lucy(speed: float, hits: dict) -> tuple[float, float]:
    """The authors' location: LUCY on the hit-time differences with their speed (grid 1 mm)."""
    order = sorted(hits, key=hits.get)
    pos = np.array([SENSORS[c] for c in order])
    dt = np.array([hits[c] - hits[order[0]] for c in order[1:]])
    g = np.arange(0.0, 0.8005, 0.001)
    X, Y = np.meshgrid(g, g)
    d = np.sqrt((X[..., None] - pos[:, 0]) ** 2 + (Y[..., None] - pos[:, 1]) ** 2)
    err = np.linalg.norm((d[..., 1:] - d[..., :1]) - speed * dt, axis=-1)
    k = np.unravel_index(np.argmin(err), err.shape)
    return float(X[k]), float(Y[k])


def main() -> None:
    out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="real_records_"))
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    print(f"machine: {machine()}")
    recs = {ch: read_channel(ch) for ch in SENSORS}
    t, x = common_axis(recs)
    f = np.linspace(100e3, 250e3, 16)
    wl = waves.Wavelet(2.0, 2.0)
    arr = {ch: first_arrivals(x[ch] * 1e-3, t, f, wl) for ch in SENSORS}
    # per frequency the picks jump between packets (resonant sensors ringing at 135-165 kHz,
    # a weak first packet): the median over the band is the channel's first arrival
    med = {ch: float(np.nanmedian(arr[ch])) for ch in SENSORS}
    (sx, sy), v, t0, rms = joint_fit(med)
    (hx, hy), hv, _, hrms = joint_fit({ch: HITS_S[ch] - HITS_S[3] for ch in SENSORS})
    ux, uy = lucy(5000.0, HITS_S)
    print(f"first-packet arrivals (us, after the ch3 hit), {wl.name}:")
    for ch in sorted(arr):
        print(f"  ch{ch}: " + " ".join(f"{f[i] / 1e3:.0f}k {arr[ch][i] * 1e6:6.1f}" for i in range(0, f.size, 3)))
    dt_ours = {ch: float(np.nanmedian(arr[ch] - arr[3])) for ch in SENSORS}
    dt_auth = {ch: HITS_S[ch] - HITS_S[3] for ch in SENSORS}
    print("arrival differences to ch3, us: ours (median over 100-250 kHz) vs the authors' hit times")
    for ch in sorted(SENSORS):
        print(f"  ch{ch}: {dt_ours[ch] * 1e6:7.2f}  {dt_auth[ch] * 1e6:7.2f}")
    print(f"source and velocity from our median first arrivals: ({sx:.3f}, {sy:.3f}) m, {v[0]:.0f} m/s, "
          f"rms residual {rms * 1e6:.2f} us")
    print(f"the same fit to the authors' hit times: ({hx:.3f}, {hy:.3f}) m, {hv[0]:.0f} m/s, "
          f"rms residual {hrms * 1e6:.2f} us; LUCY with their nominal 5000 m/s: ({ux:.3f}, {uy:.3f}) m")
    print("four arrival times against four unknowns (x, y, t0, v): the fit is exactly determined and "
          "its velocity is not steel's (S0 <= ~5.4 km/s); with a velocity assumed, the location follows")
    # the import: a wave-only rig and a run file holding the four channels
    r = {ch: math.hypot(SENSORS[ch][0] - sx, SENSORS[ch][1] - sy) for ch in SENSORS}
    pre = int(round(-t[0] * FS))
    spec = {ch: np.abs(np.fft.rfft(x[ch][:4000] * np.hanning(4000))) for ch in SENSORS}
    fpk = {ch: float(np.fft.rfftfreq(4000, 1 / FS)[np.argmax(spec[ch])]) for ch in SENSORS}
    text = RIG.format(sx=sx, sy=sy, n=t.size, pre=pre, channels="\n".join(
        CHANNEL.format(ch=ch, x=SENSORS[ch][0], y=SENSORS[ch][1], d=r[ch], f0=fpk[ch]) for ch in sorted(SENSORS)))
    rig = rig_from_text(text, "vallenae-import")
    rig.check_specimen(0.8, 0.8)
    dev = rig.device("wave")
    rec = Record(data={f"ch{ch}": x[ch] * 1e-3 for ch in SENSORS}, channels=dev.channels, timing=dev.timing,
                 trigger=dev.trigger, overload={}, backend="import:vallenae",
                 meta={"source": "vallenae 0.14.0 examples/steel_plate", "hits_s": {str(k): v for k, v in HITS_S.items()}})
    run = out_dir / "vallenae_steel_plate.h5"
    run.unlink(missing_ok=True)
    with RunStore(run) as st:
        st.write_config("", text)
        st.append_shot(rec, "wave")
    (out_dir / "vallenae_rig.toml").write_text(text)
    print(f"imported: {run} (rig {out_dir / 'vallenae_rig.toml'}): {len(rig.wave_sensors)} sensors, "
          f"{t.size} samples, resonances {', '.join(f'{fpk[c] / 1e3:.0f}' for c in sorted(fpk))} kHz")
    print(f"wall {time.perf_counter() - t_wall:.1f} s, CPU {time.process_time() - t_cpu:.1f} s")


if __name__ == "__main__":
    main()
