"""Table 1's conditions are the worlds the experiments train in."""
from __future__ import annotations

import pytest

from ecology import parse_schedule
from gridtasks.env import SpawnRules
from train.experiments.catalog import get_experiment
from train.experiments.table1 import hitting_conditions


def _env_shaping_arms() -> dict[str, dict]:
    """The shaping experiment's environment-shaping arm of each grid task: its overrides."""
    return {task: c.overrides for task, conditions in get_experiment("shaping").conditions.items()
            for c in conditions if c.name == "env-shaping-sparse"}


@pytest.mark.parametrize("task", ["salad", "hunting", "scavenging", "factory"])
def test_table1_shaped_world_is_the_shaping_experiments_world_at_its_start(task):
    """Hunting's shaped world once dropped the hard, fleeing deer the shaping runs train with (easy deer that never
    move: shaping had nothing to act on), so its hitting time was the static world's.
    """
    arm = _env_shaping_arms()[task]
    own = {k: v for k, v in arm.get("env_kwargs", {}).items()  # an arm re-run under the default window names it
           if (k, v) != ("spawn_window", SpawnRules.spawn_window)}
    expected = {**own, "shaping": parse_schedule(arm["shaping"])(0)}
    if "dynamism" in arm:
        expected["dynamism"] = arm["dynamism"]
    assert hitting_conditions(task)["shaped"] == expected
