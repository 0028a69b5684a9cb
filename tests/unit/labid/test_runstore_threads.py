"""A reader and a writer of one run in two threads of one process (store.inprocess).

HDF5 refuses an open for writing while the file is open read-only in the same process
("file is already open for read-only"), and a reader's HDF5 shared lock refused the
writer's lock on the run's inode. The store called the first "damaged or not a labid run
file" and the second "in use by another writer (... a hard link)": the panel's false
"damaged" after an Abort under load (CI, session 22). Both orders are forced with events
(no sleeps): the writer must wait for the reader, store its result, and lose no shot;
the reader must read the file whole.

Observable outside the code: the three shots written are read back, and the result the
writer stored is there."""
from __future__ import annotations

import threading

import pytest

from labid.store import RunStore, runstore
from tests.integration.test_reliability import child, small_run

GUARD_S = 900       # against a hung test only: every wait ends on an event


class Thread(threading.Thread):
    """A thread whose exception is handed back by ``result()``."""

    def __init__(self, fn):
        super().__init__(daemon=True)
        self.fn, self.value, self.error = fn, None, None

    def run(self):
        try:
            self.value = self.fn()
        except BaseException as e:  # noqa: BLE001 - handed to the test
            self.error = e

    def result(self):
        self.join(GUARD_S)
        assert not self.is_alive()
        if self.error is not None:
            raise self.error
        return self.value


def write_session(run):
    with RunStore(run, "a") as st:
        st.write_group("gui", {"state_json": "{}"})


def test_writer_waits_for_a_reader_already_open(tmp_path, monkeypatch):
    """The autosave after an Abort: the checks job's read is open when the writer comes."""
    run = small_run(tmp_path / "run.h5")
    reader_open, writer_met_reader = threading.Event(), threading.Event()
    real_changing = getattr(runstore, "changing", None)
    if real_changing is not None:           # the writer reaches the readers' gate
        def changing(path):
            if threading.current_thread() is threading.main_thread():
                writer_met_reader.set()
            return real_changing(path)
        monkeypatch.setattr(runstore, "changing", changing)

    def read():
        with RunStore(run, "r") as st:
            reader_open.set()
            assert writer_met_reader.wait(GUARD_S)
            return [r.meta["shot"] for r in st.shots("hammer")]

    t = Thread(read)
    t.start()
    assert reader_open.wait(GUARD_S)
    try:
        write_session(run)
    finally:
        writer_met_reader.set()
        shots = t.result()
    assert shots == ["hammer_0001", "hammer_0002", "hammer_0003"]
    with RunStore(run, "r") as st:
        assert st.n_shots("hammer") == 3 and "gui" in st.result_names()


def test_reader_arriving_between_the_writers_lock_and_open(tmp_path, monkeypatch):
    """The CI failure's order: the writer holds the lock, a reader of another thread opens
    the file before the writer's HDF5 open; the writer then saw 'already open for read-only'."""
    run = small_run(tmp_path / "run.h5")
    reader_ready, writer_opened = threading.Event(), threading.Event()
    real_probe, real_reading = runstore.probe, getattr(runstore, "Reading", None)
    real_open = runstore.RunStore._open_append
    reader: list[Thread] = []

    def read():
        with RunStore(run, "r") as st:
            reader_ready.set()                      # open (before the fix)
            assert writer_opened.wait(GUARD_S)      # held open across the writer's HDF5 open
            return st.n_shots("hammer")

    def probe(path):
        real_probe(path)
        if threading.current_thread() is threading.main_thread() and not reader:
            reader.append(Thread(read))             # the writer, after its lock, before its open
            reader[0].start()
            assert reader_ready.wait(GUARD_S)

    def open_append(self):
        try:
            return real_open(self)
        finally:
            writer_opened.set()

    monkeypatch.setattr(runstore, "probe", probe)
    monkeypatch.setattr(runstore.RunStore, "_open_append", open_append)
    if real_reading is not None:
        def reading(path):
            reader_ready.set()                      # about to wait at the gate (after the fix)
            return real_reading(path)
        monkeypatch.setattr(runstore, "Reading", reading)
    try:
        write_session(run)
    finally:
        writer_opened.set()
        n = reader[0].result() if reader else None
    assert n == 3
    with RunStore(run, "r") as st:
        assert st.n_shots("hammer") == 3 and "gui" in st.result_names()


def test_writer_under_a_reader_of_its_own_thread_is_one_clear_line(tmp_path):
    """A reader of the writer's own thread cannot be waited for: one line, not 'damaged'."""
    run = small_run(tmp_path / "run.h5")
    with RunStore(run, "r"):
        with pytest.raises(Exception) as e:
            write_session(run)
    msg = str(e.value)
    assert "damaged" not in msg and "another writer" not in msg
    assert "open for reading" in msg and str(run) in msg
    write_session(run)                              # the reader closed: it goes through


READER = """
import sys
from labid.store import RunStore
with RunStore(sys.argv[1], "r") as st:
    st.n_shots("hammer")
    print("reading", flush=True)
    sys.stdin.readline()
"""


def test_a_reader_in_another_process_is_not_another_writer(tmp_path):
    """Readers take no lock (store.lock): a labid reader in another process held HDF5's
    shared lock on the run, and a writer was refused as 'another writer (... a hard link)'."""
    run = small_run(tmp_path / "run.h5")
    proc = child(READER, str(run))
    try:
        assert proc.stdout.readline().strip() == "reading"
        write_session(run)
    finally:
        proc.communicate("\n")
    assert proc.returncode == 0
    with RunStore(run, "r") as st:
        assert st.n_shots("hammer") == 3 and "gui" in st.result_names()
