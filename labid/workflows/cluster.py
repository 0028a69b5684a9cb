"""Multi-start studies on a Dask distributed cluster (``labid identify --starts N --scheduler ADDR``).

``connect(address, n_starts)`` is called before any fitting: it refuses ``--scheduler``
without ``--starts``, a missing ``distributed`` (the ``labid[cluster]`` extra), an
unreachable scheduler, a cluster without workers, and workers whose environment differs
from this machine's (labid missing or of another version, other Python, dask,
distributed, cloudpickle, msgpack, numpy or scipy versions), each in one line. Returns the
connected ``distributed.Client`` (close it when done), or None without ``--scheduler``.
"""
from __future__ import annotations

import importlib.metadata as md
import sys
from typing import Any, Mapping

from ..base.errors import UserError

#: packages that must match between this machine and the workers (besides labid)
MATCH = ("python", "dask", "distributed", "cloudpickle", "msgpack", "numpy", "scipy")
TIMEOUT_S = 5.0


def local_version(name: str = "labid") -> str | None:
    """The version of an installed distribution here (None if not installed)."""
    try:
        return md.version(name)
    except md.PackageNotFoundError:
        return None


def connect(address: str | None, n_starts: int, timeout_s: float = TIMEOUT_S):
    """A client on the scheduler at ``address`` whose workers can run labid (see module docstring)."""
    if not address:
        return None
    if not n_starts:
        raise UserError("--scheduler without --starts: the cluster runs only the multi-start study; "
                        "expected --starts N (N > 0)", key="--scheduler")
    try:
        from distributed import Client  # noqa: PLC0415 - the optional 'cluster' extra
    except ImportError:
        raise UserError("dask.distributed is not installed; expected pip install 'labid[cluster]'",
                        key="--scheduler") from None
    try:
        client = Client(address, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError, ValueError) as e:
        raise UserError(f"cannot reach scheduler {address!r} ({type(e).__name__}: {e})".splitlines()[0],
                        key="--scheduler") from None
    try:
        check_workers(client, address)
    except BaseException:
        client.close()
        raise
    return client


def check_workers(client: Any, address: str = "") -> dict:
    """Refuse (UserError, one line) a cluster without workers or whose workers lack labid or
    differ in version; returns {worker: labid version}."""
    info = client.scheduler_info()
    if not info.get("workers"):
        raise UserError(f"scheduler {address!r} has no worker; expected dask workers started with "
                        "'dask worker ADDRESS' in the environment labid is installed in", key="--scheduler")
    here = local_version()
    labid = client.run(md.version, "labid", on_error="return")
    bad = []
    for w, v in labid.items():
        if isinstance(v, BaseException):
            bad.append(f"{w}: labid not installed")
        elif here is not None and v != here:
            bad.append(f"{w}: labid {v}")
    versions = client.get_versions(check=False)
    mine = _flat(versions.get("client") or {})
    for w, pk in (versions.get("workers") or {}).items():
        theirs = _flat(pk or {})
        for name in MATCH:
            a, b = mine.get(name), theirs.get(name)
            if a is not None and b is not None and _major_minor(a, name) != _major_minor(b, name):
                bad.append(f"{w}: {name} {b}")
    if bad:
        shown = "; ".join(bad[:4]) + (f"; and {len(bad) - 4} more" if len(bad) > 4 else "")
        raise UserError(f"workers differ from this machine (labid {here}, python {sys.version.split()[0]}, "
                        f"{', '.join(f'{n} {mine.get(n)}' for n in MATCH[1:3])}): {shown}; expected the same "
                        "environment on every worker (pip install 'labid[cluster]' there)", key="--scheduler")
    return {w: v for w, v in labid.items()}


def _flat(d: Mapping) -> dict[str, str]:
    """{package: version} from one entry of ``Client.get_versions`` ({host: {...}, packages: {...}})."""
    out = dict((d.get("packages") or {}))
    host = d.get("host") or {}
    if "python" in host:
        out.setdefault("python", host["python"])
    return {k: str(v) for k, v in out.items() if v is not None}


def _major_minor(v: str, name: str) -> str:
    """The part of a version that must match: major.minor for python and numpy/scipy (ABI and
    numerics), the full version for the dask family and pickling packages."""
    if name in ("python", "numpy", "scipy"):
        return ".".join(v.split(".")[:2])
    return v
