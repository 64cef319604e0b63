"""Reward modes on scripted hand-drawn episodes: sparse, subgoal, one_time, distance."""

from __future__ import annotations

import pytest
from fixtures import make, world_from_map

import gridtasks
from gridtasks.codes import Code
from gridtasks.engine import EAST, INTERACT, NORTH, PICK_UP, PLACE, SOUTH, WEST

MODES = ["sparse", "subgoal", "one_time", "distance"]


def run(env, actions):
    """Step through ``actions``; return the rewards, terminated flags and the last info."""
    rewards, ends, info = [], [], {}
    for a in actions:
        _, reward, terminated, truncated, info = env.step(a)
        rewards.append(reward)
        ends.append((terminated, truncated))
    return rewards, ends, info


# ---------------------------------------------------------------------------------------------- salad

SALAD_ROW = """
#######
#.....#
#@.L.C#
#.....#
#.....#
#.....#
#######
"""
SALAD_SCRIPT = [EAST, EAST, PICK_UP, EAST, EAST, PLACE, PICK_UP]


@pytest.mark.parametrize(
    "mode, expected",
    [
        ("sparse", [0, 0, 0, 0, 0, 0, 100]),
        ("subgoal", [0, 0, 1, 0, 0, 1, 100]),
        ("one_time", [0, 0, 1, 0, 0, 1, 100]),
        # -0.01 × L1 to the nearest ingredient (empty hands), then to the carrot (holding the lettuce)
        ("distance", [-0.01, 0, 1, -0.01, 0, 1, 100]),
    ],
)
def test_salad_rewards_along_a_solution(mode, expected):
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward=mode)
    world_from_map(env, SALAD_ROW)
    rewards, ends, info = run(env, SALAD_SCRIPT)
    assert rewards == pytest.approx(expected, abs=1e-12)
    assert ends == [(False, False)] * 6 + [(True, False)]
    assert info["solved"] and info["completions"] == 1
    assert (info["pickup_lettuce"], info["pickup_carrot"], info["pickup_salad"], info["made_salad"]) == (1, 0, 1, 1)


@pytest.mark.parametrize("mode, drop", [("sparse", 0), ("subgoal", 0), ("one_time", -100), ("distance", -100)])
def test_pick_drop_loops_earn_nothing(mode, drop):
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward=mode)
    world_from_map(env, SALAD_ROW.replace("@", "."), agent=(3, 2))
    rewards, _, _ = run(env, [PICK_UP] + [PLACE, PICK_UP] * 5)
    first = 0 if mode == "sparse" else 1
    # distance: a re-pick earns no stage, so it gets the distance term (the carrot is 2 cells away)
    repick = -0.02 if mode == "distance" else 0
    assert rewards == pytest.approx([first] + [drop, repick] * 5, abs=1e-12)


def test_the_other_ingredient_is_the_same_subgoal():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward="subgoal")
    world_from_map(env, SALAD_ROW.replace("@", "."), agent=(3, 2))
    rewards, _, _ = run(env, [PICK_UP, NORTH, PLACE, SOUTH, EAST, EAST, PICK_UP])
    assert rewards == [1, 0, 0, 0, 0, 0, 0]


def test_a_second_salad_in_the_same_cycle_earns_nothing():
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward="subgoal")
    world = world_from_map(env, """
    #######
    #.....#
    #.L.C.#
    #.....#
    #.L.C.#
    #.....#
    #######
    """, agent=(2, 2))
    script = [PICK_UP, EAST, EAST, PLACE, SOUTH, SOUTH, WEST, WEST, PICK_UP, EAST, EAST, PLACE]
    rewards, _, info = run(env, script)
    assert rewards == [1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0]
    assert info["made_salad"] == 2
    assert world["grid"][2, 4] == world["grid"][4, 4] == Code.SALAD


@pytest.mark.parametrize("mode", ["subgoal", "one_time", "distance"])
def test_stage_flags_reset_on_completion(mode):
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward=mode, reset_free=True)
    world = world_from_map(env, """
    #######
    #.....#
    #.L.C.#
    #.....#
    #.L.C.#
    #.....#
    #######
    """, agent=(2, 2))
    cycle1 = [PICK_UP, EAST, EAST, PLACE, PICK_UP]
    cycle2 = [SOUTH, SOUTH, PICK_UP, WEST, WEST, PLACE, PICK_UP]
    rewards, ends, info = run(env, cycle1 + cycle2)
    big = [r for r in rewards if abs(r) >= 1]
    assert big == [1, 1, 100, 1, 1, 100]
    assert all(end == (False, False) for end in ends)
    assert info["completions"] == 2 and world["inventory"] == 0


@pytest.mark.parametrize("mode", ["subgoal", "one_time", "distance"])
def test_stage_flags_reset_on_episode_reset(mode):
    env = make(gridtasks.SaladEnv, 7, regrow_when_empty=False, reward=mode)
    text = SALAD_ROW.replace("@", ".")
    world_from_map(env, text, agent=(3, 2))
    assert env.step(PICK_UP)[1] == 1
    world_from_map(env, text, agent=(3, 2))  # same episode: the stage is already rewarded
    assert env.step(PICK_UP)[1] == pytest.approx(-0.02 if mode == "distance" else 0.0)
    env.reset()
    world_from_map(env, text, agent=(3, 2))
    assert env.step(PICK_UP)[1] == 1


@pytest.mark.parametrize("mode", MODES)
def test_salad_on_the_horizon_step_terminates(mode):
    env = make(gridtasks.SaladEnv, 7, horizon=1, reward=mode)
    world_from_map(env, SALAD_ROW.replace("L", "S").replace("@", "."), agent=(3, 2))
    _, reward, terminated, truncated, info = env.step(PICK_UP)
    assert (reward, terminated, truncated, info["solved"]) == (100, True, False, True)


# ---------------------------------------------------------------------------------------------- hunting

HUNT = """
#######
#.....#
#.A.D.#
#.....#
#.....#
#.....#
#######
"""


@pytest.mark.parametrize(
    "mode, expected",
    [
        ("sparse", [0, 0, 0, 0, 0, 0, 0, 100]),
        ("subgoal", [1, 0, 0, 0, 0, 0, 1, 100]),
        ("one_time", [1, -100, 0, 0, 0, 0, 1, 100]),
        # the axe is carried toward the deer (2, then 1, then 0 cells); dropping costs -100
        ("distance", [1, -100, -0.02, -0.01, -0.0, -0.0, 1, 100]),
    ],
)
def test_hunting_rewards_along_a_solution(mode, expected):
    env = make(gridtasks.HuntingEnv, 7, replenish=False, reward=mode)
    world_from_map(env, HUNT, agent=(2, 2))
    script = [PICK_UP, PLACE, PICK_UP, EAST, EAST, INTERACT, PLACE, PICK_UP]
    rewards, ends, info = run(env, script)
    assert rewards == pytest.approx(expected, abs=1e-12)
    assert ends[-1] == (True, False) and all(e == (False, False) for e in ends[:-1])
    assert info["made_food"] == 1 and info["pickup_food"] == 1 and info["pickup_axe"] == 2


# ---------------------------------------------------------------------------------------------- factory

FACTORY = """
#######
#X....#
#.....#
#.m.w.#
#.....#
#.....#
#######
"""
FACTORY_SCRIPT = [INTERACT, SOUTH, PLACE, NORTH, EAST, EAST, INTERACT, SOUTH, WEST, WEST, PLACE, PICK_UP,
                  NORTH, NORTH, NORTH, WEST, PLACE]


@pytest.mark.parametrize(
    "mode, expected",
    [
        ("sparse", [0] * 16 + [100]),
        # +1 receive a material (once), +1 make the axe, +1 hold the axe; dropping costs nothing here
        ("subgoal", [1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 100]),
        # the released ladder (the default): metal 1 and wood 1 once a cycle, the wood-onto-metal axe reaches the
        # metal stage again (nothing), holding the axe 100, the delivery 10 000
        ("one_time", [1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 100, 0, 0, 0, 0, 10_000]),
        # every event pays: each material 1, the axe made 100, picked up 100, delivered 10 000
        ("waypoint", [1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 100, 100, 0, 0, 0, 0, 10_000]),
        ("flat one_time", [1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 100]),
        ("flat waypoint", [1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0, 0, 0, 100]),
    ],
)
def test_factory_rewards_along_a_solution(mode, expected):
    ladder = {"reward_ladder": "flat"} if mode.startswith("flat ") else {}
    env = make(gridtasks.FactoryEnv, 7, reward=mode.removeprefix("flat "), **ladder)
    world = world_from_map(env, FACTORY, agent=(2, 3))
    rewards, ends, info = run(env, FACTORY_SCRIPT)
    assert rewards == expected
    assert ends[-1] == (True, False) and all(e == (False, False) for e in ends[:-1])
    assert (info["pickup_metal"], info["pickup_wood"], info["pickup_axe"], info["made_axe"]) == (1, 1, 1, 1)
    assert world["grid"][1, 1] == Code.DEPOT and world["inventory"] == 0


def test_factory_released_distance_adds_the_distance_only_where_no_stage_pays():
    env = make(gridtasks.FactoryEnv, 7, reward="distance")
    world_from_map(env, FACTORY, agent=(2, 3))
    rewards, _, _ = run(env, FACTORY_SCRIPT)
    stages = [r for r in rewards if r >= 1]
    assert stages == [1, 1, 100, 10_000] and all(-0.1 < r <= 0 for r in rewards if r < 1)


def test_factory_goal_make_axe_ends_when_the_axe_is_made():
    env = make(gridtasks.FactoryEnv, 7, reward="waypoint", goal="make_axe")
    world_from_map(env, FACTORY, agent=(2, 3))
    rewards, ends, info = run(env, FACTORY_SCRIPT[:11])  # up to the place that makes the axe
    assert rewards == [1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 100]  # materials 1 each, farmable; making the axe 100
    assert ends[-1] == (True, False) and info["solved"] and info["made_axe"] == 1
    assert env.test_mdp_kwargs()["goal"] == "make_axe"


@pytest.mark.parametrize("mode", ["subgoal", "one_time", "distance"])
def test_factory_goal_make_axe_pays_each_material_once_a_cycle(mode):
    env = make(gridtasks.FactoryEnv, 7, reward=mode, goal="make_axe", reset_free=True)
    world_from_map(env, FACTORY, agent=(2, 3))
    # metal received, dropped, picked up again (no second +1), dropped; wood received; wood onto metal: the axe
    script = [INTERACT, SOUTH, PLACE, PICK_UP, PLACE, NORTH, EAST, EAST, INTERACT, SOUTH, WEST, WEST, PLACE]
    rewards, _, info = run(env, script)
    assert [r for r in rewards if r >= 1] == [1, 1, 100] and info["completions"] == 1
    assert rewards[0] == 1 and rewards[3] <= 0 and rewards[8] == 1 and rewards[-1] == 100


def test_factory_goal_make_axe_uses_the_axe_up_when_reset_free():
    env = make(gridtasks.FactoryEnv, 7, reward="sparse", goal="make_axe", reset_free=True)
    world = world_from_map(env, FACTORY, agent=(2, 3))
    rewards, ends, info = run(env, FACTORY_SCRIPT[:11])
    assert rewards[-1] == 100 and not any(t or u for t, u in ends) and info["completions"] == 1
    assert world["grid"][4, 2] == Code.EMPTY and world["inventory"] == 0  # no axe left to deliver or farm


def test_factory_delivery_is_repeatable_when_reset_free():
    env = make(gridtasks.FactoryEnv, 7, reward="subgoal", reset_free=True)
    world_from_map(env, FACTORY, agent=(2, 3))
    rewards, ends, info = run(env, FACTORY_SCRIPT)
    world_from_map(env, FACTORY, agent=(2, 3))
    rewards2, ends2, info2 = run(env, FACTORY_SCRIPT)
    assert rewards == rewards2 and sum(rewards) == 103
    assert not any(t or u for t, u in ends + ends2)
    assert info2["completions"] == 2


# ---------------------------------------------------------------------------------------------- scavenging


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("reset_free", [False, True])
def test_scavenging_food_is_worth_100_in_every_mode(mode, reset_free):
    env = make(gridtasks.ScavengingEnv, 7, predator_count=0, food_count=1, reward=mode, reset_free=reset_free)
    world = world_from_map(env, """
    #######
    #.....#
    #.F...#
    #.....#
    #.....#
    #.....#
    #######
    """, agent=(2, 2))
    _, reward, terminated, truncated, info = env.step(PICK_UP)
    assert reward == 100 and info["solved"] and info["pickup_food"] == 1
    assert (terminated, truncated) == (not reset_free, False)
    assert world["inventory"] == (0 if reset_free else Code.FOOD)


# ---------------------------------------------------------------------------------------------- distance targets


def one_step_distance(cls, text, agent, inventory=0, **kwargs):
    env = make(cls, 7, reward="distance", **kwargs)
    world_from_map(env, text, agent=agent, inventory=inventory)
    return env.step(INTERACT)[1]


@pytest.mark.parametrize(
    "row2, row4, inventory, expected",
    [
        ("#.L...#", "#...C.#", 0, -0.02),  # nearest ingredient: the carrot at (4, 4)
        ("#S....#", "#...C.#", 0, -0.07),  # a salad comes first, even when farther: (1, 2)
        ("#.L...#", "#...CL#", Code.LETTUCE, -0.02),  # holding a lettuce: the carrot, not the lettuce
        ("#.L...#", "#...C.#", Code.CARROT, -0.06),  # holding a carrot: the lettuce at (2, 2)
        ("#.L...#", "#.....#", Code.LETTUCE, 0.0),  # no carrot anywhere: nothing
    ],
)
def test_salad_distance_targets(row2, row4, inventory, expected):
    text = f"#######\n#.....#\n{row2}\n#.....#\n{row4}\n#.....#\n#######"
    kw = {"regrow_when_empty": False}
    assert one_step_distance(gridtasks.SaladEnv, text, (5, 5), inventory, **kw) == pytest.approx(expected)


@pytest.mark.parametrize(
    "row2, row4, inventory, expected",
    [
        ("#.A...#", "#...D.#", 0, -0.06),  # no food: the axe at (2, 2)
        ("#F....#", "#..A..#", 0, -0.07),  # food first: (1, 2)
        ("#.A...#", "#...E.#", Code.AXE, -0.02),  # holding the axe: the nearest deer of any kind
        ("#.H...#", "#.....#", Code.AXE, -0.06),
    ],
)
def test_hunting_distance_targets(row2, row4, inventory, expected):
    text = f"#######\n#.....#\n{row2}\n#.....#\n{row4}\n#.....#\n#######"
    assert one_step_distance(gridtasks.HuntingEnv, text, (5, 5), inventory, replenish=False) == pytest.approx(
        expected)


@pytest.mark.parametrize(
    "row3, row4, inventory, expected",
    [
        ("#.m.w.#", "#.A...#", 0, -0.04),  # an axe on the grid first (2, 4), though a worker is nearer
        ("#.m.w.#", "#.....#", 0, -0.03),  # else the nearest worker: the wood worker (4, 3)
        ("#.m.w.#", "#.W...#", Code.METAL, -0.04),  # holding metal: wood on the grid (2, 4) first
        ("#.m.w.#", "#.....#", Code.METAL, -0.03),  # else the wood worker
        ("#.m.w.#", "#...M.#", Code.WOOD, -0.02),  # holding wood: metal (4, 4)
        ("#.m.w.#", "#.....#", Code.WOOD, -0.05),  # else the metal worker (2, 3)
        ("#.m.w.#", "#.....#", Code.AXE, -0.08),  # holding the axe: the depot (1, 1)
    ],
)
def test_factory_distance_targets(row3, row4, inventory, expected):
    text = f"#######\n#X....#\n#.....#\n{row3}\n{row4}\n#.....#\n#######"
    assert one_step_distance(gridtasks.FactoryEnv, text, (5, 5), inventory) == pytest.approx(expected)


def test_scavenging_distance_to_the_nearest_food():
    text = "#######\n#F....#\n#.....#\n#.....#\n#..F..#\n#.....#\n#######"
    assert one_step_distance(gridtasks.ScavengingEnv, text, (5, 5), predator_count=0,
                             food_count=2) == pytest.approx(-0.03)
