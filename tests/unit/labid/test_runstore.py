"""The HDF5 run store: round trip, resume, results groups, crash safety."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest

from drivers.protocol import ChannelConfig, Record, Timing, Trigger
from labid.base.errors import UserError
from labid.store import RunStore

CH = (ChannelConfig("force", "force", "ai0", sensitivity=2.25e-3, coupling="IEPE"),
      ChannelConfig("acc1", "accelerometer", "ai1", sensitivity=1.02e-3, x=0.02, y=0.03, mass_kg=0.002))
TIMING = Timing(10_000.0, 1000, 100)
TRIG = Trigger("force", 0.02, "rising")


def record(i: int, n: int = 1000, channels=CH) -> Record:
    rng = np.random.default_rng(i)
    return Record(data={c.name: rng.standard_normal(n) for c in channels}, channels=channels,
                  timing=Timing(TIMING.rate_hz, n, TIMING.pretrigger), trigger=TRIG, overload={"force": i % 2 == 1, "acc1": False},
                  timestamp=1.7e9 + i, backend="mock", meta={"i": i, "note": "x"})


def test_round_trip_keeps_data_and_every_setting(tmp_path):
    p = tmp_path / "run.h5"
    recs = [record(i) for i in range(3)]
    with RunStore(p) as s:
        s.write_config("name = 'plate'\n", "name = 'rig'\n")
        names = [s.append_shot(r, "hammer") for r in recs]
    assert names == ["hammer_0001", "hammer_0002", "hammer_0003"]
    with RunStore(p, "r") as s:
        assert s.specimen_toml() == "name = 'plate'\n" and s.rig_toml() == "name = 'rig'\n"
        assert s.n_shots() == 3 and s.n_shots("hammer") == 3 and s.n_shots("wave") == 0
        back = s.shots("hammer")
    for a, b in zip(recs, back):
        for c in CH:
            np.testing.assert_array_equal(a.data[c.name], b.data[c.name])
        assert b.channels == a.channels and b.timing == a.timing and b.trigger == a.trigger
        assert b.overload == a.overload and b.timestamp == a.timestamp and b.backend == "mock"
        assert b.meta["i"] == a.meta["i"] and b.meta["kind"] == "hammer"
        assert b.t0_index == 100 and b.scaled("acc1")[5] == a.data["acc1"][5] / 1.02e-3


def test_nexus_attributes_and_compressed_chunked_rows(tmp_path):
    p = tmp_path / "run.h5"
    hi = (ChannelConfig("mfc1"),)
    with RunStore(p) as s:
        s.append_shot(Record({"mfc1": np.zeros(4096)}, hi, Timing(2e6, 4096, 400), None,
                             {"mfc1": False}), "wave")
    with h5py.File(p, "r") as f:
        assert f.attrs["NX_class"] == "NXroot" and f.attrs["labid_schema"] == 1
        ds = f["shots/wave/mfc1"]
        assert ds.attrs["units"] == "V" and ds.chunks == (1, 4096) and ds.compression == "gzip"
        assert f["shots/wave"].attrs["NX_class"] == "NXdata" and f["shots/wave/timestamp"].attrs["units"] == "s"


def test_resume_appends_and_keeps_numbering(tmp_path):
    p = tmp_path / "run.h5"
    with RunStore(p) as s:
        s.write_config("a = 1\n", "b = 2\n")
        s.append_shot(record(0), "hammer")
    with RunStore(p) as s:
        s.write_config("a = 1\n", "b = 2\n")          # same config: fine
        assert s.append_shot(record(1), "hammer") == "hammer_0002"
        with pytest.raises(UserError, match="specimen"):
            s.write_config("a = 3\n", "b = 2\n")
    with RunStore(p, "r") as s:
        assert [r.meta["i"] for r in s.shots()] == [0, 1]
        assert [r.meta["i"] for r in s.shots("hammer", limit=1)] == [0]
        assert [m["i"] for m in s.metas("hammer")] == [0, 1] and s.metas("wave") == []
        with pytest.raises(UserError, match="read-only"):
            s.append_shot(record(2), "hammer")


def test_resume_with_other_channels_is_refused(tmp_path):
    p = tmp_path / "run.h5"
    with RunStore(p) as s:
        s.append_shot(record(0), "hammer")
        with pytest.raises(UserError, match="differ"):
            s.declare("hammer", CH[:1], TIMING, TRIG)


def test_results_groups_round_trip(tmp_path):
    p = tmp_path / "run.h5"
    feats = {"modal": {"frequencies_hz": np.array([37.3, 85.8]), "n": 2, "ok": True},
             "waves": [{"mode": "A0", "cg": [812.0, 1103.0]}, {"mode": "S0", "cg": [5000.0]}],
             "labels": ["a", "b"], "specimen": "cfrp", "missing": None, "mixed": [1, "x", 2.5]}
    with RunStore(p) as s:
        s.append_shot(record(0), "hammer")
        s.write_group("features", feats)
        s.append_shot(record(1), "hammer")        # back to shot mode after a results write
        s.write_group("features", feats)          # replaces
    with RunStore(p, "r") as s:
        g = s.read_group("features")
        assert s.n_shots() == 2
    np.testing.assert_array_equal(g["modal"]["frequencies_hz"], [37.3, 85.8])
    assert g["modal"]["n"] == 2 and bool(g["modal"]["ok"]) is True
    assert g["waves"][1]["mode"] == "S0" and list(g["waves"][0]["cg"]) == [812.0, 1103.0]
    assert g["labels"] == ["a", "b"] and g["specimen"] == "cfrp" and g["missing"] is None
    assert g["mixed"] == [1, "x", 2.5]


def test_uncommitted_rows_are_dropped_on_reopen(tmp_path):
    """Rows written past the commit marker (a shot cut short) do not count and are overwritten."""
    p = tmp_path / "run.h5"
    with RunStore(p) as s:
        s.append_shot(record(0), "hammer")
    with h5py.File(p, "a") as f:                   # a writer killed before its commit
        for name in ("force", "acc1", "timestamp", "overload", "backend", "software_version", "meta"):
            f["shots/hammer"][name].resize(2, axis=0)
    with RunStore(p, "r") as s:
        assert s.n_shots() == 1
    with RunStore(p) as s:
        assert s.append_shot(record(5), "hammer") == "hammer_0002"
    with RunStore(p, "r") as s:
        np.testing.assert_array_equal(s.shots()[1].data["acc1"], record(5).data["acc1"])


WRITER = textwrap.dedent("""
    import sys, hashlib, numpy as np
    sys.path.insert(0, {root!r})
    from tests.unit.labid.test_runstore import record
    from labid.store import RunStore
    with RunStore(sys.argv[1]) as s:
        i = s.n_shots()
        while True:
            r = record(i, 20000)
            name = s.append_shot(r, "hammer")
            print(name, hashlib.sha256(r.data["acc1"].tobytes()).hexdigest(), flush=True)
            i += 1
""")


@pytest.mark.slow
def test_sigkill_mid_write_keeps_every_committed_shot(tmp_path):
    """Kill a writer at several moments (each on an event: after the k-th shot it reports
    committed, while it writes the next one, whatever the machine's load); the file opens,
    every shot reported committed is intact, and reopening appends after them."""
    root = str(Path(__file__).resolve().parents[3])
    script = tmp_path / "writer.py"
    script.write_text(WRITER.format(root=root))
    p = tmp_path / "run.h5"
    committed: dict[str, str] = {}
    for after in (2, 3, 1, 4):
        proc = subprocess.Popen([sys.executable, str(script), str(p)], stdout=subprocess.PIPE, text=True)
        for _ in range(after):
            name, digest = proc.stdout.readline().split()
            committed[name] = digest
        proc.send_signal(signal.SIGKILL)       # the next shot is being written
        out, _ = proc.communicate()
        committed.update(dict(ln.split() for ln in out.splitlines() if ln.strip()))
        with RunStore(p, "r") as s:
            recs = s.shots("hammer")
        assert len(recs) >= len(committed)
        for r in recs:
            i = r.meta["i"]
            assert r.meta["shot"] == f"hammer_{i + 1:04d}"
            h = hashlib.sha256(r.data["acc1"].tobytes()).hexdigest()
            assert h == hashlib.sha256(record(i, 20000).data["acc1"].tobytes()).hexdigest()
            if r.meta["shot"] in committed:
                assert committed[r.meta["shot"]] == h
    assert len(committed) > 4


def test_reader_follows_a_live_writer(tmp_path):
    """A read-only store opened while a writer appends sees the new committed shots."""
    p = tmp_path / "run.h5"
    w = RunStore(p)
    w.append_shot(record(0), "hammer")
    r = RunStore(p, "r")
    assert r.n_shots() == 1
    w.append_shot(record(1), "hammer")
    assert r.n_shots() == 2 and r.shots()[1].meta["i"] == 1
    r.close()
    w.close()


def test_writer_killed_outside_swmr_mode_is_readable_and_repaired(tmp_path):
    """A writer killed after writing results (normal mode, flags set without SWMR)."""
    p = tmp_path / "run.h5"
    with RunStore(p) as s:
        s.append_shot(record(0), "hammer")
    root = str(Path(__file__).resolve().parents[3])
    code = (f"import sys; sys.path.insert(0, {root!r})\n"
            "from labid.store import RunStore\n"
            f"s = RunStore({str(p)!r})\n"
            "s.write_group('features', {'f': [1.0, 2.0]})\n"
            "print('ready', flush=True); sys.stdin.readline()\n")      # killed while it waits here
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    proc.kill()
    proc.wait()
    with pytest.raises(OSError, match="consistency flags"):
        h5py.File(p, "r")
    with RunStore(p, "r") as s:
        assert s.n_shots() == 1 and list(s.read_group("features")["f"]) == [1.0, 2.0]
    with RunStore(p) as s:
        assert s.append_shot(record(1), "hammer") == "hammer_0002"
    with h5py.File(p, "r") as f:                 # repaired: opens without help
        assert f["shots/hammer/committed"].shape == (2,)


def test_write_result_keeps_a_json_copy_even_when_hdf5_cannot_hold_the_structure(tmp_path):
    import json
    nested = {"parameters": {"E": {"value": 71.0e9, "std": np.float64(np.nan)}},
              "effects": [{"name": "sensor_mass", "magnitude": 0.003}],   # list of dicts: JSON only
              "converged": True}
    with RunStore(tmp_path / "r.h5", "a") as st:
        st.write_result("identification", {"values": np.array([1.0, 2.0]), "converged": True})
        st.write_result("diagnosis", nested)
    with RunStore(tmp_path / "r.h5", "r") as st:
        ident = st.read_group("identification")
        diag = st.read_group("diagnosis")
    np.testing.assert_array_equal(ident["values"], [1.0, 2.0])          # structured part
    assert json.loads(ident["json"]) == {"values": [1.0, 2.0], "converged": True}
    doc = json.loads(diag["json"])
    assert doc["effects"][0] == {"name": "sensor_mass", "magnitude": 0.003}
    assert doc["parameters"]["E"]["std"] is None                       # NaN -> null, valid JSON


def test_lookup3_reproduces_the_superblock_checksum_hdf5_writes(tmp_path):
    """The reason h5repair keeps its own lookup3: h5py has no h5clear, so clearing the
    flags means rewriting the superblock checksum, which must equal the library's."""
    from labid.store.h5repair import lookup3
    for libver in ("v108", "latest"):
        p = tmp_path / f"sb_{libver}.h5"
        with h5py.File(p, "w", libver=libver) as f:
            f.attrs["x"] = 1
        head = p.read_bytes()[:64]
        assert head[8] in (2, 3)                       # superblock version 2/3 (checksummed)
        n = 12 + 4 * head[9]
        assert lookup3(head[:n]) == int.from_bytes(head[n:n + 4], "little")
    # Bob Jenkins' published test vector of hashlittle: "Four score and seven years ago" -> 0x17770551
    assert lookup3(b"Four score and seven years ago") == 0x17770551
