"""Episode ends (episodic vs reset-free), consumption of completed tasks, the info dict and clocks."""

from __future__ import annotations

import numpy as np
import pytest
from fixtures import cells, make, world_from_map

import gridtasks
from gridtasks.codes import Code
from gridtasks.engine import INTERACT, PICK_UP, WEST

SALAD_ON = """
#######
#.....#
#.L.C.#
#.....#
#..S..#
#.....#
#######
"""
"""A salad at (3, 4) for the agent to stand on."""


@pytest.mark.parametrize("cls", [gridtasks.SaladEnv, gridtasks.HuntingEnv, gridtasks.ScavengingEnv,
                                 gridtasks.FactoryEnv])
def test_episodic_truncates_exactly_at_the_horizon(cls):
    env = cls(horizon=5)
    env.reset(seed=0)
    ends = []
    for _ in range(5):
        _, _, terminated, truncated, _ = env.step(WEST)  # walking west never completes a task
        ends.append((terminated, truncated))
    assert ends == [(False, False)] * 4 + [(False, True)]
    env.reset()
    ends = [env.step(WEST)[2:4] for _ in range(5)]
    assert ends == [(False, False)] * 4 + [(False, True)]


def test_episodic_terminates_on_completion():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world = world_from_map(env, SALAD_ON, agent=(3, 4))
    _, reward, terminated, truncated, info = env.step(PICK_UP)
    assert (reward, terminated, truncated, info["solved"]) == (100, True, False, True)
    assert world["inventory"] == Code.SALAD  # episodic: the agent holds the salad until the reset


@pytest.mark.parametrize("cls", [gridtasks.SaladEnv, gridtasks.HuntingEnv, gridtasks.ScavengingEnv,
                                 gridtasks.FactoryEnv])
def test_reset_free_never_ends(cls):
    env = cls(reset_free=True, horizon=5, dynamism=0.5)
    env.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, 7, 400)
    for a in actions:
        _, _, terminated, truncated, _ = env.step(int(a))
        assert not terminated and not truncated


def test_reset_free_salad_is_consumed_and_the_world_goes_on():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reset_free=True)
    world = world_from_map(env, SALAD_ON, agent=(3, 4))
    obs, reward, terminated, truncated, info = env.step(PICK_UP)
    assert (reward, terminated, truncated, info["solved"]) == (100, False, False, True)
    assert world["inventory"] == 0 and world["grid"][4, 3] == Code.EMPTY
    assert not obs[-5:].any()  # the observation shows empty hands
    assert info["pickup_salad"] == 1 and info["completions"] == 1
    _, reward, _, _, info = env.step(INTERACT)
    assert reward == 0 and not info["solved"] and info["completions"] == 1


def test_reset_free_food_is_eaten():
    env = make(gridtasks.HuntingEnv, 7, replenish=False, reset_free=True)
    world = world_from_map(env, SALAD_ON.replace("S", "F").replace("L", "A").replace("C", "D"), agent=(3, 4))
    _, reward, terminated, _, info = env.step(PICK_UP)
    assert (reward, terminated, info["solved"]) == (100, False, True)
    assert world["inventory"] == 0


def test_info_reports_cell_clock_and_counts():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world_from_map(env, SALAD_ON, agent=(3, 4))
    _, _, _, _, info = env.step(WEST)
    assert tuple(info["agent_pos"]) == (2, 4) and info["agent_pos"].dtype == np.int64  # stacks in every vector mode
    assert info["lifetime_step"] == 1
    assert {"solved", "caught", "completions", "pickup_lettuce", "pickup_carrot", "pickup_salad",
            "made_salad"} <= set(info)


def test_the_lifetime_clock_survives_episode_resets_but_not_seeded_ones():
    env = gridtasks.SaladEnv(horizon=3)
    env.reset(seed=0)
    for _ in range(3):
        env.step(WEST)
    _, info = env.reset()
    assert info["lifetime_step"] == 3 and env.unwrapped.world["episode_step"] == 0
    _, _, _, _, info = env.step(WEST)
    assert info["lifetime_step"] == 4
    _, info = env.reset(seed=1)
    assert info["lifetime_step"] == 0


def test_episode_reset_clears_inventory_counts_and_stage_flags():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward="subgoal")
    world = world_from_map(env, SALAD_ON, agent=(2, 2))
    env.step(PICK_UP)
    assert world["inventory"] == Code.LETTUCE and world["stage_done"].any()
    _, info = env.reset()
    assert world["inventory"] == 0 and not world["stage_done"].any()
    assert info["pickup_lettuce"] == 0 and info["completions"] == 0


def test_reset_draws_a_fresh_layout_each_episode():
    env = gridtasks.SaladEnv()
    env.reset(seed=0)
    layouts = set()
    for _ in range(10):
        env.reset()
        w = env.unwrapped.world
        layouts.add((w["grid"].tobytes(), tuple(w["agent"])))
    assert len(layouts) == 10


def test_reset_places_the_initial_objects_and_the_agent_on_an_empty_cell():
    env = gridtasks.HuntingEnv(deer_count=2, axe_count=3)
    for seed in range(20):
        env.reset(seed=seed)
        w = env.unwrapped.world
        grid = w["grid"]
        assert np.count_nonzero(grid == Code.DEER) == 2 and np.count_nonzero(grid == Code.AXE) == 3
        x, y = w["agent"]
        assert grid[y, x] == Code.EMPTY
        assert (grid[[0, -1], :] == Code.WALL).all() and (grid[:, [0, -1]] == Code.WALL).all()


def test_factory_reset_puts_the_depot_at_1_1_and_one_worker_of_each_kind():
    env = gridtasks.FactoryEnv()
    for seed in range(10):
        env.reset(seed=seed)
        grid = env.unwrapped.world["grid"]
        assert grid[1, 1] == Code.DEPOT
        assert np.count_nonzero(grid == Code.METAL_WORKER) == np.count_nonzero(grid == Code.WOOD_WORKER) == 1


def test_scavenging_reset_puts_predators_on_object_free_cells_the_agents_as_the_original_does():
    """The original places its monsters before the agent, so one may start on the agent's cell."""
    env = gridtasks.ScavengingEnv(predator_count=4)
    on_agent = 0
    for seed in range(100):
        env.reset(seed=seed)
        w = env.unwrapped.world
        for i in range(4):
            x, y = w["pred"][i]
            assert w["grid"][y, x] == Code.EMPTY and w["pred_age"][i] == 0
            on_agent += tuple(w["pred"][i]) == tuple(w["agent"])
    assert 0 < on_agent < 20  # about 400 / 62


def test_scavenging_reset_never_puts_a_predator_on_the_agent_off_agent():
    env = gridtasks.ScavengingEnv(predator_count=4, predator_respawn="off-agent")
    for seed in range(30):
        env.reset(seed=seed)
        w = env.unwrapped.world
        for i in range(4):
            assert tuple(w["pred"][i]) != tuple(w["agent"])
            assert w["pred_age"][i] == 0


def test_reset_free_eaten_food_is_replaced_in_the_same_step():
    env = make(gridtasks.ScavengingEnv, grid_size=7, reset_free=True, predator_count=0)
    world = world_from_map(env, """
    #######
    #.....#
    #.F...#
    #.....#
    #...F.#
    #.....#
    #######
    """, agent=(2, 2))
    _, reward, *_ = env.step(PICK_UP)
    assert reward == 100.0 and world["inventory"] == 0
    assert len(cells(world, gridtasks.Code.FOOD)) == 2
