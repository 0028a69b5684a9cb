"""The HDF5 run store: one file per test session (schema in ``runstore``).

Public seam: ``RunStore`` (open, append shots, read shots, write/read results),
``decode_result`` (a results group -> its JSON copy), ``SCHEMA``, ``KINDS``,
``software_version``, ``WriterLock`` (one writer at a time: ``RUN.h5.lock``).
``results`` holds ``RunStore``'s ``/results`` methods (a kept result's predecessor moved
aside in the same file copy); ``h5repair`` mends files left open by a killed writer (used by
``RunStore`` itself); ``readonly`` is the read path that never writes; ``inprocess`` lets readers and
writers of one run in several threads of a process wait for each other.
"""
from .lock import WriterLock
from .runstore import KINDS, SCHEMA, RunStore, software_version
from .tree import decode_result

__all__ = ["KINDS", "SCHEMA", "RunStore", "WriterLock", "decode_result", "software_version"]
