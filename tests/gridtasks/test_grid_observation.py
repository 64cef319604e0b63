"""The observation layout: channel·25 + row·5 + col, walls outside the grid, centre under the agent,
inventory one-hot at the end, predator overlay.
"""

from __future__ import annotations

import numpy as np
import pytest
from fixtures import make, parse_map, world_from_map

import gridtasks
from gridtasks import engine
from gridtasks.codes import Code
from gridtasks.engine import INTERACT


def reference_view(text: str, agent, channels, predators=()) -> np.ndarray:
    """The expected (channels, 5, 5) view, computed from the map independently of the engine."""
    grid, _, _ = parse_map(text)
    n = grid.shape[0]
    index = {int(code): i for i, code in enumerate(channels)}
    view = np.zeros((len(channels), 5, 5), dtype=np.float32)
    ax, ay = agent
    for row in range(5):
        for col in range(5):
            x, y = ax - 2 + col, ay - 2 + row
            code = int(grid[y, x]) if 0 <= x < n and 0 <= y < n else int(Code.WALL)
            if code in (Code.DEER_EASY, Code.DEER_HARD):
                code = int(Code.DEER)
            view[index[code], row, col] = 1
    for x, y in predators:
        row, col = y - ay + 2, x - ax + 2
        if 0 <= row < 5 and 0 <= col < 5:
            view[index[int(Code.PREDATOR)], row, col] = 1
    return view


def observe(env) -> np.ndarray:
    u = env.unwrapped
    obs = np.zeros(u.observation_space.shape, dtype=np.float32)
    engine.observe(u.world, u.rules[0], obs)
    return obs


SALAD = """
#######
#..C..#
#.L.S.#
#.....#
#C...L#
#.....#
#######
"""


@pytest.mark.parametrize("agent", [(2, 2), (3, 3), (1, 1), (5, 5), (1, 5), (4, 2)])
def test_salad_view_matches_the_map(agent):
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world_from_map(env, SALAD, agent=agent)
    obs = observe(env)
    expected = reference_view(SALAD, agent, env.channels)
    np.testing.assert_array_equal(obs[:125].reshape(5, 5, 5), expected)
    assert not obs[125:].any()


def test_index_is_channel_row_col():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world_from_map(env, SALAD, agent=(2, 2))
    obs = observe(env)
    lettuce, carrot, salad = 2, 3, 4
    assert obs[lettuce * 25 + 2 * 5 + 2] == 1  # the centre: the lettuce under the agent
    assert obs[carrot * 25 + 1 * 5 + 3] == 1  # carrot at (3, 1): row 1 (north of the agent), col 3
    assert obs[carrot * 25 + 3 * 5 + 1] == 0  # not transposed
    assert obs[salad * 25 + 2 * 5 + 4] == 1  # salad at (4, 2): same row, two to the east
    assert obs[carrot * 25 + 4 * 5 + 1] == 1  # carrot at (1, 4): row 4, col 1
    assert obs[:125].reshape(5, 25).sum(axis=0).tolist() == [1.0] * 25  # one channel per cell


def test_cells_outside_the_grid_read_as_wall():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world_from_map(env, SALAD, agent=(1, 1))
    view = observe(env)[:125].reshape(5, 5, 5)
    wall = 1
    assert view[wall, 0, :].all() and view[wall, :, 0].all()  # outside (y = -1, x = -1)
    assert view[wall, 1, :].all() and view[wall, :, 1].all()  # the wall ring
    assert not view[wall, 2:, 2:].any()


@pytest.mark.parametrize("carried, index", [(Code.LETTUCE, 2), (Code.CARROT, 3), (Code.SALAD, 4)])
def test_inventory_one_hot_at_the_end(carried, index):
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world_from_map(env, SALAD, agent=(3, 3), inventory=carried)
    obs = observe(env)
    expected = np.zeros(5, dtype=np.float32)
    expected[index] = 1
    np.testing.assert_array_equal(obs[125:], expected)


def test_step_returns_the_observation_of_the_new_state():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False)
    world_from_map(env, SALAD, agent=(2, 2))
    obs, *_ = env.step(engine.PICK_UP)
    assert obs.dtype == np.float32 and obs.shape == (130,)
    assert obs[0 * 25 + 12] == 1 and obs[2 * 25 + 12] == 0  # the centre is now empty
    assert obs[125 + 2] == 1  # holding the lettuce
    obs2, *_ = env.step(engine.EAST)
    np.testing.assert_array_equal(obs2[:125].reshape(5, 5, 5),
                                  reference_view(SALAD.replace(".L.S", "...S"), (3, 2), env.channels))


def test_every_deer_kind_shows_on_the_deer_channel():
    text = """
    #######
    #.....#
    #.D.E.#
    #..A..#
    #.H.F.#
    #.....#
    #######
    """
    env = make(gridtasks.HuntingEnv, 7, replenish=False)
    world_from_map(env, text, agent=(3, 3), inventory=Code.AXE)
    obs = observe(env)
    assert obs.shape == (130,)
    np.testing.assert_array_equal(obs[:125].reshape(5, 5, 5), reference_view(text, (3, 3), env.channels))
    deer = 3
    assert obs[deer * 25:(deer + 1) * 25].sum() == 3
    assert obs[125:].tolist() == [0, 0, 1, 0, 0]


def test_factory_channels():
    text = """
    #######
    #X....#
    #.M...#
    #..m..#
    #.W.w.#
    #...A.#
    #######
    """
    env = make(gridtasks.FactoryEnv, 7)
    world_from_map(env, text, agent=(3, 3), inventory=Code.WOOD)
    obs = observe(env)
    assert obs.shape == (208,)
    np.testing.assert_array_equal(obs[:200].reshape(8, 5, 5), reference_view(text, (3, 3), env.channels))
    assert obs[200:].tolist() == [0, 0, 0, 1, 0, 0, 0, 0]


def test_predators_are_overlaid_on_their_cells():
    text = """
    #######
    #.....#
    #..F..#
    #.....#
    #.....#
    #.....#
    #######
    """
    env = make(gridtasks.ScavengingEnv, 7, predator_count=3, food_count=1)
    # one on the food (3, 2), one on an empty cell (1, 4), one outside the 5×5 view of (2, 3)
    preds = [(3, 2), (1, 4), (5, 5)]
    world_from_map(env, text, agent=(2, 3), predators=preds)
    obs = observe(env)
    assert obs.shape == (104,)
    view = obs[:100].reshape(4, 5, 5)
    np.testing.assert_array_equal(view, reference_view(text, (2, 3), env.channels, preds))
    food, predator = 2, 3
    assert view[food, 1, 3] == 1 and view[predator, 1, 3] == 1  # two ones on the food cell
    assert view[0, 3, 1] == 1 and view[predator, 3, 1] == 1  # empty + predator
    assert view[predator].sum() == 2


def test_a_predator_on_the_agent_shows_in_the_centre():
    env = make(gridtasks.ScavengingEnv, 7, predator_count=1, food_count=0)
    world_from_map(env, "\n".join(["#######"] + ["#.....#"] * 5 + ["#######"]), agent=(3, 3),
                   predators=[(3, 2)])
    obs, reward, *_ = env.step(INTERACT)
    assert reward == -100
    assert obs[3 * 25 + 12] == 1 and obs[0 * 25 + 12] == 1
