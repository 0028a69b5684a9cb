"""Issue 15: a writer killed in the middle of the repair copy (the atomic "write a synced
copy, then rename") leaves the run file as it was; the next writer clears the half-written
copy and repairs. Every kill waits on an event (a line the child prints at the moment of
interest), never on a sleep budget.
"""
from __future__ import annotations

import signal

import h5py
import pytest

from labid.store import RunStore

from tests.integration.test_reliability import child, flagged_run, siblings, small_run, temps

#: a run writer (``"a"`` open) whose repair is stopped at a chosen moment
REPAIRER = """
import os
import labid.store.runstore as rs
from labid.store import RunStore
moment = sys.argv[2]
orig_open = rs.open_read_only


class Source:
    "The flagged run as repair reads it; stops after its first group is copied."
    def __init__(self, f):
        self._f, self._copied = f, 0

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __iter__(self):
        return iter(self._f)

    def __getitem__(self, key):
        return self._f[key]

    def copy(self, src, dst, name):
        self._f.copy(src, dst, name)
        self._copied += 1
        if moment == "copying" and self._copied == 1:
            dst.file.flush()                      # part of the copy is on disk
            print("copying", flush=True)
            sys.stdin.readline()                  # SIGKILL arrives here


rs.open_read_only = lambda p: Source(orig_open(p))
orig_replace = os.replace


def replace(a, b):
    if moment == "renaming" and str(a).endswith(".repair"):
        print("renaming", flush=True)             # the copy is complete and closed, not renamed
        sys.stdin.readline()                      # SIGKILL arrives here
    return orig_replace(a, b)


os.replace = replace
with RunStore(sys.argv[1]):                      # the "a" open repairs the flagged run
    pass
print("finished", flush=True)
"""


@pytest.mark.parametrize("moment", ["copying", "renaming"])
def test_kill_during_the_repair_copy_leaves_the_run_intact(tmp_path, moment):
    p = flagged_run(tmp_path / "run.h5")
    before = p.read_bytes()
    with RunStore(p, "r") as st:
        shots, result = st.n_shots(), st.read_result("analysis")
    assert shots == 3
    proc = child(REPAIRER, str(p), moment)
    try:
        line = proc.stdout.readline().strip()
        assert line == moment, proc.stderr.read()
        assert temps(p, ".repair")                 # the copy is being made beside the run (mkstemp name)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    # the run file is untouched, bit for bit, and reads as before; the half copy is left beside it
    assert p.read_bytes() == before
    with RunStore(p, "r") as st:
        assert st.n_shots() == 3 and st.read_result("analysis") == result
    assert temps(p, ".repair")
    # the next writer removes the killed writer's copy, repairs the run and appends to it
    from tests.integration.test_reliability import record
    with RunStore(p) as st:
        assert not temps(p, ".repair")
        st.append_shot(record(7), "hammer")
    with h5py.File(p, "r") as f:                  # repaired: opens without help
        assert f.attrs["labid_schema"] is not None
    with RunStore(p, "r") as st:
        assert st.n_shots() == 4 and st.read_result("analysis") == result
    assert not {s for s in siblings(p) if s.endswith((".repair", ".unlocked", ".new", ".results"))}
