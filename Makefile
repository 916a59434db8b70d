# sieve-mi: the two quick-start commands are `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SCENE  ?= scenes/default.toml

.PHONY: setup demo test test-fast lint bench clean

setup: $(STAMP)

# The virtual environment, the package and its dependencies, a libLLVM (>= 17) that Dr.Jit accepts,
# and (best effort, never failing) a headless Chromium for the browser tests of report.html.
$(STAMP): pyproject.toml tools/ensure_llvm.sh tools/ensure_chromium.sh
	bash tools/ensure_llvm.sh
	-bash tools/ensure_chromium.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,cluster,shake]'
	touch $(STAMP)

demo: setup
	$(VENV)/bin/sieve-mi solve $(SCENE)

test: setup
	$(PY) -m pytest -q -n 2 --dist worksteal --durations=15 tests

lint: setup
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) tools/long_functions.py 80
	$(PY) tools/layering.py

test-fast: setup
	$(PY) -m pytest -q -m "not slow" tests

bench: setup
	$(PY) -m benchmarks.run

clean:
	rm -rf out build *.egg-info
