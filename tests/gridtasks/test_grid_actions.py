"""The agent's actions on hand-drawn worlds: movement, pick-up, crafting, dispensing, delivering."""

from __future__ import annotations

import pytest
from fixtures import assert_map, make, world_from_map

import gridtasks
from gridtasks.codes import Code
from gridtasks.engine import EAST, INTERACT, NORTH, PICK_UP, PLACE, SOUTH, WEST


def salad(**kwargs):
    """A static 7×7 salad env where nothing grows (so only the action changes the grid)."""
    return make(gridtasks.SaladEnv, 7, regrow_when_empty=False, **kwargs)


def hunting(**kwargs):
    """A static 7×7 hunting env without replenishment."""
    return make(gridtasks.HuntingEnv, 7, replenish=False, **kwargs)


def factory(**kwargs):
    """A static 7×7 factory env (workers never move)."""
    return make(gridtasks.FactoryEnv, 7, **kwargs)


# ---------------------------------------------------------------------------------------------- movement

MOVE_MAP = """
#######
#.....#
#.L#..#
#.@C..#
#.....#
#.....#
#######
"""


@pytest.mark.parametrize(
    "action, expected",
    [(WEST, (1, 3)), (EAST, (3, 3)), (NORTH, (2, 2)), (SOUTH, (2, 4))],
    ids=["west", "east", "north", "south"],
)
def test_moves_one_cell_and_walks_over_objects(action, expected):
    env = salad()
    world = world_from_map(env, MOVE_MAP)
    _, reward, terminated, truncated, info = env.step(action)
    # objects stay where they are: the agent stands on top of them
    assert_map(world, MOVE_MAP.replace("@", "."), agent=expected)
    assert tuple(info["agent_pos"]) == expected
    assert (reward, terminated, truncated) == (0.0, False, False)


@pytest.mark.parametrize(
    "agent, action",
    [((1, 1), WEST), ((1, 1), NORTH), ((5, 5), EAST), ((5, 5), SOUTH), ((3, 3), NORTH), ((4, 2), WEST), ((2, 2), EAST)],
)
def test_walls_block_moves(agent, action):
    text = """
    #######
    #.....#
    #..#..#
    #.....#
    #.....#
    #.....#
    #######
    """
    env = salad()
    world = world_from_map(env, text, agent=agent)
    env.step(action)
    assert tuple(world["agent"]) == agent
    assert_map(world, text, agent=agent)


# ---------------------------------------------------------------------------------------------- pick up


def test_pick_up_takes_the_object_under_the_agent():
    env = salad()
    world = world_from_map(env, """
    #######
    #.....#
    #.L.C.#
    #.....#
    #.....#
    #.....#
    #######
    """, agent=(2, 2))
    obs, reward, terminated, truncated, info = env.step(PICK_UP)
    assert world["inventory"] == Code.LETTUCE
    assert_map(world, """
    #######
    #.....#
    #.@.C.#
    #.....#
    #.....#
    #.....#
    #######
    """)
    assert info["pickup_lettuce"] == 1 and info["pickup_carrot"] == 0
    assert (reward, terminated, truncated) == (0.0, False, False)


def test_pick_up_with_full_hands_does_nothing():
    env = salad()
    text = """
    #######
    #.....#
    #.L.C.#
    #.....#
    #.....#
    #.....#
    #######
    """
    world = world_from_map(env, text, agent=(2, 2), inventory=Code.CARROT)
    _, _, _, _, info = env.step(PICK_UP)
    assert world["inventory"] == Code.CARROT
    assert_map(world, text, agent=(2, 2))
    assert info["pickup_lettuce"] == 0


def test_pick_up_on_an_empty_cell_does_nothing():
    env = salad()
    text = """
    #######
    #.....#
    #.L.C.#
    #..@..#
    #.....#
    #.....#
    #######
    """
    world = world_from_map(env, text)
    env.step(PICK_UP)
    assert world["inventory"] == 0
    assert_map(world, text)


@pytest.mark.parametrize("symbol", ["D", "E", "H"])
def test_deer_cannot_be_picked_up(symbol):
    env = hunting()
    text = f"""
    #######
    #.....#
    #.{symbol}.A.#
    #.....#
    #.....#
    #.....#
    #######
    """
    world = world_from_map(env, text, agent=(2, 2))
    env.step(PICK_UP)
    assert world["inventory"] == 0
    assert_map(world, text, agent=(2, 2))


@pytest.mark.parametrize("agent", [(1, 1), (3, 3), (4, 4)], ids=["depot", "metal worker", "wood worker"])
def test_workers_and_depot_cannot_be_picked_up(agent):
    env = factory()
    text = """
    #######
    #X....#
    #.....#
    #..m..#
    #...w.#
    #.....#
    #######
    """
    world = world_from_map(env, text, agent=agent)
    _, _, _, _, info = env.step(PICK_UP)
    assert world["inventory"] == 0
    assert_map(world, text, agent=agent)
    assert info["pickup_metal"] == info["pickup_wood"] == 0


# ---------------------------------------------------------------------------------------------- crafting


@pytest.mark.parametrize("carried, under", [(Code.LETTUCE, "C"), (Code.CARROT, "L")], ids=["L on C", "C on L"])
def test_lettuce_and_carrot_make_a_salad_either_way_round(carried, under):
    env = salad()
    world = world_from_map(env, f"""
    #######
    #.....#
    #..{under}..#
    #.....#
    #L...C#
    #.....#
    #######
    """, agent=(3, 2), inventory=carried)
    _, reward, terminated, truncated, info = env.step(PLACE)
    assert world["inventory"] == 0
    assert_map(world, """
    #######
    #.....#
    #..S..#
    #.....#
    #L...C#
    #.....#
    #######
    """, agent=(3, 2))
    assert world["age"][2, 3] == 0
    assert info["made_salad"] == 1
    assert (reward, terminated, truncated, info["solved"]) == (0.0, False, False, False)


@pytest.mark.parametrize("carried, under", [(Code.LETTUCE, "L"), (Code.CARROT, "C"), (Code.LETTUCE, "S"),
                                            (Code.CARROT, "S")])
def test_placing_on_a_non_recipe_object_does_nothing(carried, under):
    env = salad()
    text = f"""
    #######
    #.....#
    #..{under}..#
    #.....#
    #L...C#
    #.....#
    #######
    """
    world = world_from_map(env, text, agent=(3, 2), inventory=carried)
    _, reward, _, _, info = env.step(PLACE)
    assert world["inventory"] == carried
    assert_map(world, text, agent=(3, 2))
    assert info["made_salad"] == 0 and reward == 0.0


def test_place_drops_on_an_empty_cell_keeping_the_carried_age():
    env = salad()
    world = world_from_map(env, """
    #######
    #.....#
    #..@..#
    #.....#
    #L...C#
    #.....#
    #######
    """, inventory=Code.LETTUCE)
    world["carried_age"] = 7
    env.step(PLACE)
    assert world["inventory"] == 0
    assert_map(world, """
    #######
    #.....#
    #..L..#
    #.....#
    #L...C#
    #.....#
    #######
    """, agent=(3, 2))
    assert world["age"][2, 3] == 7  # static salad: ingredients do not age on the grid


def test_place_with_empty_hands_does_nothing():
    env = salad()
    text = """
    #######
    #.....#
    #..C..#
    #.....#
    #L....#
    #.....#
    #######
    """
    world = world_from_map(env, text, agent=(3, 2))
    env.step(PLACE)
    assert world["inventory"] == 0
    assert_map(world, text, agent=(3, 2))


def test_interact_is_a_no_op_outside_the_factory():
    env = salad()
    text = """
    #######
    #.....#
    #..C..#
    #.....#
    #L....#
    #.....#
    #######
    """
    world = world_from_map(env, text, agent=(3, 2))
    _, reward, _, _, _ = env.step(INTERACT)
    assert world["inventory"] == 0 and reward == 0.0
    assert_map(world, text, agent=(3, 2))


@pytest.mark.parametrize("deer", ["D", "E", "H"], ids=["wander", "easy", "hard"])
def test_axe_on_deer_makes_food_and_uses_the_axe(deer):
    env = hunting()
    world = world_from_map(env, f"""
    #######
    #A....#
    #.....#
    #..{deer}..#
    #.....#
    #....D#
    #######
    """, agent=(3, 3), inventory=Code.AXE)
    _, reward, terminated, _, info = env.step(PLACE)
    assert world["inventory"] == 0
    assert_map(world, """
    #######
    #A....#
    #.....#
    #..F..#
    #.....#
    #....D#
    #######
    """, agent=(3, 3))
    assert info["made_food"] == 1
    assert (reward, terminated, info["solved"]) == (0.0, False, False)


@pytest.mark.parametrize("under", ["A", "F"])
def test_axe_on_non_deer_does_nothing(under):
    env = hunting()
    text = f"""
    #######
    #.....#
    #.....#
    #..{under}..#
    #.....#
    #....D#
    #######
    """
    world = world_from_map(env, text, agent=(3, 3), inventory=Code.AXE)
    env.step(PLACE)
    assert world["inventory"] == Code.AXE
    assert_map(world, text, agent=(3, 3))


def test_pick_up_food_solves_hunting():
    env = hunting()
    world = world_from_map(env, """
    #######
    #.....#
    #.....#
    #..F..#
    #.....#
    #....D#
    #######
    """, agent=(3, 3))
    _, reward, terminated, truncated, info = env.step(PICK_UP)
    assert (reward, terminated, truncated, info["solved"]) == (100.0, True, False, True)
    assert world["inventory"] == Code.FOOD and info["pickup_food"] == 1


@pytest.mark.parametrize("carried, under", [(Code.METAL, "W"), (Code.WOOD, "M")], ids=["M on W", "W on M"])
def test_metal_and_wood_make_an_axe(carried, under):
    env = factory()
    world = world_from_map(env, f"""
    #######
    #X....#
    #.....#
    #..{under}..#
    #m....#
    #....w#
    #######
    """, agent=(3, 3), inventory=carried)
    _, reward, _, _, info = env.step(PLACE)
    assert world["inventory"] == 0
    assert_map(world, """
    #######
    #X....#
    #.....#
    #..A..#
    #m....#
    #....w#
    #######
    """, agent=(3, 3))
    assert info["made_axe"] == 1 and reward == 0.0


@pytest.mark.parametrize("reset_free", [False, True])
def test_axe_on_the_depot_solves_and_the_depot_stays(reset_free):
    env = factory(reset_free=reset_free)
    text = """
    #######
    #X....#
    #.....#
    #.....#
    #m....#
    #....w#
    #######
    """
    world = world_from_map(env, text, agent=(1, 1), inventory=Code.AXE)
    _, reward, terminated, truncated, info = env.step(PLACE)
    assert world["inventory"] == 0
    assert_map(world, text, agent=(1, 1))
    assert reward == 100.0 and info["solved"] and info["completions"] == 1
    assert (terminated, truncated) == (not reset_free, False)


@pytest.mark.parametrize("carried", [Code.METAL, Code.WOOD])
def test_materials_on_the_depot_do_nothing(carried):
    env = factory()
    text = """
    #######
    #X....#
    #.....#
    #.....#
    #m....#
    #....w#
    #######
    """
    world = world_from_map(env, text, agent=(1, 1), inventory=carried)
    _, reward, terminated, _, info = env.step(PLACE)
    assert world["inventory"] == carried
    assert_map(world, text, agent=(1, 1))
    assert (reward, terminated, info["solved"]) == (0.0, False, False)


@pytest.mark.parametrize("carried", [Code.AXE, Code.METAL])
def test_nothing_is_placed_on_a_worker(carried):
    env = factory()
    text = """
    #######
    #X....#
    #.....#
    #.....#
    #m....#
    #....w#
    #######
    """
    world = world_from_map(env, text, agent=(1, 4), inventory=carried)
    env.step(PLACE)
    assert world["inventory"] == carried
    assert_map(world, text, agent=(1, 4))


# ---------------------------------------------------------------------------------------------- dispensing

WORKERS = """
#######
#X....#
#.....#
#..m..#
#...w.#
#.....#
#######
"""


@pytest.mark.parametrize("agent, material", [((3, 3), Code.METAL), ((4, 4), Code.WOOD)])
def test_interact_on_a_worker_with_empty_hands_dispenses_its_material(agent, material):
    env = factory()
    world = world_from_map(env, WORKERS, agent=agent)
    _, reward, _, _, info = env.step(INTERACT)
    assert world["inventory"] == material
    assert_map(world, WORKERS, agent=agent)  # the worker stays and nothing appears on the grid
    assert info[f"pickup_{material.name.lower()}"] == 1
    assert reward == 0.0


def test_interact_with_full_hands_does_nothing():
    env = factory()
    world = world_from_map(env, WORKERS, agent=(3, 3), inventory=Code.WOOD)
    _, _, _, _, info = env.step(INTERACT)
    assert world["inventory"] == Code.WOOD
    assert info["pickup_metal"] == 0
    assert_map(world, WORKERS, agent=(3, 3))


@pytest.mark.parametrize("agent", [(2, 2), (1, 1)], ids=["empty cell", "depot"])
def test_interact_off_a_worker_does_nothing(agent):
    env = factory()
    world = world_from_map(env, WORKERS, agent=agent)
    env.step(INTERACT)
    assert world["inventory"] == 0
    assert_map(world, WORKERS, agent=agent)


def test_interact_on_material_on_the_ground_does_not_pick_it_up():
    env = factory()
    text = WORKERS.replace("#.....#\n#######", "#.M...#\n#######")
    world = world_from_map(env, text, agent=(2, 5))
    env.step(INTERACT)
    assert world["inventory"] == 0


@pytest.mark.parametrize("on_grid, dispenses", [(0, True), (1, True), (2, True), (3, False)])
def test_workers_dispense_only_while_at_most_max_material_lie_on_the_grid(on_grid, dispenses):
    env = factory(max_material=2)
    metals = "M" * on_grid + "." * (5 - on_grid)
    text = f"""
    #######
    #X....#
    #{metals}#
    #..m..#
    #WWW..#
    #...w.#
    #######
    """
    world = world_from_map(env, text, agent=(3, 3))
    env.step(INTERACT)
    assert world["inventory"] == (Code.METAL if dispenses else 0)
    # wood on the grid does not count toward metal, and 3 woods > 2 stop the wood worker
    world_from_map(env, text, agent=(4, 5))
    env.step(INTERACT)
    assert world["inventory"] == 0


def test_max_material_counts_only_the_grid_not_the_hands():
    env = factory(max_material=0)
    world = world_from_map(env, WORKERS, agent=(3, 3))
    env.step(INTERACT)  # hands: metal, grid: 0 metal
    env.step(EAST)
    env.step(PLACE)  # grid: 1 metal
    env.step(WEST)
    env.step(INTERACT)
    assert world["inventory"] == 0
    assert world["grid"][3, 4] == Code.METAL
