# The two commands of the README: `make demo` (set-up + main job) and `make test` (set-up + tests).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# A CPU build of torch: pinned, and taken from a local wheel folder when the machine has one.
TORCH ?= torch==2.13.0
WHEELS := $(if $(wildcard /opt/wheels),--find-links /opt/wheels,)

.PHONY: setup demo test test-all bench wheels clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -c "import torch" 2>/dev/null || $(BIN)/pip install -q $(WHEELS) "$(TORCH)"
	$(BIN)/pip install -q $(WHEELS) -e ".[dev]"
	touch $@

demo: setup
	$(BIN)/ecorl run headline-waypoint --budget quick --out results --report

test: setup
	$(BIN)/python -m pytest -q

test-all: setup
	$(BIN)/python -m pytest -q -m ""

bench: setup
	$(BIN)/python benchmarks/bench_gridtasks.py
	$(BIN)/python benchmarks/bench_foodcollector.py
	$(BIN)/python benchmarks/bench_train.py

# The wheels a GPU image with torch, numba, numpy, matplotlib, opencv and tqdm lacks (gymnasium and pymunk
# with their dependencies) for Python 3.12 on manylinux x86_64, into the ignored folder wheels/. Carry it to
# the machine, install there with `pip install --no-index --find-links wheels gymnasium pymunk` and run
# from the repository root (`python -m train.cli ...`), which needs no install of ecorl itself.
WHEELS_DIR ?= wheels
GPU_WHEELS ?= gymnasium pymunk cffi pycparser farama-notifications cloudpickle typing-extensions

wheels:
	$(PYTHON) -m pip download --only-binary=:all: --no-deps --python-version 3.12 \
		--platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux_2_28_x86_64 \
		--implementation cp --dest $(WHEELS_DIR) $(GPU_WHEELS)

clean:
	rm -rf $(VENV) results .pytest_cache
