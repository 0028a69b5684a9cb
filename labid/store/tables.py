"""Reading the shot tables of a run file into ``drivers.protocol.Record`` objects."""
from __future__ import annotations

import json

import h5py
import numpy as np

from drivers.protocol import ChannelConfig, Record, Timing, Trigger


def read_records(shots: h5py.Group, kind: str | None, limit: int | None) -> list[Record]:
    """Every committed shot under ``/shots`` (of ``kind``, or all kinds in table order),
    at most ``limit`` of each kind; ``meta`` gains ``kind``, ``shot``, ``software_version``."""
    out: list[Record] = []
    kinds = [kind] if kind else sorted(shots)
    for k in kinds:
        if k not in shots:
            continue
        g = shots[k]
        chans = tuple(ChannelConfig(**d) for d in json.loads(g.attrs["channels"]))
        timing = Timing(float(g.attrs["rate_hz"]), int(g.attrs["samples"]), int(g.attrs["pretrigger"]))
        trig = json.loads(g.attrs["trigger"])
        trigger = Trigger(**trig) if trig else None
        n = g["committed"].shape[0]
        if limit is not None:
            n = min(n, max(0, int(limit)))
        if n == 0:
            continue
        data = {c.name: np.asarray(g[c.name][:n], dtype="f8") for c in chans}
        ts, ov = g["timestamp"][:n], g["overload"][:n]
        be, sv, me = g["backend"][:n], g["software_version"][:n], g["meta"][:n]
        for i in range(n):
            meta = json.loads(me[i].decode() or "{}")
            meta.update(kind=k, shot=f"{k}_{i + 1:04d}", software_version=sv[i].decode())
            out.append(Record(data={c.name: data[c.name][i] for c in chans}, channels=chans,
                              timing=timing, trigger=trigger,
                              overload={c.name: bool(ov[i, j]) for j, c in enumerate(chans)},
                              timestamp=float(ts[i]), backend=be[i].decode(), meta=meta))
    return out

