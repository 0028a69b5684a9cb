"""Pairing as a cause: is the gap a wrong peak-to-mode pairing rather than a physical effect?

``labid identify`` pairs measured peaks with predicted modes by order (no
mode shapes). A missing peak (a mode the response point barely sees), an
extra peak (suspension, harmonic, electrical) or two close modes swapped
then shift every later pair and leave a gap no effect explains.
:func:`pairing_check` pairs the peaks again at the start estimate: one-to-one
(Hungarian) by log-frequency distance / 0.05 among n + 6 predicted modes, a
peak may stay unpaired at the cost of a 15 % distance. If that differs from
the current pairing, the constants are refitted with it
(``scipy.optimize.least_squares``, unpaired peaks left out, waves kept) and
the peaks re-paired, up to 4 rounds or until a pairing repeats; the findings are phrased for ``where``:

* "peak k (f Hz) is probably mode m (f' Hz)";
* "predicted mode m near f Hz has no measured peak[, which the response
  point barely sees (relative amplitude a)]": a = largest |w| at the
  accelerometers over the largest |w| on the plate (``engine.forward.pairing.visibility``);
* "peak k (f Hz) matches no mode (nearest: mode m at f' Hz): suspension,
  harmonic or electrical?".

``explains`` is True when the re-paired fit passes the chi^2 test at alpha.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..fit.chisq import chi2_sf
from ..forward import ModalForward
from ..forward.pairing import match, visibility
from .residuals import GapFit

__all__ = ["PairingCheck", "pairing_check", "propose_pairing", "BARELY_SEEN", "UNPAIRED_REL"]

#: relative amplitude at the sensors below which a mode is "barely seen"
BARELY_SEEN = 0.15
#: relative frequency distance beyond which a peak is better left unpaired
UNPAIRED_REL = 0.15
EXTRA_MODES = 6
#: re-pair / refit rounds at most
MAX_ROUNDS = 4


@dataclass(frozen=True)
class PairingCheck:
    current: list[int]
    proposed: list[int | None]
    findings: list[str]
    chi2: float
    dof: float
    p_value: float
    explains: bool
    residual: np.ndarray
    constants: dict[str, float]
    converged: bool

    def to_dict(self) -> dict:
        return {"current": self.current, "proposed": self.proposed, "findings": self.findings,
                "chi2_after": self.chi2, "dof_after": self.dof, "p_value_after": self.p_value,
                "explains": self.explains, "constants_after": self.constants, "converged": self.converged}


def propose_pairing(measured_hz, predicted_hz, rel: float = 0.05, unpaired_rel: float = UNPAIRED_REL
                    ) -> list[int | None]:
    """Predicted mode index per measured peak (None: unpaired), one-to-one, minimal total
    log-frequency distance / ``rel``; leaving a peak unpaired costs log(1 + unpaired_rel) / rel."""
    fm = np.log(np.asarray(measured_hz, float))
    fp = np.log(np.asarray(predicted_hz, float))
    idx = match(np.abs(fm[:, None] - fp[None, :]) / rel, np.log1p(unpaired_rel) / rel)
    return [int(c) if c >= 0 else None for c in idx]


def _fit(F, inner, names, th0, paired, sel, y, sig, n, nw):
    def resid(th):
        p = {nm: float(v) for nm, v in zip(names, np.exp(th))}
        rm = (inner.predict(p)[sel] - y[paired]) / sig[paired]
        return np.concatenate([rm, F.residual(p, {})[n:]]) if nw else rm

    def jac(th):
        p = {nm: float(v) for nm, v in zip(names, np.exp(th))}
        _, J = inner.jacobian(p, list(names))
        Jm = J[sel] * np.exp(th)[None, :] / sig[paired][:, None]
        return np.vstack([Jm, F.jacobian(p, {})[n:]]) if nw else Jm

    try:
        return least_squares(resid, th0, jac=jac, method="trf", x_scale=0.05, max_nfev=30, ftol=1e-4,
                             bounds=(th0 - 1.1, th0 + 1.1))
    except (ValueError, np.linalg.LinAlgError):
        return None


def pairing_check(F: GapFit, p_hat: dict, r0: np.ndarray, alpha: float, dof: float) -> PairingCheck | None:
    """Re-pair the peaks at ``p_hat`` and refit (see module docstring); None if the pairing stands."""
    fw, prob = F.fw, F.fw.features
    n = fw.n_modal
    y, sig = F.y[:n], F.sigma[:n]
    model = fw.modal_forward().model
    inner = ModalForward(model, n + EXTRA_MODES, material=prob.material)
    modes = inner.solve(dict(p_hat)).modes
    fp = modes.frequencies_hz[:n + EXTRA_MODES]
    prop = propose_pairing(y, fp)
    current = list(range(n))
    if prop == current:
        return None
    names = F.names
    k = len(names)
    nw = len(F.y) - n
    th = np.log([p_hat[nm] for nm in names])
    seen: list = [current]
    res = None
    for _ in range(MAX_ROUNDS):     # re-pair, refit, until the pairing stands (or repeats)
        paired = np.array([j is not None for j in prop])
        sel = np.array([j for j in prop if j is not None], int)
        res = _fit(F, inner, names, th, paired, sel, y, sig, n, nw)
        if res is None:
            return None
        th = res.x
        seen.append(prop)
        p_new = {nm: float(v) for nm, v in zip(names, np.exp(th))}
        nxt = propose_pairing(y, inner.predict(p_new))
        if nxt in seen:
            break
        prop = nxt
    if prop == current:
        return None
    r = res.fun
    chi2 = float(r @ r)
    dof2 = max(len(r) - k, 1.0)
    pv = float(chi2_sf(chi2, dof2))
    if not chi2 + np.log(max(n, 2)) * (len(r) < len(r0)) < float(r0 @ r0):
        return None
    p_new = {nm: float(v) for nm, v in zip(names, np.exp(res.x))}
    modes = inner.solve(p_new).modes
    fp = modes.frequencies_hz
    vis = visibility(model, modes, prob.rig.accelerometers, length=prob.length, width=prob.width)
    findings = []
    for i, j in enumerate(prop):
        if j is None:
            m = int(np.argmin(np.abs(np.log(fp / y[i]))))
            findings.append(f"peak {i + 1} ({y[i]:.1f} Hz) matches no mode (nearest: mode {m + 1} at "
                            f"{fp[m]:.1f} Hz, {100 * (fp[m] / y[i] - 1):+.0f} %): suspension, harmonic "
                            "or electrical?")
        elif j != i:
            findings.append(f"peak {i + 1} ({y[i]:.1f} Hz) is probably mode {j + 1} ({fp[j]:.1f} Hz)")
    top = max(j for j in prop if j is not None)
    for m in range(top + 1):
        if m not in sel:
            seen = (f", which the response point barely sees (relative amplitude {vis[m]:.2f})"
                    if vis[m] < BARELY_SEEN else "")
            findings.insert(0, f"predicted mode {m + 1} near {fp[m]:.1f} Hz has no measured peak{seen}")
    full = np.zeros(len(F.y))
    full[np.flatnonzero(paired)] = r[:int(paired.sum())]
    if nw:
        full[n:] = r[int(paired.sum()):]
    return PairingCheck(current, prop, findings, chi2, dof2, pv, bool(pv >= alpha), full, p_new,
                        bool(res.status > 0))
