"""The identification's typed result: one shape for ``labid identify`` (console, ``--json``,
``--csv``), the panel, the report and the run file (``/results/identification``).

``Identification`` is a frozen dataclass over plain data (no engine, no I/O):

- ``estimate``: the estimator's JSON (``engine.fit.Estimate.to_dict``: the CONTRACT keys
  ``parameters`` ({name: {value, std, identified[, reason]}}, SI), ``converged``, ``residual``,
  and ``method``, ``iterations``, ``seconds``, ``start``, ``correlation``,
  ``identifiability``, ``blocks``, ``warnings``, ``fit`` (the verdict), ``held``, ``pairing``,
  ``unpaired_modes``, ...);
- ``data``: the kinds of data fitted, sorted: ``("modal",)``, ``("waves",)`` or
  ``("modal", "waves")`` (:attr:`data_set` names them 'modal', 'waves', 'combined');
- ``specimen`` (its name), ``nominal`` (the specimen's constants of the fitted names, SI);
- ``budget`` (the GUM ``uncertainty_budget``) or ``budget_error`` (why there is none);
- ``multi_start`` (one dict per start) and ``multi_start_minima`` (their distinct end points);
- ``posterior`` (MCMC), ``stored`` (number, time and writer once kept in a run file).

"Identified" has ONE definition, :meth:`Identification.status`: a constant is identified
when the fit's verdict says so (``parameters[name].identified``: the fit is consistent, the
constant's relative std is below the threshold, it is not flagged (runaway, at a bound,
ambiguous)) and it is not held at its start under a weak prior. The console, the CSV, the
JSON, the panel and the report all read it from here.

``to_dict()`` is the ``labid identify --json`` document (CONTRACT keys kept, the others
added) and what the run file stores; ``from_dict()`` reads it back, and also the older
shapes (the panel's ``data`` = 'combined', a bare estimate without ``data``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

__all__ = ["Identification", "DATA_SETS"]

#: the name of each combination of data kinds
DATA_SETS = {("modal",): "modal", ("waves",): "waves", ("modal", "waves"): "combined"}
#: keys of the JSON that are not the estimator's
_OWN = ("data", "data_set", "specimen", "nominal", "uncertainty_budget", "uncertainty_budget_error",
        "multi_start", "multi_start_minima", "posterior", "stored")


def _kinds_of(d: Mapping) -> tuple[str, ...]:
    """The data kinds of a stored result: its ``data`` list, a data-set name, else the
    ``kind`` each of its ``blocks`` records."""
    data = d.get("data")
    if isinstance(data, (list, tuple)):
        return tuple(sorted(str(k) for k in data))
    kinds = tuple(sorted({str(b["kind"]) for b in (d.get("blocks") or {}).values()
                          if isinstance(b, Mapping) and b.get("kind")}))
    if kinds or not isinstance(data, str):
        return kinds
    return {v: k for k, v in DATA_SETS.items()}.get(data, ())


@dataclass(frozen=True)
class Identification:
    """One identification (module docstring)."""

    estimate: Mapping[str, Any]
    data: tuple[str, ...] = ()
    specimen: str = ""
    nominal: Mapping[str, float] = field(default_factory=dict)
    budget: Mapping[str, Any] | None = None
    budget_error: str | None = None
    multi_start: tuple[Mapping[str, Any], ...] = ()
    multi_start_minima: tuple[Mapping[str, Any], ...] = ()
    posterior: Mapping[str, Any] | None = None
    stored: Mapping[str, Any] | None = None

    # -- the estimate ----------------------------------------------------------------
    @property
    def parameters(self) -> dict[str, dict]:
        """{name: {value, std, identified, reason}} (SI), every fitted constant (held ones too)."""
        p = self.estimate.get("parameters")
        return dict(p) if isinstance(p, Mapping) else {}

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.parameters)

    @property
    def converged(self) -> bool:
        return bool(self.estimate.get("converged"))

    @property
    def fit(self) -> dict:
        """The verdict: chi2, dof, p_value, consistent, flags, chi2_per_dof ... ({} if none)."""
        f = self.estimate.get("fit")
        return dict(f) if isinstance(f, Mapping) else {}

    @property
    def held(self) -> dict[str, dict]:
        """{name: {value, reason}}: constants held at their start under a weak prior."""
        h = self.estimate.get("held")
        return dict(h) if isinstance(h, Mapping) else {}

    @property
    def pairing(self) -> list[dict] | None:
        p = self.estimate.get("pairing")
        return list(p) if isinstance(p, list) else None

    @property
    def warnings(self) -> list[str]:
        return [str(w) for w in self.estimate.get("warnings") or []]

    @property
    def data_set(self) -> str:
        """'modal', 'waves' or 'combined' ('+'.join of the kinds otherwise)."""
        return DATA_SETS.get(tuple(self.data), "+".join(self.data) or "?")

    # -- "identified": the one definition ----------------------------------------------
    def status(self, name: str) -> tuple[bool, str]:
        """(identified, why not) of constant ``name`` (module docstring); ``why not`` is ''
        when identified."""
        p = self.parameters.get(name)
        if not isinstance(p, Mapping):
            return False, "not fitted"
        if name in self.held:
            h = self.held[name]
            why = p.get("reason") or (h.get("reason") if isinstance(h, Mapping) else None)
            return False, str(why or "held at its start under a weak prior")
        if "identified" in p:
            ok = bool(p["identified"])
            return ok, "" if ok else str(p.get("reason") or "poorly identified")
        ident = ((self.estimate.get("identifiability") or {}).get("parameters") or {}).get(name)
        if isinstance(ident, Mapping) and "identified" in ident:       # a result without a verdict
            ok = bool(ident["identified"]) and bool(self.fit.get("consistent", True))
            return ok, "" if ok else str(ident.get("reason") or "poorly identified")
        return False, "no verdict in this result"

    def is_identified(self, name: str) -> bool:
        return self.status(name)[0]

    @property
    def identified(self) -> bool:
        """The fit as a whole: the verdict's ``identified`` (consistent, every fitted
        constant identified, no flag); without a verdict, every constant's status."""
        if "identified" in self.estimate:
            return bool(self.estimate["identified"])
        return bool(self.parameters) and all(self.is_identified(n) for n in self.names if n not in self.held)

    def constants(self) -> list[dict]:
        """One row per fitted constant: name, value, std (SI), identified, reason, held."""
        return [{"name": n, "value": p.get("value"), "std": p.get("std"), "identified": self.status(n)[0],
                 "reason": self.status(n)[1], "held": n in self.held}
                for n, p in self.parameters.items() if isinstance(p, Mapping)]

    # -- JSON ---------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The ``labid identify --json`` document; what the run file keeps."""
        out = dict(self.estimate)
        out["data"] = list(self.data)
        if self.posterior is not None:
            out["posterior"] = dict(self.posterior)
        out["specimen"] = self.specimen
        if self.multi_start:
            out["multi_start"] = [dict(r) for r in self.multi_start]
            out["multi_start_minima"] = [dict(m) for m in self.multi_start_minima]
        if self.budget is not None:
            out["uncertainty_budget"] = dict(self.budget)
        if self.budget_error:
            out["uncertainty_budget_error"] = self.budget_error
        out["data_set"] = self.data_set
        out["nominal"] = dict(self.nominal)
        if self.stored is not None:
            out["stored"] = dict(self.stored)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "Identification":
        """The typed result of a stored or ``--json`` document (any labid version's shape)."""
        d = dict(d or {})
        return cls(estimate={k: v for k, v in d.items() if k not in _OWN}, data=_kinds_of(d),
                   specimen=str(d.get("specimen") or ""), nominal=dict(d.get("nominal") or {}),
                   budget=d.get("uncertainty_budget"), budget_error=d.get("uncertainty_budget_error"),
                   multi_start=tuple(d.get("multi_start") or ()),
                   multi_start_minima=tuple(d.get("multi_start_minima") or ()),
                   posterior=d.get("posterior"), stored=d.get("stored"))
