# The two commands of the README: `make demo` (set-up + main job) and `make test` (set-up + tests).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# A CPU build of torch, pinned: from a local wheel folder when the machine has one, else from PyTorch's CPU index
# (PyPI's Linux wheels of torch are CUDA builds that pull GBs of NVIDIA packages; TORCH_INDEX= takes PyPI's).
TORCH ?= torch==2.13.0
LOCAL_WHEELS ?= /opt/wheels
TORCH_INDEX ?= https://download.pytorch.org/whl/cpu
WHEELS := $(if $(wildcard $(LOCAL_WHEELS)),--find-links $(LOCAL_WHEELS),)
TORCH_SOURCE := $(if $(WHEELS),$(WHEELS),$(if $(TORCH_INDEX),--index-url $(TORCH_INDEX),))
# The main job's clock starts when make does, so that set-up counts against its time budget.
DEMO_START := $(shell date +%s)
DEMO_SECONDS ?= 690

.PHONY: setup demo test test-all bench wheels clean

setup: $(VENV)/.installed

# A line every 20 s while pip works silently (unpacking torch takes minutes on a slow disk).
$(VENV)/.installed: pyproject.toml
	@echo "setting up $(VENV) (first time only): torch (CPU build), then ecorl and its dependencies"
	$(PYTHON) -m venv $(VENV)
	@(while sleep 20; do echo "  ... still setting up $(VENV) ($$(date +%T))"; done) & ticker=$$!; \
	  ( $(BIN)/python -c "import torch" 2>/dev/null || $(BIN)/pip install --progress-bar off $(TORCH_SOURCE) "$(TORCH)" ) \
	  && $(BIN)/pip install --progress-bar off $(WHEELS) -e ".[dev]" | grep -E "^(Collecting|Successfully)"; \
	  kill $$ticker
	$(BIN)/python -c "import ecology, train" && $(BIN)/python -m train.warmup && touch $@

# The headline's contrast, live: static vs dynamic non-episodic salad (waypoint reward, 3 seeds), as many steps (up
# to the paper's 1 M) as this machine trains by DEMO_SECONDS after make started (the quick budget's 100 000 took
# under 2 minutes on a 2-core AMD EPYC); the page leads with the shipped paper-budget panels.
demo: setup
	$(BIN)/ecorl run headline-waypoint --budget quick --condition static-reset-free dynamic-reset-free \
		--steps 1000000 --out results --report \
		--minutes $$($(BIN)/python -c "import time; print(round(($(DEMO_SECONDS) - (time.time() - $(DEMO_START))) / 60, 2))")

# The suite on every core (pytest-xdist), a test file per worker so each module's fixtures are built once.
PYTEST_PARALLEL ?= -n auto --dist loadfile

test: setup
	$(BIN)/python -m pytest -q $(PYTEST_PARALLEL)

test-all: setup
	$(BIN)/python -m pytest -q $(PYTEST_PARALLEL) -m ""

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
