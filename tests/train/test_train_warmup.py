"""`python -m train.warmup` (run by `make setup`) compiles every numba kernel a run calls, so no later process does."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

EVERY_ENV = """
import gymnasium as gym
import gridtasks, foodcollector
for env_id in [i for i in gym.registry if i.startswith(("gridtasks/", "foodcollector/"))]:
    env = gym.make(env_id, dynamism=0.1, reset_free=True)
    env.reset(seed=0)
    for _ in range(30):
        env.step(env.action_space.sample())
    if env_id.startswith("gridtasks/"):
        vec = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", dynamism=0.1)
        vec.reset(seed=0)
        for _ in range(30):
            vec.step(vec.action_space.sample())
"""


@pytest.mark.slow
def test_after_the_warm_up_the_environments_compile_nothing(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "NUMBA_DEBUG_CACHE": "1", "PYTHONPATH": str(ROOT)}
    warm = subprocess.run([sys.executable, "-m", "train.warmup"], env=env, cwd=ROOT, capture_output=True, text=True)
    assert warm.returncode == 0, warm.stderr[-2000:]
    assert "data saved" in warm.stdout  # it compiled, into the empty cache
    after = subprocess.run([sys.executable, "-c", EVERY_ENV], env=env, cwd=ROOT, capture_output=True, text=True)
    assert after.returncode == 0, after.stderr[-2000:]
    assert "data loaded" in after.stdout
    assert [line for line in after.stdout.splitlines() if "data saved" in line] == []


def test_the_warm_up_asks_for_no_more_environment_threads_than_numba_holds(monkeypatch):
    """One CPU (a 1-core VM, a container or a cluster job pinned to one core): numba's pool holds one thread, and
    `make setup` must not ask for two.
    """
    import numba

    from train import warmup

    asked = []

    class Recorder:
        def __init__(self, cfg):
            asked.append((cfg.env.task, cfg.run.env_threads))

        def train_epoch(self): ...
        def evaluate(self): ...
        def close(self): ...

    monkeypatch.setattr(warmup, "Trainer", Recorder)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 1)
    warmup.warm_up()
    assert {threads for _, threads in asked} == {1} and len(asked) == len(warmup.TASKS)
    asked.clear()
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 16)
    warmup.warm_up()
    assert sorted({threads for _, threads in asked}) == [1, 2] and len(asked) == 2 * len(warmup.TASKS)
