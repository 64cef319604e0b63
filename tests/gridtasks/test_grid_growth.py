"""Growth, withering and the shaping window (salad), easy-deer shaping (hunting), replenishment."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fixtures import cells, make, world_from_map

import gridtasks
from gridtasks import engine
from gridtasks.codes import Code
from gridtasks.engine import INTERACT, PICK_UP, PLACE

BOTH = """
#######
#.....#
#.L...#
#.....#
#...C.#
#....@#
#######
"""
"""One lettuce at (2, 2), one carrot at (4, 4), the agent at (5, 5)."""
BARE = BOTH.replace("@", ".")
"""``BOTH`` without the agent (give it with ``agent=``)."""


def tolerance(n: int, p: float, sigmas: float = 4.0) -> float:
    return sigmas * math.sqrt(n * p * (1 - p))


def salad(**kwargs):
    return make(gridtasks.SaladEnv, 7, **kwargs)


def count(world, code) -> int:
    return int(np.count_nonzero(world["grid"] == code))


# ---------------------------------------------------------------------------------------------- growth


def test_each_ingredient_grows_with_probability_p_per_step():
    p, trials = 0.2, 2000
    env = salad(dynamism=p)
    rules = env.unwrapped.rules[0]
    grown = {Code.LETTUCE: 0, Code.CARROT: 0}
    for _ in range(trials):
        world = world_from_map(env, BOTH)
        engine.grow_resources(world, rules, 0.0)
        for code in grown:
            new = count(world, code) - 1
            assert new in (0, 1)  # at most one of a kind per step
            grown[code] += new
    for code, n in grown.items():
        assert abs(n - p * trials) < tolerance(trials, p), code.name


@pytest.mark.parametrize("spawn_on_agent", [True, False])
def test_grown_ingredients_land_on_empty_cells_under_the_agent_only_if_allowed(spawn_on_agent):
    env = salad(dynamism=1.0, spawn_on_agent=spawn_on_agent)
    rules = env.unwrapped.rules[0]
    seen = set()
    for _ in range(400):
        world = world_from_map(env, BOTH)
        engine.grow_resources(world, rules, 0.0)
        new = set(cells(world, Code.LETTUCE, Code.CARROT)) - {(2, 2), (4, 4)}
        assert len(new) == 2
        seen |= new
    interior = {(x, y) for x in range(1, 6) for y in range(1, 6)}
    under_agent = set() if spawn_on_agent else {(5, 5)}
    assert seen == interior - {(2, 2), (4, 4)} - under_agent


def test_growth_stops_while_more_than_the_cap_exist():
    env = salad(dynamism=1.0)
    rules = env.unwrapped.rules[0]
    cap = int(rules["growth_cap"])
    assert cap == (7 - 2) ** 2 // 8 == 3
    world = world_from_map(env, BOTH)
    counts = []
    for _ in range(6):
        engine.grow_resources(world, rules, 0.0)
        counts.append(count(world, Code.LETTUCE))
    # growth is allowed while count <= cap, so a kind reaches cap + 1 and no further
    assert counts == [2, 3, 4, 4, 4, 4]


def test_default_cap_is_4_on_8x8_and_8_on_10x10():
    assert gridtasks.SaladEnv().rules[0]["growth_cap"] == 4
    assert gridtasks.WalledSaladEnv().rules[0]["growth_cap"] == 8


# ---------------------------------------------------------------------------------------------- withering


@pytest.mark.parametrize("initial, p, lifespan", [(2, 0.1, 20), (1, 0.1, 10), (2, 0.05, 40), (2, 0.5, 4),
                                                  (3, 0.3, 10), (2, 0.01, 200)])
def test_lifespan_is_initial_count_over_p(initial, p, lifespan):
    rules = gridtasks.SaladEnv(dynamism=p, initial_count=initial).rules[0]
    assert rules["lifespan"][Code.LETTUCE] == rules["lifespan"][Code.CARROT] == lifespan
    assert rules["lifespan"][Code.SALAD] == 0


def test_an_ingredient_withers_exactly_at_its_lifespan():
    env = salad(dynamism=0.1, initial_count=2)  # lifespan 20
    rules = env.unwrapped.rules[0]
    world = world_from_map(env, BOTH, ages={(4, 4): 5})
    for step in range(1, 21):
        engine.wither(world, rules)
        assert (world["grid"][2, 2] == Code.LETTUCE) == (step < 20), step
        assert (world["grid"][4, 4] == Code.CARROT) == (step < 15), step
        if step < 20:
            assert world["age"][2, 2] == step


def test_a_full_step_removes_an_ingredient_reaching_its_lifespan():
    env = salad(dynamism=0.1, initial_count=2)  # lifespan 20
    world = world_from_map(env, BOTH, ages={(2, 2): 19, (4, 4): 18})
    env.step(INTERACT)
    assert world["grid"][2, 2] == Code.EMPTY
    assert world["grid"][4, 4] == Code.CARROT and world["age"][4, 4] == 19


def test_carried_ingredients_do_not_age():
    env = salad(dynamism=0.1, initial_count=2)  # lifespan 20
    world = world_from_map(env, BARE, agent=(2, 2), ages={(2, 2): 5})
    env.step(PICK_UP)
    for _ in range(30):
        env.step(INTERACT)
    assert world["inventory"] == Code.LETTUCE
    world["grid"][2, 1] = Code.EMPTY  # (1, 2) may have grown something meanwhile
    env.step(engine.WEST)
    env.step(PLACE)
    assert world["grid"][2, 1] == Code.LETTUCE
    assert world["age"][2, 1] == 6  # 5 when picked up, +1 by the drop step's withering


def test_products_never_wither():
    env = salad(dynamism=0.5, initial_count=1)  # ingredients live 2 steps
    world = world_from_map(env, BOTH.replace("C", "S"))
    for _ in range(50):
        engine.wither(world, env.unwrapped.rules[0])
    assert world["grid"][4, 4] == Code.SALAD


@pytest.mark.parametrize("cls", [gridtasks.SaladEnv, gridtasks.HuntingEnv, gridtasks.ScavengingEnv,
                                 gridtasks.FactoryEnv])
def test_without_dynamism_nothing_withers(cls):
    env = cls(dynamism=0.0)
    assert not env.rules[0]["lifespan"].any()


def test_static_salad_keeps_every_ingredient_forever():
    env = salad(dynamism=0.0, horizon=1000)  # one episode of 500 steps
    world = world_from_map(env, BOTH, ages={(2, 2): 10**6})
    before = world["grid"].copy()
    for _ in range(500):
        env.step(INTERACT)
    np.testing.assert_array_equal(world["grid"], before)
    assert world["age"][2, 2] == 10**6


# ---------------------------------------------------------------------------------------------- regrowth


def test_static_ingredients_regrow_only_when_none_is_left_on_the_grid():
    env = salad(dynamism=0.0, regrow_when_empty=True)
    world = world_from_map(env, BARE, agent=(2, 2))
    env.step(PICK_UP)
    # the original counts the grid only: the carried lettuce does not stop one regrowing at once
    (lettuce,) = cells(world, Code.LETTUCE)
    assert cells(world, Code.CARROT) == [(4, 4)]
    for action in (engine.EAST, engine.EAST, engine.SOUTH, engine.SOUTH):
        env.step(action)
    assert cells(world, Code.LETTUCE) == [lettuce]
    env.step(PLACE)  # lettuce + carrot -> salad: no carrot is left, one regrows at once
    assert world["grid"][4, 4] == Code.SALAD
    assert cells(world, Code.LETTUCE) == [lettuce]
    (carrot,) = cells(world, Code.CARROT)
    for _ in range(50):
        env.step(INTERACT)
    assert cells(world, Code.LETTUCE) == [lettuce] and cells(world, Code.CARROT) == [carrot]


def test_with_count_carried_the_carried_lettuce_holds_back_regrowth():
    env = salad(dynamism=0.0, regrow_when_empty=True, count_carried=True)
    world = world_from_map(env, BARE, agent=(2, 2))
    env.step(PICK_UP)
    for _ in range(20):
        env.step(INTERACT)
    assert cells(world, Code.LETTUCE) == [] and world["inventory"] == Code.LETTUCE


def test_dropping_the_carried_last_ingredient_after_it_regrew_leaves_two():
    env = salad(dynamism=0.0, regrow_when_empty=True)
    world = world_from_map(env, BARE, agent=(2, 2))
    env.step(PICK_UP)
    (regrown,) = cells(world, Code.LETTUCE)
    step = engine.NORTH if regrown != (2, 1) else engine.SOUTH
    env.step(step)
    env.step(PLACE)
    dropped = (2, 1) if step == engine.NORTH else (2, 3)
    assert sorted(cells(world, Code.LETTUCE)) == sorted([regrown, dropped])


def test_no_regrowth_while_one_of_the_kind_is_left():
    env = salad(dynamism=0.0, regrow_when_empty=True)
    world = world_from_map(env, BARE.replace("#.....#\n#.L", "#L....#\n#.L"), agent=(2, 2))
    assert count(world, Code.LETTUCE) == 2
    env.step(PICK_UP)
    assert cells(world, Code.LETTUCE) == [(1, 1)]


def test_without_regrowth_an_eaten_kind_stays_gone():
    env = salad(dynamism=0.0, regrow_when_empty=False, horizon=200)
    world = world_from_map(env, BARE, agent=(2, 2))
    env.step(PICK_UP)
    for _ in range(100):
        env.step(INTERACT)
    assert count(world, Code.LETTUCE) == 0


def test_hunting_replenishes_one_deer_and_one_axe_per_step():
    env = make(gridtasks.HuntingEnv, 7, deer_count=2, axe_count=2)
    world = world_from_map(env, """
    #######
    #.....#
    #.....#
    #.....#
    #.....#
    #....@#
    #######
    """)
    env.step(INTERACT)
    assert count(world, Code.DEER) == 1 and count(world, Code.AXE) == 1
    env.step(INTERACT)
    assert count(world, Code.DEER) == 2 and count(world, Code.AXE) == 2
    for _ in range(20):
        env.step(INTERACT)
    assert count(world, Code.DEER) == 2 and count(world, Code.AXE) == 2


def test_a_carried_axe_counts_toward_the_hunting_population_only_with_count_carried():
    env = make(gridtasks.HuntingEnv, 7, deer_count=1, axe_count=2, count_carried=True)
    world = world_from_map(env, """
    #######
    #.....#
    #.A...#
    #.....#
    #...D.#
    #....@#
    #######
    """, inventory=Code.AXE)
    for _ in range(10):
        env.step(INTERACT)
    assert cells(world, Code.AXE) == [(2, 2)]


def test_scavenging_replenishes_food():
    env = make(gridtasks.ScavengingEnv, 7, food_count=2, predator_count=0, reset_free=True)
    world = world_from_map(env, """
    #######
    #.....#
    #.F...#
    #.....#
    #.....#
    #.....#
    #######
    """, agent=(2, 2))
    env.step(PICK_UP)
    assert count(world, Code.FOOD) == 1  # one added per step: from 0 to 1
    env.step(INTERACT)
    assert count(world, Code.FOOD) == 2


TWO_FOOD = """
#######
#.....#
#.F...#
#.....#
#...F.#
#....@#
#######
"""
"""Two food, the agent at (5, 5): replenishment has nothing to add."""


def test_scavenging_food_grows_with_probability_food_growth_beyond_the_replenished_two():
    p, trials = 0.2, 2000
    env = make(gridtasks.ScavengingEnv, 7, food_count=2, predator_count=0, food_growth=p, reset_free=True)
    rules, grown = env.unwrapped.rules[0], 0
    for _ in range(trials):
        world = world_from_map(env, TWO_FOOD)
        engine.grow_resources(world, rules, 0.0)
        new = count(world, Code.FOOD) - 2
        assert new in (0, 1)
        grown += new
    assert abs(grown - p * trials) < tolerance(trials, p)


def test_scavenging_food_grows_only_while_replenishment_adds_none():
    env = make(gridtasks.ScavengingEnv, 7, food_count=2, predator_count=0, food_growth=1.0, reset_free=True)
    world = world_from_map(env, TWO_FOOD.replace("F", ".", 1))
    engine.grow_resources(world, env.unwrapped.rules[0], 0.0)
    assert count(world, Code.FOOD) == 2  # the replenished one, no growth in the same step
    engine.grow_resources(world, env.unwrapped.rules[0], 0.0)
    assert count(world, Code.FOOD) == 3


@pytest.mark.parametrize(("food_growth", "lifespan"), [(0.0, 0), (0.2, 10), (0.3, 6)])
def test_growing_food_withers_after_food_count_over_p(food_growth, lifespan):
    env = make(gridtasks.ScavengingEnv, 7, food_count=2, food_growth=food_growth)
    assert env.unwrapped.rules[0]["lifespan"][Code.FOOD] == lifespan


def test_the_scavenging_test_mdp_grows_no_food():
    env = make(gridtasks.ScavengingEnv, 7, food_growth=0.2)
    assert env.unwrapped.test_mdp_kwargs()["food_growth"] == 0.0


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan"), True, "0.2"])
def test_food_growth_must_be_a_probability(bad):
    with pytest.raises(ValueError, match="food_growth must be a probability"):
        gridtasks.ScavengingEnv(food_growth=bad)


# ---------------------------------------------------------------------------------------------- shaping window


def test_window_side_endpoints():
    for n in (5, 7, 8, 10, 16):
        assert engine.window_side(n, 1.0) == 2
        assert engine.window_side(n, 0.0) == 2 * n


@pytest.mark.parametrize("schedule, period", [("linear:1:0:280000", 20000), ("linear:1:0:560000", 40000),
                                              ("linear:1:0:840000", 60000)])
def test_linear_schedules_widen_the_window_as_the_released_salad_windows_on_8x8(schedule, period):
    """The original's window side is (t + 2 * period) // period, capped at the whole grid (16 on 8x8)."""
    rules = gridtasks.SaladEnv(shaping=schedule).rules[0]
    for k in range(15):
        t = period * k
        s = engine.shaping_strength(rules, float(t))
        assert engine.window_side(8, s) == 2 + k, t
        if k > 0:
            s_before = engine.shaping_strength(rules, float(t - 1))
            assert engine.window_side(8, s_before) == 1 + k, t - 1
    for t in (14 * period, 15 * period, 10**7):
        assert engine.window_side(8, engine.shaping_strength(rules, float(t))) == 16


def spawn_cells(env, agent, trials: int, s: float) -> set[tuple[int, int]]:
    """Cells where the missing lettuce regrows over ``trials`` regrowths with the agent at ``agent``."""
    rules = env.unwrapped.rules[0]
    text = """
    #######
    #.....#
    #.....#
    #.....#
    #.....#
    #....C#
    #######
    """
    seen = set()
    for _ in range(trials):
        world = world_from_map(env, text, agent=agent)
        engine.grow_resources(world, rules, s)
        (cell,) = cells(world, Code.LETTUCE)
        seen.add(cell)
    return seen


@pytest.mark.parametrize("agent", [(3, 3), (2, 4), (5, 2)])
def test_full_shaping_grows_ingredients_only_in_the_2_cell_window(agent):
    env = salad(dynamism=0.0, shaping=1.0, regrow_when_empty=True)
    x, y = agent
    window = {(x - 1, y - 1), (x, y - 1), (x - 1, y), (x, y)}  # the 2×2 square ending at the agent
    assert spawn_cells(env, agent, 300, 1.0) == window


@pytest.mark.parametrize(("agent", "original", "shifted"), [
    ((1, 1), {(1, 1)}, {(1, 1), (2, 1), (1, 2), (2, 2)}),
    ((5, 1), {(4, 1), (5, 1)}, {(4, 1), (5, 1), (4, 2), (5, 2)}),
    ((1, 4), {(1, 3), (1, 4)}, {(1, 3), (2, 3), (1, 4), (2, 4)}),
])
def test_full_shaping_window_beside_a_wall(agent, original, shifted):
    """The original clips the 2-cell window at the grid's edge, its wall cells taking nothing (in a corner only the
    agent's cell is left); ``spawn_window="shifted"`` moves it inside the wall ring instead.
    """
    assert spawn_cells(salad(dynamism=0.0, shaping=1.0, regrow_when_empty=True), agent, 300, 1.0) == original
    env = salad(dynamism=0.0, shaping=1.0, regrow_when_empty=True, spawn_window="shifted")
    assert spawn_cells(env, agent, 300, 1.0) == shifted


@pytest.mark.parametrize("rule", ["original", "shifted"])
def test_a_side_4_window_at_the_far_walls(rule):
    """Agent at (5, 4) of 7×7, side 4: the original's window starts at (3, 2) and is cut by the walls (3 × 4 cells,
    the carrot's taken), the shifted one starts at (2, 2) (4 × 4).
    """
    env = salad(dynamism=0.0, shaping=1.0, regrow_when_empty=True, spawn_window=rule)
    x0 = 3 if rule == "original" else 2
    window = {(x, y) for x in range(x0, 6) for y in range(2, 6)} - {(5, 5)}
    assert spawn_cells(env, (5, 4), 1500, 5 / 6) == window


def test_intermediate_shaping_window_side_4():
    env = salad(dynamism=0.0, shaping=1.0, regrow_when_empty=True)
    s = 5 / 6  # side = 2 + floor((1 - s)·12) = 4 on 7×7
    assert engine.window_side(7, s) == 4
    x0, y0 = 3 - 2, 3 - 2
    window = {(x, y) for x in range(x0, x0 + 4) for y in range(y0, y0 + 4)}
    assert spawn_cells(env, (3, 3), 1000, s) == window


def test_unshaped_ingredients_grow_anywhere():
    env = salad(dynamism=0.0, shaping=0.0, regrow_when_empty=True)
    interior = {(x, y) for x in range(1, 6) for y in range(1, 6)}
    assert spawn_cells(env, (3, 3), 1000, 0.0) == interior - {(5, 5)}


def test_shaped_regrowth_in_a_full_step_lands_next_to_the_agent():
    env = salad(dynamism=0.0, shaping=1.0, regrow_when_empty=True)
    text = """
    #######
    #.....#
    #.....#
    #.....#
    #...C.#
    #.....#
    #######
    """
    for _ in range(50):
        world = world_from_map(env, text, agent=(4, 4), inventory=Code.LETTUCE)
        env.step(PLACE)  # the salad uses up the last lettuce and carrot: both regrow next to the agent
        assert world["grid"][4, 4] == Code.SALAD
        assert set(cells(world, Code.LETTUCE, Code.CARROT)) <= {(3, 3), (4, 3), (3, 4)}
        assert len(cells(world, Code.LETTUCE)) == len(cells(world, Code.CARROT)) == 1


def test_shaped_growth_with_dynamism_stays_in_the_window():
    env = salad(dynamism=0.5, shaping=1.0)
    rules = env.unwrapped.rules[0]
    for _ in range(300):
        world = world_from_map(env, BARE, agent=(4, 3))
        engine.grow_resources(world, rules, 1.0)
        new = set(cells(world, Code.LETTUCE, Code.CARROT)) - {(2, 2), (4, 4)}
        assert new <= {(3, 2), (4, 2), (3, 3), (4, 3)}


def test_initial_objects_ignore_the_window():
    env = gridtasks.SaladEnv(shaping=1.0, initial_count=2)
    far = 0
    for seed in range(30):
        env.reset(seed=seed)
        world = env.unwrapped.world
        ax, ay = (int(v) for v in world["agent"])
        for x, y in cells(world, Code.LETTUCE, Code.CARROT):
            far += abs(x - ax) + abs(y - ay) > 2
    assert far > 0


# ---------------------------------------------------------------------------------------------- easy deer


def deer_spawns(env, trials: int, s: float) -> list[int]:
    """Kinds of the deer replenished ``trials`` times on an otherwise deer-free grid."""
    rules = env.unwrapped.rules[0]
    text = """
    #######
    #.....#
    #.A...#
    #.....#
    #...A.#
    #....@#
    #######
    """
    kinds = []
    for _ in range(trials):
        world = world_from_map(env, text)
        engine.grow_resources(world, rules, s)
        ((x, y),) = cells(world, Code.DEER, Code.DEER_EASY, Code.DEER_HARD)
        kinds.append(int(world["grid"][y, x]))
    return kinds


def hunting(**kwargs):
    return make(gridtasks.HuntingEnv, 7, deer_count=1, axe_count=2, **kwargs)


def test_full_easy_deer_shaping_spawns_only_easy_deer():
    env = hunting(deer_kind="hard", deer_speed=0.2, shaping=1.0)
    assert set(deer_spawns(env, 200, 1.0)) == {Code.DEER_EASY}


def test_initial_deer_are_shaped_too():
    env = gridtasks.HuntingEnv(deer_kind="hard", deer_speed=0.2, shaping=1.0, deer_count=2)
    for seed in range(10):
        env.reset(seed=seed)
        grid = env.unwrapped.world["grid"]
        assert np.count_nonzero(grid == Code.DEER_EASY) == 2
        assert np.count_nonzero(grid == Code.DEER_HARD) == 0


@pytest.mark.parametrize("kind, code", [("hard", Code.DEER_HARD), ("wander", Code.DEER), ("easy", Code.DEER_EASY)])
def test_no_shaping_spawns_only_the_base_kind(kind, code):
    env = hunting(deer_kind=kind, shaping=0.0)
    assert set(deer_spawns(env, 100, 0.0)) == {code}


def test_easy_deer_fraction_is_the_shaping_strength():
    s, trials = 0.3, 2000
    env = hunting(deer_kind="hard", shaping=1.0)
    kinds = deer_spawns(env, trials, s)
    easy = kinds.count(Code.DEER_EASY)
    assert set(kinds) == {Code.DEER_EASY, Code.DEER_HARD}
    assert abs(easy - s * trials) < tolerance(trials, s)


def test_nearby_mechanism_spawns_base_deer_and_axes_next_to_the_agent():
    env = hunting(deer_kind="hard", shaping=1.0, shaping_mechanism="nearby")
    rules = env.unwrapped.rules[0]
    window = {(3, 2), (4, 2), (3, 3), (4, 3)}
    for _ in range(100):
        world = world_from_map(env, """
        #######
        #.....#
        #.....#
        #.....#
        #.....#
        #.....#
        #######
        """, agent=(4, 3))
        engine.grow_resources(world, rules, 1.0)
        deer, axes = cells(world, Code.DEER_HARD), cells(world, Code.AXE)
        assert len(deer) == 1 and len(axes) == 1 and cells(world, Code.DEER_EASY) == []
        assert set(deer + axes) <= window


def test_shaping_window_for_scavenging_food():
    env = make(gridtasks.ScavengingEnv, 7, food_count=1, predator_count=0, shaping=1.0)
    for _ in range(100):
        world = world_from_map(env, """
        #######
        #.....#
        #.....#
        #.....#
        #.....#
        #.....#
        #######
        """, agent=(2, 5))
        engine.grow_resources(world, env.unwrapped.rules[0], 1.0)
        assert cells(world, Code.FOOD)[0] in {(1, 4), (2, 4), (1, 5), (2, 5)}
