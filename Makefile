# The two commands of the README: `make demo` (set-up + main job) and `make test` (set-up + tests).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# A CPU build of torch: pinned, and taken from a local wheel folder when the machine has one.
TORCH ?= torch==2.13.0
WHEELS := $(if $(wildcard /opt/wheels),--find-links /opt/wheels,)

.PHONY: setup demo test test-all bench clean

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

clean:
	rm -rf $(VENV) results .pytest_cache
