"""The original code's dynamics, rule by rule, on hand-drawn worlds (issue: dynamics as the original has them).

Each test pins one rule that an earlier version of the engine got differently: new objects may grow under
the agent; growth comes before ageing; replenishment counts the grid only; hunting's deer move before the
agent's pick-up / place; a random step is one of a fixed set of directions, taken only if free; and the
original's farmable ``waypoint`` reward.
"""

from __future__ import annotations

import numpy as np
import pytest
from fixtures import cells, make, world_from_map

import gridtasks
from gridtasks import engine
from gridtasks.codes import Code
from gridtasks.engine import EAST, INTERACT, NORTH, PICK_UP, PLACE

ONLY_THE_AGENTS_CELL_FREE = """
#######
#SSSSS#
#SSSSS#
#SS@SS#
#SSSSS#
#SSSSS#
#######
"""
"""A world whose only free interior cell is the agent's (3, 3): whatever grows, grows under the agent."""
SIZE = 7
"""Every world here is 7×7 (numba mis-compiles when one process mixes several grid sizes)."""
CORNERS = """
#######
#L....#
#.....#
#.....#
#.....#
#....C#
#######
"""
"""A lettuce at (1, 1), a carrot at (5, 5)."""
WORKERS = """
#######
#X....#
#.....#
#..m..#
#.....#
#....w#
#######
"""


def salad(**kwargs):
    return make(gridtasks.SaladEnv, SIZE, **kwargs)


# ---------------------------------------------------------------------------------------------- spawn on agent


def test_an_ingredient_grows_under_the_agent_and_is_picked_up_on_the_next_step():
    env = salad(dynamism=0.0)
    world = world_from_map(env, ONLY_THE_AGENTS_CELL_FREE)
    env.step(INTERACT)  # no lettuce or carrot on the grid: the lettuce regrows on the only free cell
    assert world["grid"][3, 3] == Code.LETTUCE and tuple(world["agent"]) == (3, 3)
    _, reward, *_ = env.step(PICK_UP)
    assert world["inventory"] == Code.LETTUCE


def test_with_spawn_on_agent_off_nothing_grows_under_the_agent():
    env = salad(dynamism=0.0, spawn_on_agent=False)
    world = world_from_map(env, ONLY_THE_AGENTS_CELL_FREE)
    for _ in range(10):
        env.step(INTERACT)
    assert world["grid"][3, 3] == Code.EMPTY


def test_nothing_grows_on_the_agents_start_cell():
    env = salad(dynamism=0.0)
    world = world_from_map(env, ONLY_THE_AGENTS_CELL_FREE, start=(3, 3))
    for _ in range(10):
        env.step(INTERACT)
    assert world["grid"][3, 3] == Code.EMPTY


def test_reset_records_the_start_cell():
    env = gridtasks.SaladEnv()
    for seed in range(5):
        env.reset(seed=seed)
        world = env.unwrapped.world
        assert tuple(world["start"]) == tuple(world["agent"])


# ---------------------------------------------------------------------------------------------- grow, then age


@pytest.mark.parametrize("lifespan, dynamism", [(4, 0.5), (2, 1.0), (20, 0.1)])
def test_a_grown_ingredient_can_be_picked_up_on_exactly_lifespan_minus_one_steps(lifespan, dynamism):
    # initial_count 2 and p give lifespan int(2 / p); the lettuce grows under the agent on step 0 and is
    # gone on step `lifespan` (a new one regrows there at the end of that step)
    pickable = []
    for wait in range(1, lifespan + 1):
        env = salad(dynamism=dynamism, initial_count=2)
        assert env.unwrapped.rules[0]["lifespan"][Code.LETTUCE] == lifespan
        world = world_from_map(env, ONLY_THE_AGENTS_CELL_FREE)
        env.step(INTERACT)
        assert world["grid"][3, 3] == Code.LETTUCE
        for _ in range(wait - 1):
            env.step(INTERACT)
        env.step(PICK_UP)
        pickable.append(bool(world["inventory"] == Code.LETTUCE))
    assert pickable == [True] * (lifespan - 1) + [False]


# ---------------------------------------------------------------------------------------------- grid-only counts


def test_picking_up_the_last_lettuce_grows_one_at_once():
    env = salad(dynamism=0.0)
    world = world_from_map(env, CORNERS, agent=(1, 1))
    env.step(PICK_UP)
    assert world["inventory"] == Code.LETTUCE
    assert len(cells(world, Code.LETTUCE)) == 1  # regrown in the same step


def test_hunting_keeps_two_axes_on_the_grid_while_the_agent_carries_a_third():
    env = make(gridtasks.HuntingEnv, SIZE, deer_count=2, axe_count=2)
    world = world_from_map(env, """
    #######
    #A....#
    #.....#
    #..D..#
    #...D.#
    #....A#
    #######
    """, agent=(1, 1))
    env.step(PICK_UP)
    assert world["inventory"] == Code.AXE
    assert len(cells(world, Code.AXE)) == 2


# ---------------------------------------------------------------------------------------------- hunting order


def test_deer_move_before_the_agents_place():
    # a deer under an axe-carrying agent, p = 1 and every neighbour free: the original moves the deer
    # away before the place, so the axe is dropped on the empty cell instead of making food
    env = make(gridtasks.HuntingEnv, SIZE, replenish=False, dynamism=1.0)
    for _ in range(20):
        world = world_from_map(env, CORNERS.replace("L", ".").replace("C", "."), agent=(3, 3), inventory=Code.AXE)
        world["grid"][3, 3] = Code.DEER
        env.step(PLACE)
        assert world["grid"][3, 3] == Code.AXE and world["inventory"] == 0
        assert cells(world, Code.FOOD) == [] and len(cells(world, Code.DEER)) == 1


def test_factory_workers_move_after_the_agents_interact():
    env = make(gridtasks.FactoryEnv, SIZE, dynamism=1.0)
    for _ in range(20):
        world = world_from_map(env, WORKERS, agent=(3, 3))
        env.step(INTERACT)
        assert world["inventory"] == Code.METAL  # the worker was still under the agent


# ---------------------------------------------------------------------------------------------- waypoint


def test_waypoint_pays_every_ingredient_pick_up_again_after_a_drop():
    env = salad(reward="waypoint")
    world = world_from_map(env, CORNERS, agent=(1, 1))
    rewards = []
    for action in (PICK_UP, EAST, PLACE, PICK_UP, PLACE, PICK_UP):
        _, reward, *_ = env.step(action)
        rewards.append(reward)
    assert world["inventory"] == Code.LETTUCE
    assert rewards == [1.0, 0.0, 0.0, 1.0, 0.0, 1.0]  # pick, move, drop, pick, drop, pick


def test_subgoal_pays_an_ingredient_once_per_cycle():
    env = salad(reward="subgoal")
    world_from_map(env, CORNERS, agent=(1, 1))
    rewards = [env.step(a)[1] for a in (PICK_UP, PLACE, PICK_UP, PLACE, PICK_UP)]
    assert rewards == [1.0, 0.0, 0.0, 0.0, 0.0]


def test_waypoint_pays_making_a_salad_and_100_for_picking_it_up():
    env = salad(reward="waypoint", reset_free=True)
    world_from_map(env, CORNERS, agent=(1, 1))
    moves = [EAST] * 4 + [engine.SOUTH] * 4
    rewards = [env.step(a)[1] for a in (PICK_UP, *moves, PLACE, PICK_UP)]
    assert rewards == [1.0] + [0.0] * 8 + [1.0, 100.0]


def test_hunting_waypoint_is_progress_based_as_in_the_original():
    env = make(gridtasks.HuntingEnv, SIZE, replenish=False, reward="waypoint")
    world_from_map(env, CORNERS.replace("L", "A").replace("C", "D"), agent=(1, 1))
    rewards = [env.step(a)[1] for a in (PICK_UP, EAST, PLACE, engine.WEST, PICK_UP)]
    assert rewards == [1.0, 0.0, 0.0, 0.0, 0.0]  # re-picking the dropped axe pays nothing


def test_factory_waypoint_pays_every_dispense():
    env = make(gridtasks.FactoryEnv, SIZE, reward="waypoint")
    world_from_map(env, WORKERS, agent=(3, 3))
    rewards = [env.step(a)[1] for a in (INTERACT, NORTH, PLACE, engine.SOUTH, INTERACT)]
    assert rewards == [1.0, 0.0, 0.0, 0.0, 1.0]


def test_waypoint_is_a_reward_mode_of_every_grid_task():
    for cls in gridtasks.TASKS.values():
        env = cls(reward="waypoint")
        assert env.ecology.reward == "waypoint"


# ---------------------------------------------------------------------------------------------- episodic replay


def layouts_of_episodes(env, episodes: int) -> list[bytes]:
    """Grid bytes at the start of each of ``episodes`` episodes of a vector env stepping 'interact' only
    (so no episode is ever solved).
    """
    starts = [env.worlds["grid"][0].tobytes()]
    while len(starts) < episodes:
        *_, terminated, truncated, _ = env.step(np.full(1, INTERACT))
        if truncated[0] or terminated[0]:
            env.step(np.full(1, INTERACT))  # the autoreset step
            starts.append(env.worlds["grid"][0].tobytes())
    return starts


def test_replay_unsolved_repeats_a_layout_within_a_collection_and_draws_anew_after_it():
    from gridtasks.vector import GridTaskVectorEnv

    # horizon 10, collections of 35 steps: episodes end at world steps 10, 20, 30 (unsolved, replayed),
    # then the collection boundary at 35 cuts the fourth and the fifth starts from a fresh layout
    env = GridTaskVectorEnv(gridtasks.SaladEnv, 1, horizon=10, replay_unsolved=35)
    env.reset(seed=3)
    starts = layouts_of_episodes(env, 5)
    assert starts[0] == starts[1] == starts[2] == starts[3]
    assert starts[4] != starts[0]


def test_without_replay_every_episode_draws_a_fresh_layout():
    from gridtasks.vector import GridTaskVectorEnv

    env = GridTaskVectorEnv(gridtasks.SaladEnv, 1, horizon=10)
    env.reset(seed=3)
    starts = layouts_of_episodes(env, 4)
    assert len(set(starts)) == 4


def test_replay_is_off_in_the_test_mdp():
    env = gridtasks.SaladEnv(replay_unsolved=500)
    assert env.test_mdp_kwargs()["replay_unsolved"] == 0
    with pytest.raises(ValueError, match="replay_unsolved"):
        gridtasks.SaladEnv(replay_unsolved=-1)
