"""Shared fixtures of the trainer, experiment and command-line tests: one torch thread, the ``ecorl`` command
in a fresh interpreter, and every experiment run once at the smoke budget (a task subset where it has many
tasks).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch


@pytest.fixture(autouse=True)
def one_thread():
    """Small tensors: one torch thread avoids OpenMP overhead (and oversubscription on a busy machine)."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)

REPO = Path(__file__).resolve().parents[2]

SMOKE_TASKS = {
    "settings": None,
    "headline": None,
    "headline-waypoint": None,
    "salad-gap": None,
    "lr-sweep": None,
    "episodic-vs-reset-free": None,
    "dynamism": ["foodcollector"],
    "dynamism-waypoint": ["hunting"],
    "hunting-gap": None,
    "dynamism-sweep": ["salad"],
    "dynamism-sweep-waypoint": None,
    "shaping": ["hunting"],
    "shaping-gap": None,
    "rnd": None,
    "walls": None,
    "measure": ["factory"],
    "factory-released": None,
    "factory-make-axe": None,
    "hunting-released": None,
    "hunting-released-fig4": None,
    "foodcollector-episodes-1000": None,
    "hunting-behaviour": None,
    "hunting-inventory": None,
    "factory-behaviour": None,
    "salad-shaping-released": None,
    "scavenging-released": None,
    "scavenging-released-fig4": None,
    "walls-released": None,
}
"""Which tasks of each experiment the smoke fixture runs (None: all of them)."""
SMOKE_CONDITIONS = {
    "settings": ["ep-h100-replay", "rf-batch256"],
    "factory-released": ["dynamic-reset-free", "one-time-reward"],
    "factory-make-axe": ["static-episodic", "rnd"],
    "hunting-released": ["env-shaping-waypoint-260k", "distance-reward"],
    "hunting-released-fig4": ["dynamic-episodic-distance"],
    "foodcollector-episodes-1000": ["dynamic-episodic"],
    "hunting-behaviour": ["eps-1"],
    "hunting-inventory": ["rf-waypoint-inv8"],
    "factory-behaviour": ["released-eps-floor-0.3"],
    "salad-shaping-released": ["env-shaping-sparse"],
    "scavenging-released": ["env-shaping-540k"],
    "scavenging-released-fig4": ["dynamic-episodic"],
    "walls-released": ["env-shaping-sparse-reset-free"],
}
"""Which conditions of an experiment the smoke fixture runs where not all (each new kind of setting once)."""


def run_cli(*args: str, timeout: float = 300, check: bool = True) -> subprocess.CompletedProcess:
    """``ecorl <args>`` through ``python -m train.cli`` in a fresh interpreter; returns the finished process."""
    proc = subprocess.run([sys.executable, "-m", "train.cli", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    if check and proc.returncode != 0:
        raise AssertionError(f"ecorl {' '.join(args)} exited {proc.returncode}:\n{proc.stdout}\n{proc.stderr}")
    return proc


@pytest.fixture(scope="session")
def smoke_tasks() -> dict:
    """`SMOKE_TASKS` as a fixture."""
    return SMOKE_TASKS


@pytest.fixture(scope="session")
def smoke_conditions() -> dict:
    """`SMOKE_CONDITIONS` as a fixture."""
    return SMOKE_CONDITIONS


@pytest.fixture(scope="session")
def cli():
    """`run_cli` as a fixture (test modules do not import each other)."""
    return run_cli


@pytest.fixture(scope="session")
def smoke_root(tmp_path_factory) -> Path:
    """A results directory holding every experiment at the smoke budget (one process pool for all)."""
    from train.experiments.catalog import EXPERIMENTS
    from train.experiments.sweep import plan, run_jobs, summarize, write_experiment_file

    root = tmp_path_factory.mktemp("smoke")
    jobs = []
    for name, tasks in SMOKE_TASKS.items():
        exp_jobs = plan(EXPERIMENTS[name], "smoke", root, tasks, conditions=SMOKE_CONDITIONS.get(name))
        write_experiment_file(EXPERIMENTS[name], "smoke", exp_jobs, root)
        jobs += exp_jobs
    results = run_jobs(jobs, "local", workers=os.cpu_count() or 2, progress=False)
    failed = [r for r in results if r.status != "done"]
    assert not failed, "\n".join(f"{r.job}: {r.status}\n{r.error}" for r in failed)
    assert summarize(results) == {"done": len(jobs)}
    return root
