"""labid decides its own BLAS/OpenMP threading (labid.base.threads): precedence,
effect on the loaded libraries, children and worker processes, bad values."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

from labid.base import threads
from labid.base.errors import UserError


def _clean_env(**extra: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in threads.STANDARD_VARS and k != "LABID_THREADS"}
    env.update(extra)
    return env


def _probe(code: str, env: dict) -> dict:
    """Run ``code`` (which prints one JSON line last) in a fresh interpreter."""
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, capture_output=True,
                         text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_precedence_flag_then_labid_variable_then_user_variables_then_one():
    assert threads.decide(3, {"LABID_THREADS": "2", "OMP_NUM_THREADS": "4"}) == threads.ThreadChoice(3, "--threads")
    assert threads.decide(None, {"LABID_THREADS": "2", "OMP_NUM_THREADS": "4"}) == \
        threads.ThreadChoice(2, "LABID_THREADS")
    assert threads.decide(None, {"OPENBLAS_NUM_THREADS": "4"}) == threads.ThreadChoice(None, "environment")
    assert threads.decide(None, {}) == threads.ThreadChoice(1, "default")


@pytest.mark.parametrize("bad", ["0", "-2", "two", "1.5"])
def test_bad_thread_counts_are_user_errors(bad):
    with pytest.raises(UserError, match="LABID_THREADS"):
        threads.decide(None, {"LABID_THREADS": bad})


_LIBS = """
    import json, numpy, scipy.linalg
    from threadpoolctl import threadpool_info
    from labid.base import threads
    libs = lambda: {i["filepath"]: int(i["num_threads"]) for i in threadpool_info()}   # noqa: E731
    before = libs()
    choice = threads.configure()
    print(json.dumps({"before": before, "after": libs(),
                      "omp": __import__("os").environ.get("OMP_NUM_THREADS")}))
"""


def test_default_is_one_thread_in_every_loaded_library():
    r = _probe(_LIBS, _clean_env())
    assert r["after"] and set(r["after"].values()) == {1}
    assert r["omp"] == "1"          # and for libraries loaded later and child processes


def test_user_variables_still_win():
    r = _probe(_LIBS, _clean_env(OPENBLAS_NUM_THREADS="2"))
    assert r["after"] == r["before"]       # labid changed nothing
    r = _probe(_LIBS, _clean_env(LABID_THREADS="2"))
    assert set(r["after"].values()) == {2}


def test_worker_processes_get_the_choice():
    code = """
        import json, multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        import numpy, scipy.linalg
        from labid.base import threads

        def probe(_):
            import scipy.linalg  # noqa: F401  (loaded in the worker too)
            from threadpoolctl import threadpool_info
            return sorted({int(i["num_threads"]) for i in threadpool_info()})

        if __name__ == "__main__":
            threads.configure()
            out = {}
            for method in ("spawn", "fork"):
                ctx = multiprocessing.get_context(method)
                with ProcessPoolExecutor(1, mp_context=ctx, initializer=threads.worker_init,
                                         initargs=(threads.for_workers(),)) as ex:
                    out[method] = ex.submit(probe, 0).result()
            print(json.dumps(out))
    """
    path = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"labid_threads_probe_{os.getpid()}.py")
    with open(path, "w") as f:
        f.write(textwrap.dedent(code))
    try:
        out = subprocess.run([sys.executable, path], env=_clean_env(), capture_output=True, text=True,
                             check=True).stdout
    finally:
        os.unlink(path)
    r = json.loads(out.strip().splitlines()[-1])
    assert r == {"spawn": [1], "fork": [1]}


def test_cli_rejects_a_bad_thread_count_in_one_line():
    p = subprocess.run([sys.executable, "-m", "labid.cli.main", "modes", "cfrp", "--threads", "0"],
                       capture_output=True, text=True, env=_clean_env())
    assert p.returncode == 2
    assert p.stderr.strip().count("\n") == 0 and "--threads" in p.stderr and "Traceback" not in p.stderr
    p = subprocess.run([sys.executable, "-m", "labid.cli.main", "modes", "cfrp"],
                       capture_output=True, text=True, env=_clean_env(LABID_THREADS="many"))
    assert p.returncode == 2 and "LABID_THREADS" in p.stderr and "Traceback" not in p.stderr


def test_decided_before_numpy_the_variables_alone_limit_every_library():
    """The command line decides before the command's module imports numpy (issue 29, session 26):
    no threadpoolctl then, and the libraries numpy loads afterwards still run one thread."""
    r = _probe("""
        import json, sys
        from labid.base import threads
        threads.configure()
        early = "threadpoolctl" in sys.modules
        import numpy, scipy.linalg
        threads.configure()                 # again, as the command does: nothing to limit
        late = "threadpoolctl" in sys.modules
        from threadpoolctl import threadpool_info
        print(json.dumps({"early": early, "late": late,
                          "after": sorted({int(i["num_threads"]) for i in threadpool_info()})}))
    """, _clean_env())
    assert r == {"early": False, "late": False, "after": [1]}
    r = _probe("""
        import json
        from labid.base import threads
        threads.configure(1)
        import numpy, scipy.linalg
        threads.configure(2)                # another count once loaded: limited now
        from threadpoolctl import threadpool_info
        print(json.dumps({"after": sorted({int(i["num_threads"]) for i in threadpool_info()})}))
    """, _clean_env())
    assert r == {"after": [2]}
