"""Creatures on hand-drawn worlds: wandering and directed deer, predators, factory workers."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from fixtures import assert_map, cells, make, world_from_map

import gridtasks
from gridtasks import engine
from gridtasks.codes import Code
from gridtasks.engine import EAST, INTERACT, NORTH, WEST

OPEN_CENTRE = """
#######
#.....#
#.....#
#..D..#
#.....#
#....@#
#######
"""
"""A deer at (3, 3) with all four neighbours free, the agent far away at (5, 5)."""

NEIGHBOURS = {(3, 2): "N", (2, 3): "W", (3, 4): "S", (4, 3): "E"}


def binomial_tolerance(n: int, p: float, sigmas: float = 4.0) -> float:
    """``sigmas`` standard deviations of a Binomial(n, p) count."""
    return sigmas * math.sqrt(n * p * (1 - p))


def hunting(**kwargs):
    """A 7×7 hunting env without replenishment (only the drawn deer exist)."""
    return make(gridtasks.HuntingEnv, 7, replenish=False, **kwargs)


def deer_moves(env, text: str, trials: int, agent=None, s: float = 0.0) -> dict[tuple[int, int], int]:
    """Draw the map ``trials`` times, move the creatures once each time, count where the one deer ends."""
    counts: dict[tuple[int, int], int] = {}
    rules = env.unwrapped.rules[0]
    for _ in range(trials):
        world = world_from_map(env, text, agent=agent)
        engine.move_creatures(world, rules, s, *world["agent"])  # the agent has not moved
        (cell,) = cells(world, Code.DEER, Code.DEER_EASY, Code.DEER_HARD)
        counts[cell] = counts.get(cell, 0) + 1
    return counts


# ---------------------------------------------------------------------------------------------- wander deer


def test_wander_deer_never_move_without_dynamism():
    env = hunting(dynamism=0.0)
    world = world_from_map(env, OPEN_CENTRE)
    for _ in range(200):
        env.step(INTERACT)
    assert_map(world, OPEN_CENTRE)


def test_wander_deer_with_p1_always_move_to_a_free_neighbour():
    env = hunting(dynamism=1.0)
    counts = deer_moves(env, OPEN_CENTRE, 400)
    assert set(counts) == set(NEIGHBOURS)


def test_wander_deer_move_at_rate_p_uniformly_over_free_neighbours():
    p, trials = 0.3, 2000
    env = hunting(dynamism=p)
    counts = deer_moves(env, OPEN_CENTRE, trials)
    moved = trials - counts.get((3, 3), 0)
    assert set(counts) <= set(NEIGHBOURS) | {(3, 3)}
    assert abs(moved - p * trials) < binomial_tolerance(trials, p)
    for cell in NEIGHBOURS:  # each direction is a quarter of the moves
        assert abs(counts[cell] - moved / 4) < binomial_tolerance(moved, 0.25)


def test_wander_deer_never_step_onto_walls_or_objects():
    # deer in the corner (1, 1): west and north are walls, east holds an axe -> only south is free
    text = """
    #######
    #DA...#
    #.....#
    #.....#
    #.....#
    #....@#
    #######
    """
    # the original's rule: one of N, W, S, E at random, taken only if free, so with p = 1 the deer moves
    # south a quarter of the time and stays otherwise
    trials = 800
    env = hunting(dynamism=1.0)
    counts = deer_moves(env, text, trials)
    assert set(counts) == {(1, 1), (1, 2)}
    assert abs(counts[(1, 2)] - trials / 4) < binomial_tolerance(trials, 0.25)


def test_wander_deer_with_no_free_neighbour_stay():
    text = """
    #######
    #DA...#
    #F....#
    #.....#
    #.....#
    #....@#
    #######
    """
    env = hunting(dynamism=1.0)
    assert deer_moves(env, text, 50) == {(1, 1): 50}


def test_deer_may_step_onto_the_agents_cell():
    text = """
    #######
    #DA...#
    #@....#
    #.....#
    #.....#
    #.....#
    #######
    """
    env = hunting(dynamism=1.0)
    counts = deer_moves(env, text, 200)
    assert set(counts) == {(1, 1), (1, 2)}  # south onto the agent (a quarter of the time), else blocked


# ---------------------------------------------------------------------------------------------- easy / hard


@pytest.mark.parametrize(
    "kind, deer, agent, expected",
    [
        ("easy", (3, 3), (1, 1), (3, 2)),  # N and W both approach: N wins the tie
        ("easy", (3, 3), (1, 5), (2, 3)),  # W and S both approach: W wins
        ("easy", (3, 3), (5, 5), (3, 4)),  # S and E both approach: S wins
        ("easy", (3, 3), (5, 3), (4, 3)),  # only E approaches
        ("easy", (3, 3), (3, 4), (3, 4)),  # onto the agent's cell
        ("easy", (3, 3), (3, 3), (3, 3)),  # on the agent's cell already: every step is worse, stay
        ("hard", (3, 3), (1, 1), (3, 4)),  # S and E both flee: S wins
        ("hard", (3, 3), (5, 5), (3, 2)),  # N and W both flee: N wins
        ("hard", (3, 3), (1, 5), (3, 2)),  # N and E flee: N wins
        ("hard", (3, 5), (1, 1), (4, 5)),  # south is a wall, only E flees
        ("hard", (5, 5), (1, 1), (5, 5)),  # cornered: every free step approaches, stay
    ],
)
def test_directed_deer_take_the_best_step_with_tie_order_n_w_s_e_stay(kind, deer, agent, expected):
    env = hunting(deer_kind=kind, deer_speed=1.0)
    symbol = {"easy": "E", "hard": "H"}[kind]
    rows = [list("#######")] + [list("#.....#") for _ in range(5)] + [list("#######")]
    rows[deer[1]][deer[0]] = symbol
    world = world_from_map(env, "\n".join("".join(r) for r in rows), agent=agent)
    env.step(INTERACT)  # a no-op: the agent stays where it is
    assert cells(world, Code.DEER_EASY, Code.DEER_HARD) == [expected]
    assert world["grid"][expected[1], expected[0]] == (Code.DEER_EASY if kind == "easy" else Code.DEER_HARD)


@pytest.mark.parametrize(("rule", "expected"), [("original", (3, 3)), ("current-free", (2, 3))])
def test_a_blocked_best_step_is_not_taken_by_the_original_rule_and_gone_around_by_current_free(rule, expected):
    # N (3, 2) holds an axe and ties with W as the best approach: the original picks N and, blocked, stays;
    # current-free picks the best free step, W
    text = """
    #######
    #.....#
    #..A..#
    #..E..#
    #.....#
    #.....#
    #######
    """
    env = hunting(deer_kind="easy", deer_speed=1.0, directed_moves=rule)
    world = world_from_map(env, text, agent=(1, 1))
    env.step(INTERACT)
    assert cells(world, Code.DEER_EASY) == [expected]


@pytest.mark.parametrize(("rule", "expected"), [("original", (3, 4)), ("current-free", (2, 3))])
def test_hard_deer_flee_the_cell_the_agent_left_under_the_original_rule(rule, expected):
    # the agent steps east from (2, 2) to (3, 2), beside the deer at (3, 3). Fleeing (2, 2), S and E tie at
    # distance 3 (S first); fleeing (3, 2), W, S and E tie at 2 (W first)
    env = hunting(deer_kind="hard", deer_speed=1.0, directed_moves=rule)
    world = world_from_map(env, OPEN_CENTRE.replace("D", "H").replace("@", "."), agent=(2, 2))
    env.step(EAST)
    assert tuple(world["agent"]) == (3, 2)
    assert cells(world, Code.DEER_HARD) == [expected]


@pytest.mark.parametrize("kind", ["easy", "hard"])
def test_directed_deer_with_speed_0_and_no_dynamism_never_move(kind):
    env = hunting(deer_kind=kind, deer_speed=0.0)
    symbol = {"easy": "E", "hard": "H"}[kind]
    text = OPEN_CENTRE.replace("D", symbol)
    world = world_from_map(env, text)
    for _ in range(100):
        env.step(INTERACT)
    assert_map(world, text)


def test_directed_step_rate_is_deer_speed():
    speed, trials = 0.4, 2000
    env = hunting(deer_kind="easy", deer_speed=speed)
    counts = deer_moves(env, OPEN_CENTRE.replace("D", "E"), trials)
    # the agent at (5, 5): an approach is S (3, 4) by the tie order
    assert set(counts) == {(3, 3), (3, 4)}
    assert abs(counts[(3, 4)] - speed * trials) < binomial_tolerance(trials, speed)


# ---------------------------------------------------------------------------------------------- predators


def scavenging(**kwargs):
    """A 7×7 scavenging env with one predator and no food (so no distance term)."""
    kwargs = {"predator_count": 1, "food_count": 0, **kwargs}
    return make(gridtasks.ScavengingEnv, 7, **kwargs)


EMPTY7 = "\n".join(["#######"] + ["#.....#"] * 5 + ["#######"])


@pytest.mark.parametrize(
    "predator, agent, action, expected",
    [
        ((1, 3), (3, 3), NORTH, (2, 3)),  # chases (3, 3), where the agent was, not (3, 2): E, not N
        ((1, 3), (4, 3), EAST, (2, 3)),
        ((2, 1), (4, 3), EAST, (2, 2)),  # S and E tie toward (4, 3): S first
        ((5, 5), (3, 3), INTERACT, (5, 4)),  # N and W tie: N first
        ((4, 1), (2, 3), INTERACT, (3, 1)),  # W and S tie: W first
        ((1, 1), (5, 5), INTERACT, (1, 2)),  # N and W are walls: S
        ((3, 3), (3, 3), EAST, (3, 3)),  # already on the target cell: stay
    ],
)
def test_predators_step_greedily_toward_the_agents_previous_cell(predator, agent, action, expected):
    env = scavenging()
    world = world_from_map(env, EMPTY7, agent=agent, predators=[predator])
    _, reward, _, _, info = env.step(action)
    assert tuple(world["pred"][0]) == expected
    assert world["pred_age"][0] == 1
    assert info["caught"] == (expected == tuple(info["agent_pos"]))


@pytest.mark.parametrize("reward_mode", ["sparse", "subgoal", "one_time", "distance"])
def test_a_predator_on_the_agents_cell_costs_100_in_every_reward_mode(reward_mode):
    env = scavenging(reward=reward_mode)
    world = world_from_map(env, EMPTY7, agent=(3, 3), predators=[(3, 2)])
    _, reward, terminated, truncated, info = env.step(INTERACT)
    assert tuple(world["pred"][0]) == (3, 3)
    assert reward == -100.0 and info["caught"]
    assert (terminated, truncated) == (False, False)
    # the agent steps away from the predator: chased to its previous cell, (3, 3), not caught
    _, reward, _, _, info = env.step(EAST)
    assert tuple(world["pred"][0]) == (3, 3)
    assert not info["caught"]
    assert reward == 0.0


def test_a_predator_next_to_the_agent_costs_nothing():
    env = scavenging()
    world = world_from_map(env, EMPTY7, agent=(3, 3), predators=[(1, 3)])
    _, reward, _, _, info = env.step(INTERACT)
    assert tuple(world["pred"][0]) == (2, 3)
    assert reward == 0.0 and not info["caught"]


def test_two_predators_on_the_agent_cost_100_once():
    env = scavenging(predator_count=2)
    world_from_map(env, EMPTY7, agent=(3, 3), predators=[(3, 2), (4, 3)])
    _, reward, _, _, info = env.step(INTERACT)
    assert reward == -100.0 and info["caught"]


def test_food_is_worth_100_even_when_caught():
    env = scavenging()
    text = EMPTY7[:8 * 3 + 3] + "F" + EMPTY7[8 * 3 + 4:]  # food at (3, 3)
    world = world_from_map(env, text, agent=(3, 3), predators=[(3, 2)])
    assert world["grid"][3, 3] == Code.FOOD
    _, reward, terminated, _, info = env.step(engine.PICK_UP)
    assert info["caught"] and info["solved"] and terminated
    assert reward == 0.0  # +100 - 100


@pytest.mark.parametrize("respawn", ["original", "off-agent"])
def test_predators_reappear_after_their_lifespan(respawn):
    env = scavenging(predator_lifespan=3, predator_respawn=respawn)
    world = world_from_map(env, EMPTY7, agent=(5, 5), predators=[(1, 1)], start=(4, 4))
    trail, ages = [], []
    for _ in range(3):
        env.step(INTERACT)
        trail.append(tuple(int(v) for v in world["pred"][0]))
        ages.append(int(world["pred_age"][0]))
    assert trail[:2] == [(1, 2), (1, 3)]
    assert ages == [1, 2, 0]  # reborn on its third step (alone, it is the step's one)
    x, y = trail[2]
    assert 1 <= x <= 5 and 1 <= y <= 5 and (x, y) != {"original": (4, 4), "off-agent": (5, 5)}[respawn]


FOOD_AT_2_2 = EMPTY7[:8 * 2 + 2] + "F" + EMPTY7[8 * 2 + 3:]
"""EMPTY7 with a food at (2, 2)."""


@pytest.mark.parametrize("respawn, never", [("original", {(4, 4), (2, 2)}), ("off-agent", {(3, 3)})])
def test_reborn_predators_appear_at_random_cells_but_the_excluded_ones(respawn, never):
    """The original rule: any cell holding no object but the agent's start cell (4, 4), the agent's own (3, 3)
    included; off-agent: any non-wall cell, food included, but the agent's.
    """
    env = scavenging(predator_lifespan=1, horizon=400, food_count=1, predator_respawn=respawn)
    world = world_from_map(env, FOOD_AT_2_2, agent=(3, 3), predators=[(1, 1)], start=(4, 4))
    seen = set()
    for _ in range(300):
        env.step(INTERACT)
        assert world["pred_age"][0] == 0
        seen.add(tuple(int(v) for v in world["pred"][0]))
    assert seen == {(x, y) for x in range(1, 6) for y in range(1, 6)} - never


def test_a_predator_reborn_on_the_agent_catches_it_at_once():
    env = scavenging(predator_lifespan=1, horizon=400)
    world = world_from_map(env, EMPTY7, agent=(3, 3), predators=[(1, 1)], start=(4, 4))
    births_on_agent = 0
    for _ in range(300):
        _, reward, _, _, info = env.step(INTERACT)
        on_agent = tuple(world["pred"][0]) == (3, 3)
        births_on_agent += on_agent
        assert info["caught"] == on_agent and reward == (-100.0 if on_agent else 0.0)
    assert births_on_agent > 0


def test_two_predators_dying_together_come_back_a_step_apart_the_waiting_one_unseen_and_harmless():
    env = scavenging(predator_count=2, predator_lifespan=2)
    # both die on the first step (age 1 -> 2): the first is reborn then, the second a step later
    world = world_from_map(env, EMPTY7, agent=(3, 3), predators=[(1, 3), (3, 4)], pred_ages=[1, 1],
                           start=(5, 5))
    obs, reward, _, _, info = env.step(INTERACT)
    assert list(world["pred_age"][:2]) == [0, 2]  # the second is dead, left where it died: (3, 3), on the agent
    assert tuple(world["pred"][1]) == (3, 3)
    first = tuple(int(v) for v in world["pred"][0])
    assert info["caught"] == (first == (3, 3))
    predator = 3
    assert obs[predator * 25:predator * 25 + 25].sum() == (1 if first in _view_of((3, 3)) else 0)
    env.step(INTERACT)
    assert list(world["pred_age"][:2]) == [1, 0]


def _view_of(agent):
    """The cells of the 5x5 view around ``agent`` on EMPTY7's interior."""
    return {(x, y) for x in range(agent[0] - 2, agent[0] + 3) for y in range(agent[1] - 2, agent[1] + 3)}


def test_a_dead_predator_does_not_move():
    env = scavenging(predator_count=2, predator_lifespan=1)
    world = world_from_map(env, EMPTY7, agent=(5, 5), predators=[(1, 1), (1, 2)])
    env.step(INTERACT)  # both die moving; the first is reborn, the second waits at (1, 3)
    assert list(world["pred_age"][:2]) == [0, 1] and tuple(world["pred"][1]) == (1, 3)


def test_predators_with_p1_move_at_random():
    trials = 2000
    env = scavenging(dynamism=1.0)
    world = env.unwrapped.world
    rules = env.unwrapped.rules[0]
    counts: dict[tuple[int, int], int] = {}
    for _ in range(trials):
        world_from_map(env, EMPTY7, agent=(1, 1), predators=[(3, 3)])
        engine.move_predators(world, rules, 1, 1)
        cell = tuple(int(v) for v in world["pred"][0])
        counts[cell] = counts.get(cell, 0) + 1
    # one of N, W, S, E, stay uniformly (the original's monsters): away from the agent (S, E) as often as
    # toward it
    assert set(counts) == set(NEIGHBOURS) | {(3, 3)}
    for cell in [*NEIGHBOURS, (3, 3)]:
        assert abs(counts[cell] - trials / 5) < binomial_tolerance(trials, 0.2)


def test_predators_with_p0_always_chase():
    env = scavenging(dynamism=0.0)
    world = env.unwrapped.world
    rules = env.unwrapped.rules[0]
    for _ in range(200):
        world_from_map(env, EMPTY7, agent=(1, 1), predators=[(3, 3)])
        engine.move_predators(world, rules, 1, 1)
        assert tuple(world["pred"][0]) == (3, 2)


def test_random_predator_steps_into_a_wall_stay():
    env = scavenging(dynamism=1.0)
    world = env.unwrapped.world
    rules = env.unwrapped.rules[0]
    seen = set()
    for _ in range(200):
        world_from_map(env, EMPTY7, agent=(5, 5), predators=[(1, 1)])
        engine.move_predators(world, rules, 5, 5)
        seen.add(tuple(int(v) for v in world["pred"][0]))
    assert seen == {(1, 1), (2, 1), (1, 2)}


def test_predators_walk_over_food():
    env = scavenging(food_count=1)
    text = EMPTY7[:8 * 2 + 3] + "F" + EMPTY7[8 * 2 + 4:]  # food at (3, 2)
    world = world_from_map(env, text, agent=(3, 4), predators=[(3, 1)])
    env.step(INTERACT)
    assert tuple(world["pred"][0]) == (3, 2)
    assert world["grid"][2, 3] == Code.FOOD


# ---------------------------------------------------------------------------------------------- workers

FACTORY = """
#######
#X....#
#.....#
#..m..#
#.....#
#....w#
#######
"""


def factory(**kwargs):
    return make(gridtasks.FactoryEnv, 7, **kwargs)


def worker_moves(env, trials: int, agent=(1, 5), s: float = 0.0) -> dict[tuple[int, int], int]:
    counts: dict[tuple[int, int], int] = {}
    rules = env.unwrapped.rules[0]
    for _ in range(trials):
        world = world_from_map(env, FACTORY, agent=agent)
        engine.move_creatures(world, rules, s, *world["agent"])  # the agent has not moved
        (cell,) = cells(world, Code.METAL_WORKER)
        counts[cell] = counts.get(cell, 0) + 1
    return counts


def test_static_workers_never_move():
    env = factory()
    world = world_from_map(env, FACTORY, agent=(1, 5))
    for _ in range(200):
        env.step(INTERACT)
    assert_map(world, FACTORY, agent=(1, 5))


def test_workers_move_with_probability_p_among_four_directions_and_stay():
    # the original's rule: with probability p one of N, W, S, E, stay uniformly, so a free worker changes
    # cell with probability 4p/5
    p, trials = 0.25, 2000
    env = factory(dynamism=p)
    counts = worker_moves(env, trials)
    moved = trials - counts[(3, 3)]
    assert set(counts) == set(NEIGHBOURS) | {(3, 3)}
    assert abs(moved - 0.8 * p * trials) < binomial_tolerance(trials, 0.8 * p)


def test_workers_with_p1_never_move_onto_objects():
    env = factory(dynamism=1.0)
    rules = env.unwrapped.rules[0]
    text = """
    #######
    #Xm...#
    #M....#
    #.....#
    #.....#
    #....w#
    #######
    """
    for _ in range(100):
        world = world_from_map(env, text, agent=(3, 3))
        engine.move_creatures(world, rules, 0.0, *world["agent"])
        # metal worker at (2, 1): west is the depot, north a wall, so it goes S or E or stays
        assert cells(world, Code.METAL_WORKER)[0] in {(2, 1), (2, 2), (3, 1)}
        assert cells(world, Code.WOOD_WORKER)[0] in {(5, 5), (5, 4), (4, 5)}
        assert world["grid"][1, 1] == Code.DEPOT and world["grid"][2, 1] == Code.METAL


def test_cooperative_workers_step_toward_the_agent_with_shaping_1():
    env = factory(shaping=1.0)
    world = world_from_map(env, FACTORY, agent=(1, 5))
    env.step(INTERACT)
    # metal worker (3, 3) -> W and S tie toward (1, 5): W first; wood worker (5, 5) -> W (4, 5)
    assert_map(world, """
    #######
    #X....#
    #.....#
    #.m...#
    #.....#
    #...w.#
    #######
    """, agent=(1, 5))
    env.step(INTERACT)
    assert cells(world, Code.METAL_WORKER) == [(1, 3)]
    assert cells(world, Code.WOOD_WORKER) == [(3, 5)]


@pytest.mark.parametrize(("rule", "expected"), [("original", (3, 2)), ("current-free", (2, 1))])
def test_cooperative_workers_head_for_the_cell_the_agent_left_under_the_original_rule(rule, expected):
    # the agent steps west from (3, 3) to (2, 3). Toward (3, 3) the metal worker at (3, 1) steps S; toward
    # (2, 3), W and S tie at distance 2 and W comes first
    text = """
    #######
    #X.m..#
    #.....#
    #.....#
    #.....#
    #....w#
    #######
    """
    env = factory(shaping=1.0, directed_moves=rule)
    world = world_from_map(env, text, agent=(3, 3))
    env.step(WEST)
    assert tuple(world["agent"]) == (2, 3)
    assert cells(world, Code.METAL_WORKER) == [expected]


def test_cooperative_workers_sit_on_the_agents_cell_far_less_under_the_original_rule():
    """What the rule changes for a random policy (docs/fidelity.md): at strength 1 a worker ends a third of the
    steps on the agent's cell (where it blocks a drop) aiming at the cell the agent left, nearly every step
    aiming at the cell it moved to.
    """
    under = {}
    for rule in ("original", "current-free"):
        env = gridtasks.FactoryEnv(reset_free=True, shaping=1.0, directed_moves=rule)
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        w = env.unwrapped.world
        hits = 0
        for _ in range(2000):
            env.step(int(rng.integers(7)))
            hits += int(w["grid"][w["agent"][1], w["agent"][0]] in (Code.METAL_WORKER, Code.WOOD_WORKER))
        under[rule] = hits / 2000
    assert under["current-free"] > 0.9 and under["original"] < 0.4, under


def test_cooperative_step_rate_is_the_shaping_strength():
    s, trials = 0.5, 2000
    env = factory(shaping=1.0)  # the rule reads the strength passed to the phase
    counts = worker_moves(env, trials, agent=(1, 5), s=s)
    assert set(counts) == {(3, 3), (2, 3)}
    assert abs(counts[(2, 3)] - s * trials) < binomial_tolerance(trials, s)


def test_unshaped_static_workers_ignore_the_agent():
    env = factory(shaping=0.0)
    assert worker_moves(env, 100, agent=(1, 5)) == {(3, 3): 100}


def test_interact_follows_a_worker_that_moved():
    env = factory(dynamism=1.0)
    world = world_from_map(env, FACTORY, agent=(3, 3))
    env.step(INTERACT)  # dispensed before the worker moved away
    assert world["inventory"] == Code.METAL
    assert world["grid"][3, 3] == Code.EMPTY
    assert np.count_nonzero(world["grid"] == Code.METAL_WORKER) == 1


def test_a_dead_predator_is_not_drawn():
    from gridtasks.render import render_world

    env = scavenging(predator_count=2, predator_lifespan=3)
    world = world_from_map(env, EMPTY7, agent=(5, 5), predators=[(1, 1), (3, 3)])
    rules = env.unwrapped.rules[0]
    both = render_world(world, rules)
    world["pred_age"][1] = 3  # the second one dead, waiting to be reborn
    one = render_world(world, rules)
    world["pred"][1] = (1, 5)  # where a dead one waits does not matter
    np.testing.assert_array_equal(render_world(world, rules), one)
    world["pred_age"][1] = 0
    assert not np.array_equal(render_world(world, rules), one) and not np.array_equal(one, both)


def test_easy_deer_shaping_without_a_deer_speed_warns_that_it_changes_nothing():
    with pytest.warns(UserWarning, match="changes nothing while deer_speed is 0"):
        gridtasks.HuntingEnv(shaping=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gridtasks.HuntingEnv(shaping=1.0, deer_speed=0.2)
        gridtasks.HuntingEnv(shaping=1.0, shaping_mechanism="nearby")
