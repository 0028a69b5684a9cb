"""Counting the forward-model work of a run: plate eigen-solves (by mesh size), eigen-
sensitivity evaluations, plate model builds and SAFE dispersion calls, with their CPU.

    with Counts() as c:
        ...            # anything that solves plates or SAFE models
    print(c.table())   # or c.snapshot() between stages

Patches the engine's entry points for the duration (bench only; not for the product).
"""
from __future__ import annotations

import collections
import time


class Counts:
    """Counters of forward-model work; ``snapshot()`` returns a copy of the totals."""

    def __init__(self) -> None:
        self.n: collections.Counter = collections.Counter()
        self.cpu: collections.Counter = collections.Counter()
        self._undo: list = []

    def _wrap(self, owner, attr: str, label) -> None:
        orig = getattr(owner, attr)
        counts = self

        def wrapped(*a, **k):
            lab = label(a, k) if callable(label) else label
            counts.n[lab] += 1
            t = time.process_time()
            try:
                return orig(*a, **k)
            finally:
                counts.cpu[lab] += time.process_time() - t

        setattr(owner, attr, wrapped)
        self._undo.append((owner, attr, orig))

    def __enter__(self) -> "Counts":
        import engine.plate.model as pm
        import engine.forward.waves as fw
        import engine.safe.curves as sc

        def solve_label(a, k):
            n_dof = a[0].mesh.n_dof
            return f"plate solve ({n_dof} DOF)"

        self._wrap(pm.PlateModel, "solve_coefficients", solve_label)
        self._wrap(pm.PlateModel, "eigen_sensitivities", "eigen-sensitivities")
        self._wrap(pm.PlateModel, "build", "plate model build")
        self._wrap(sc, "_model_for", "SAFE model (any SAFE call)")
        self._wrap(fw, "safe_group_velocity", "SAFE group velocity (fit blocks)")
        import engine.identify.surrogate as su
        if hasattr(su, "shift_invert"):   # the surrogate's basis blocks (session 26, h46)
            self._wrap(su, "shift_invert", "surrogate shift-invert block")
        try:    # the warm block solves (engine/plate/warm.py, session 26); absent in older trees
            from engine.plate.warm import COUNTS as warm_counts
        except ImportError:
            warm_counts = None
        self._warm = (warm_counts, dict(warm_counts or {}))
        return self

    def __exit__(self, *exc) -> None:
        for owner, attr, orig in reversed(self._undo):
            setattr(owner, attr, orig)
        self._undo.clear()

    def snapshot(self) -> dict:
        out = {k: (self.n[k], self.cpu[k]) for k in self.n}
        live, start = getattr(self, "_warm", (None, {}))
        for k, lab in (("warm", "block solves answered warm"), ("failed", "warm tried, not certified"),
                       ("again", "the same solve again (model memo)")):
            if live is not None and live.get(k, 0) - start.get(k, 0):
                out[lab] = (live[k] - start.get(k, 0), 0.0)
        return out

    @staticmethod
    def diff(a: dict, b: dict) -> dict:
        """b - a per label: (count, CPU s)."""
        out = {}
        for k in b:
            n0, c0 = a.get(k, (0, 0.0))
            if b[k][0] - n0:
                out[k] = (b[k][0] - n0, b[k][1] - c0)
        return out

    @staticmethod
    def line(d: dict) -> str:
        return "; ".join(f"{k}: {n} ({c:.2f} s)" for k, (n, c) in sorted(d.items())) or "-"


class Stages:
    """Inclusive forward-model work and CPU per named stage (a wrapped function), summed
    over its calls: ``Stages(counts).wrap(module, "func", "label")``."""

    def __init__(self, counts: Counts) -> None:
        self.c = counts
        self.rows: dict[str, list] = {}      # label -> [calls, cpu, {work label: (n, cpu)}]
        self._undo: list = []

    def wrap(self, owner, attr: str, label: str | None = None) -> "Stages":
        orig = getattr(owner, attr)
        label = label or attr
        st = self

        def wrapped(*a, **k):
            s0, t0 = st.c.snapshot(), time.process_time()
            try:
                return orig(*a, **k)
            finally:
                d = Counts.diff(s0, st.c.snapshot())
                row = st.rows.setdefault(label, [0, 0.0, {}])
                row[0] += 1
                row[1] += time.process_time() - t0
                for kk, (n, cpu) in d.items():
                    n0, c0 = row[2].get(kk, (0, 0.0))
                    row[2][kk] = (n0 + n, c0 + cpu)

        setattr(owner, attr, wrapped)
        self._undo.append((owner, attr, orig))
        return self

    def undo(self) -> None:
        for owner, attr, orig in reversed(self._undo):
            setattr(owner, attr, orig)
        self._undo.clear()

    def table(self) -> str:
        lines = ["| stage (inclusive) | calls | CPU (s) | work |", "|---|---|---|---|"]
        for lab, (n, cpu, d) in self.rows.items():
            lines.append(f"| {lab} | {n} | {cpu:.2f} | {Counts.line(d)} |")
        return "\n".join(lines)
