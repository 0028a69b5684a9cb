"""The one check of a table's keys against those it may hold (specimen, rig, features,
``[uncertainty]``): an unknown key is a ``UserError`` naming the file and the key."""
from __future__ import annotations

from typing import Any, Iterable, Mapping

from ..base.errors import UserError

__all__ = ["check_keys"]


def check_keys(tab: Mapping[str, Any], allowed: Iterable[str], where: str, src: str | None) -> None:
    """UserError naming the first key of ``tab`` not in ``allowed`` (``where``: the key
    prefix, e.g. ``"plate."``; ``src``: the file)."""
    allowed = set(allowed)
    for k in tab:
        if k not in allowed:
            raise UserError(f"unknown key; expected one of {sorted(allowed)}", file=src, key=f"{where}{k}")
