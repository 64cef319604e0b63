"""The map helper itself, and the order of the phases inside one step."""

from __future__ import annotations

import pytest
from fixtures import assert_map, cells, make, map_of, parse_map, world_from_map

import gridtasks
from gridtasks.codes import Code
from gridtasks.engine import INTERACT

MAP = """
#######
#.L.C.#
#..@..#
#SADEH#
#FMWmw#
#X....#
#######
"""


def test_map_round_trip():
    env = make(gridtasks.SaladEnv, 7)
    world = world_from_map(env, MAP)
    text = map_of(world)
    assert text.splitlines()[:7] == [line.strip() for line in MAP.strip().splitlines()]
    assert text.splitlines()[7] == "agent=(3, 2) on EMPTY, carrying nothing"
    assert_map(world, MAP)
    assert world["grid"][1, 2] == Code.LETTUCE and world["grid"][4, 4] == Code.METAL_WORKER
    assert cells(world, Code.CARROT) == [(4, 1)]
    assert tuple(world["agent"]) == (3, 2)


def test_world_from_map_overwrites_the_whole_world():
    env = make(gridtasks.SaladEnv, 7)
    world = env.unwrapped.world
    world["age"][:, :] = 9
    world_from_map(env, MAP, ages={(2, 1): 4}, inventory=Code.CARROT)
    assert world["age"][1, 2] == 4 and world["age"].sum() == 4
    assert world["inventory"] == Code.CARROT
    assert "carrying CARROT" in map_of(world)


def test_assert_map_reports_both_maps():
    env = make(gridtasks.SaladEnv, 7)
    world = world_from_map(env, MAP)
    with pytest.raises(AssertionError, match="expected:"):
        assert_map(world, MAP.replace("L", "C"))
    with pytest.raises(AssertionError):
        assert_map(world, MAP, agent=(1, 1))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"text": MAP.replace("@", ".")}, "exactly once"),
        ({"text": MAP, "agent": (1, 1)}, "exactly once"),
        ({"text": MAP.replace("#X....#", "#X...?#")}, "unknown map symbol"),
        ({"text": "#####\n#.@.#\n#...#\n#...#\n#####"}, "grid_size is 7"),
        ({"text": MAP.replace("#X....#", "#X...#")}, "square"),
    ],
)
def test_bad_maps_are_refused(kwargs, message):
    env = make(gridtasks.SaladEnv, 7)
    with pytest.raises(ValueError, match=message):
        world_from_map(env, **kwargs)


def test_predator_marks_and_counts():
    env = make(gridtasks.ScavengingEnv, 7, predator_count=2)
    text = MAP.replace("#.L.C.#", "#.P.P.#").replace("#SADEH#", "#.....#").replace("#FMWmw#", "#.....#")
    world = world_from_map(env, text.replace("X", "."))
    assert world["pred"][:2].tolist() == [[2, 1], [4, 1]]
    assert map_of(world, predators=2).splitlines()[1] == "#.P.P.#"
    with pytest.raises(ValueError, match="2 predators"):
        world_from_map(env, text.replace("X", ".").replace("P", "."))
    grid, agent, preds = parse_map(text)
    assert agent == (3, 2) and preds == [(2, 1), (4, 1)] and grid[5, 1] == Code.DEPOT


# ---------------------------------------------------------------------------------------------- phase order


def test_distance_reward_is_measured_after_the_creatures_moved():
    env = make(gridtasks.HuntingEnv, 7, replenish=False, deer_kind="easy", deer_speed=1.0, reward="distance")
    world = world_from_map(env, """
    #######
    #.....#
    #.....#
    #...E.#
    #.....#
    #.....#
    #######
    """, agent=(2, 5), inventory=Code.AXE)
    _, reward, *_ = env.step(INTERACT)
    assert cells(world, Code.DEER_EASY) == [(3, 3)]  # W and S approach: W first
    assert reward == pytest.approx(-0.03)  # 1 + 2 after the deer's step (it was 4 before)


def test_growth_comes_before_withering():
    # lifespan int(1 / 1.0) = 1: as in the original, each step's new ingredients age in the same step,
    # so an ingredient with lifespan 1 withers the step it grew and none is ever left on the grid
    env = make(gridtasks.SaladEnv, 7, dynamism=1.0, initial_count=1)
    world = env.unwrapped.world
    assert env.unwrapped.rules[0]["lifespan"][Code.LETTUCE] == 1
    for _ in range(20):
        obs, *_ = env.step(INTERACT)
        assert cells(world, Code.LETTUCE) == [] and cells(world, Code.CARROT) == []
        assert obs[2 * 25:4 * 25].sum() == 0
