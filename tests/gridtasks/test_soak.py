"""Reset-free worlds run 100 000 random steps without ending, and populations stay within the rules."""

from __future__ import annotations

import numpy as np
import pytest

import gridtasks
from gridtasks import Code
from gridtasks.engine import GROUP

STEPS = 100_000


def group_counts(world) -> np.ndarray:
    """Population of each group: objects on the grid plus the carried one."""
    counts = np.bincount(GROUP[world["grid"].ravel()], minlength=len(Code))
    counts[GROUP[world["inventory"]]] += world["inventory"] != 0
    return counts


def grid_counts(world) -> np.ndarray:
    """Population of each group on the grid (the original's replenishment count)."""
    return np.bincount(GROUP[world["grid"].ravel()], minlength=len(Code))


def check_salad(world, env):
    on_grid, counts = grid_counts(world), group_counts(world)
    rules = env.rules[0]
    for code in (Code.LETTUCE, Code.CARROT):
        # growth adds one only while at most the cap lie on the grid, so with the carried one at most
        # cap + 2 exist; withering (after growth) may empty the grid for a step, otherwise regrowth keeps
        # one of each kind there
        lowest = 1 if rules["lifespan"][code] == 0 else 0
        assert lowest <= on_grid[code] and counts[code] <= rules["growth_cap"] + 2, f"{code.name}: {counts[code]}"
    assert (world["grid"][[0, -1], :] == Code.WALL).all() and (world["grid"][:, [0, -1]] == Code.WALL).all()


def check_hunting(world, env):
    on_grid, counts = grid_counts(world), group_counts(world)
    assert 1 <= on_grid[Code.DEER] <= 2
    assert counts[Code.AXE] <= 3  # two are kept on the grid while one is carried (and may be dropped)


def check_scavenging(world, env):
    counts = group_counts(world)
    assert 1 <= counts[Code.FOOD] <= 2
    n = env.config.grid_size
    assert ((world["pred"][:2] >= 1) & (world["pred"][:2] <= n - 2)).all()
    assert (world["pred_age"][:2] < env.config.predator_lifespan).all()


def check_factory(world, env):
    counts = group_counts(world)
    assert counts[Code.METAL_WORKER] == counts[Code.WOOD_WORKER] == counts[Code.DEPOT] == 1
    assert world["grid"][1, 1] == Code.DEPOT
    # workers dispense while at most max_material lie on the grid, so one more can be dropped there
    assert counts[Code.METAL] <= env.config.max_material + 1 and counts[Code.WOOD] <= env.config.max_material + 1


CASES = [
    ("salad", {"dynamism": 0.1}, check_salad),
    ("salad", {"dynamism": 0.0, "shaping": "linear:1:0:50000"}, check_salad),
    ("walled-salad", {"dynamism": 0.05, "shaping": 0.5}, check_salad),
    ("hunting", {"dynamism": 0.2, "shaping": 0.5}, check_hunting),
    ("hunting", {"shaping": 1.0, "shaping_mechanism": "nearby", "deer_kind": "hard", "deer_speed": 0.3},
     check_hunting),
    ("scavenging", {"dynamism": 0.3, "shaping": 0.5}, check_scavenging),
    ("factory", {"dynamism": 0.2, "shaping": 0.3}, check_factory),
]


@pytest.mark.parametrize(("task", "knobs", "check"), CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_reset_free_soak(task, knobs, check):
    env = gridtasks.TASKS[task](reset_free=True, reward="one_time", **knobs)
    env.reset(seed=123)
    world = env.world
    actions = np.random.default_rng(0).integers(0, 7, STEPS)
    completions = 0
    for t, a in enumerate(actions):
        _, _, terminated, truncated, info = env.step(int(a))
        assert not (terminated or truncated)
        completions += info["solved"]
        if t % 97 == 0:
            check(world, env)
    assert info["lifetime_step"] == STEPS
    assert completions == info["completions"]
    if task != "scavenging":  # scavenging completions are rare but not guaranteed to be > 0 under attack
        assert completions > 0, "a random agent never completed the task in 100 000 steps"
