"""Vibration shots of the simulated rig: plate modes excited by a half-sine hammer force.

The plate modes of ``engine.plate`` (mass-normalised shapes phi) respond to a half-sine
hammer force F(t) = F0 sin(pi t / T), 0 <= t <= T, at (xh, yh). Each mode is a damped
oscillator q'' + 2 zeta w q' + w^2 q = phi(xh, yh) F(t), solved in closed form;
accelerometer j reads sum_m phi_m(xj, yj) q_m''(t). Units SI (s, rad/s, m, kg, N/m).

The modes come from the converged reference mesh (``engine.plate.convergence.reference_mesh``,
2x the default elements per direction), not from the identification's default mesh: a
simulated plate computed on the model's own mesh would hide the model's discretisation
error (the "inverse crime"; issue 12).
"""
from __future__ import annotations

import functools

import numpy as np

from engine.laminate import Laminate
from engine.plate import PlateModel
from engine.plate.convergence import reference_mesh


@functools.lru_cache(maxsize=16)
def plate_modes(lam: Laminate, length: float, width: float, n_modes: int,
                masses: tuple = (), springs: tuple = (), mesh=None):
    """(PlateModel, Modes) for the plate with point masses/springs; cached. ``mesh`` None:
    the converged reference mesh."""
    model = PlateModel.build(lam, length, width, mesh if mesh is not None
                             else reference_mesh(length, width, lam.thickness))
    if masses:
        model = model.with_point_masses(masses)
    if springs:
        model = model.with_springs(springs)
    return model, model.solve(n_modes)


def half_sine(t: np.ndarray, contact_s: float) -> np.ndarray:
    """Unit-peak half-sine force sin(pi t / T) on 0 <= t <= T, else 0."""
    return np.where((t >= 0) & (t <= contact_s), np.sin(np.pi * np.clip(t, 0, None) / contact_s), 0.0)


def modal_acceleration(t: np.ndarray, omega: np.ndarray, zeta: np.ndarray, contact_s: float) -> np.ndarray:
    """(n_modes, n_t) q'' of q'' + 2 zeta w q' + w^2 q = sin(pi t/T) [0 <= t <= T], q(0)=q'(0)=0.

    Exact closed form (steady sine + free transient, superposed with the same
    shifted by T). omega in rad/s, zeta < 1, t in s.
    """
    W = np.pi / contact_s
    w = np.asarray(omega, float)[:, None]
    z = np.asarray(zeta, float)[:, None]
    H = 1.0 / (w**2 - W**2 + 2j * z * w * W)
    sig = -z * w
    wd = w * np.sqrt(1.0 - z**2)
    c1 = -H.imag
    c2 = (-W * H.real - sig * c1) / wd
    s = sig + 1j * wd
    C = (c1 - 1j * c2) * s**2

    def g(tt):
        tp = np.clip(tt, 0.0, None)
        a = -W**2 * (H * np.exp(1j * W * tp)).imag + (C * np.exp(s * tp)).real
        return np.where(tt >= 0, a, 0.0)

    return g(t[None, :]) + g(t[None, :] - contact_s)


def vibration_signals(rig, specimen, lam, effects, channels, t) -> dict[str, np.ndarray]:
    """Force (V) and accelerometer (V) signals of a hammer hit of unit peak force on times ``t`` (s):
    the plate modes (with the declared sensor masses plus ``effects.sensor_mass``, and
    ``effects.support_stiffness`` springs at the supports) excited at the hammer point."""
    sim, ham = rig.sim, rig.hammer
    accs = [c for c in channels if c.kind == "accelerometer"]
    # the declared sensor masses are always on the plate (the model knows them);
    # the sensor_mass effect is mass beyond what the rig file declares
    masses = tuple((c.x, c.y, c.mass_kg + effects.sensor_mass) for c in accs
                   if c.mass_kg + effects.sensor_mass > 0.0)
    springs = tuple((x, y, effects.support_stiffness) for x, y in rig.supports) \
        if effects.support_stiffness else ()
    out: dict[str, np.ndarray] = {}
    for c in channels:
        if c.kind == "force":
            out[c.name] = c.sensitivity * half_sine(t, ham.contact_s)
    if accs:
        model, modes = plate_modes(lam, specimen.length, specimen.width, sim.n_modes, masses, springs)
        pts = np.array([[ham.x, ham.y]] + [[c.x, c.y] for c in accs])
        phi = model.shapes_at(modes, pts)                    # (n_modes, 1 + n_acc)
        omega = np.sqrt(np.maximum(modes.omega2, 0.0))
        zeta = np.full(omega.shape, sim.modal_damping + effects.viscoelastic / 2.0)
        acc = np.zeros((len(accs), t.size))
        for lo in range(0, omega.size, 10):                  # bounded memory
            q = modal_acceleration(t, omega[lo:lo + 10], zeta[lo:lo + 10], ham.contact_s)
            acc += (phi[lo:lo + 10, 1:] * phi[lo:lo + 10, :1]).T @ q
        for j, c in enumerate(accs):
            out[c.name] = c.sensitivity * acc[j]
    return out
