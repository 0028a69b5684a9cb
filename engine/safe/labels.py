"""Names of the SAFE branches: polarisation, fundamental modes, families by cut-off.

Mode families and labels (the rule)
-----------------------------------
The DOFs are split into classes that the matrices do not couple, decided
from the ply data (relative tolerance 1e-12; a test checks the matrices):

* mid-plane mirror symmetry (mirrored plies with equal stiffness and density:
  u, v even / w odd = symmetric, the opposite = antisymmetric);
* Lamb / SH separation (C16 = C36 = C45 = 0 in every ply in propagation axes,
  e.g. along 0 or 90 deg in a cross-ply).

Branches of different classes may cross; within one class branches do not
cross (they veer), so sorting the frequencies at fixed k within a class
tracks each mode continuously; this is how labels are kept through crossings.
Names: the rigid-body translations at k = 0 give the three fundamental modes
A0 (w-like), S0 (u-like) and SH0 (v-like); where two or three of them share a
class, sorted at small k they are A0 < SH0 < S0 (flexural slowest, the
quasi-shear slower than the quasi-longitudinal). Higher branches are named by
class (S, A, SH) or, in a coupled class, by the polarisation of the cut-off
(thickness) mode: mostly v -> SH; otherwise Lamb, symmetric if the dominant
component (u or w) has the S parity in the mirror symmetric class, or by a
mirror-correlation heuristic when the layup is not symmetric. Each family
(A, S, SH) is numbered in order of cut-off frequency (A1, A2, ...; SH1, SH2,
... across both SH parities). ``Dispersion.modes`` lists A0, S0, SH0 first and
then the rest by cut-off.

A mode "exists" at frequency f when its branch reaches f; where the branch
is not monotonic (backward wave below a zero-group-velocity point) the largest
wavenumber root, which has c_g >= 0, is reported.
"""
from __future__ import annotations

import numpy as np

from .model import TWO_PI, DofClass, SafeModel

__all__ = ["FUND_ORDER", "fundamental_rows", "branch_table"]


def _polarisation(cls: DofClass, M: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Kinetic-energy fractions (u, v, w) of a class eigenvector."""
    phi = cls.to_phys @ psi
    e = np.array([phi[c::3] @ M[c::3, c::3] @ phi[c::3] for c in range(3)])
    return e / e.sum()


def _mirror_even(z: np.ndarray, f: np.ndarray) -> bool:
    g = np.interp(-z, z, f)
    return float(np.sum(f * g)) >= 0.0


_FUND = {"S": ["S0"], "A": ["A0"], "SHs": ["SH0"], "SHa": [], "sym": ["SH0", "S0"],
         "anti": ["A0"], "lamb": ["A0", "S0"], "sh": ["SH0"], "all": ["A0", "SH0", "S0"]}
FUND_ORDER = {"A0": 0, "S0": 1, "SH0": 2}


def fundamental_rows(model: SafeModel):
    """Rows of the three zero-cut-off modes, found from the class kinds alone."""
    rows = [dict(ci=ci, j=j, family=None, label=lbl, cutoff=0.0)
            for ci, cls in enumerate(model.classes) for j, lbl in enumerate(_FUND[cls.kind])]
    return sorted(rows, key=lambda r: FUND_ORDER[r["label"]])


def branch_table(model: SafeModel, wmax: float):
    """All branches below wmax: list of dicts (class index, branch, family, cutoff)."""
    fund = _FUND
    rows = []
    for ci, cls in enumerate(model.classes):
        lam, vec = np.linalg.eigh(cls.A0)
        lam[:cls.n_rigid] = 0.0
        for j in range(len(lam)):
            if j >= cls.n_rigid and lam[j] >= (1.05 * wmax) ** 2:
                break
            cut = np.sqrt(max(lam[j], 0.0)) / TWO_PI
            if j < cls.n_rigid:
                rows.append(dict(ci=ci, j=j, family=None, label=fund[cls.kind][j], cutoff=0.0))
                continue
            kind = cls.kind
            if kind in ("S", "A"):
                fam = kind
            elif kind in ("SHs", "SHa", "sh"):
                fam = "SH"
            else:
                pol = _polarisation(cls, model.M, vec[:, j])
                if pol[1] > 0.5:
                    fam = "SH"
                else:
                    c = 0 if pol[0] >= pol[2] else 2
                    if kind in ("sym", "anti"):
                        fam = "S" if kind == "sym" else "A"
                    else:
                        phi = (cls.to_phys @ vec[:, j])[c::3]
                        even = _mirror_even(model.z_nodes, phi)
                        fam = "S" if (even == (c == 0)) else "A"
            rows.append(dict(ci=ci, j=j, family=fam, label=None, cutoff=cut))
    order = {"A0": 0, "S0": 1, "SH0": 2}
    rows.sort(key=lambda r: (r["cutoff"] if r["label"] is None else -1.0, order.get(r["label"], 9)))
    count = {"A": 1, "S": 1, "SH": 1}
    for r in rows:
        if r["label"] is None:
            r["label"] = f"{r['family']}{count[r['family']]}"
            count[r["family"]] += 1
    return rows
