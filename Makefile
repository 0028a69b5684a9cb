# The two commands of the README. Both set up .venv by themselves.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
OUT    ?= demo_out

.PHONY: test demo bench setup clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@# bytecode, as a non-editable install has it (pip compiles on install): with it a quick command
	@# such as `labid dispersion` starts ~0.08 s sooner (bench/RESULTS.md, session 27 lead); stale
	@# files are harmless, Python checks each against its source's mtime
	$(PY) -m compileall -q engine drivers mock_hw labid
	@touch $(STAMP)

# both cores, one test file per worker (module fixtures built once): 640 tests, 645 s of CPU
# (614 s user + 31 s sys); wall 72 min beside two CPU burners on a shared 2-core EPYC at load
# 10-32, 2026-11-28 (bench/RESULTS.md, "Issue 26, session 22"); the wall time is the load's
test: $(STAMP)
	QT_QPA_PLATFORM=offscreen MPLBACKEND=Agg $(PY) -m pytest -q -n 2 --dist loadfile

demo: $(STAMP)
	QT_QPA_PLATFORM=offscreen MPLBACKEND=Agg $(VENV)/bin/labid demo --out $(OUT)

bench: $(STAMP)
	for b in bench/bench_*.py; do OMP_NUM_THREADS=1 $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache build *.egg-info
