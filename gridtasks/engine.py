"""The grid engine: world state as numpy records, the rules as lookup tables, `step` as named phases.

One world is one record of ``world_dtype(n)`` (grid codes, ages, agent, inventory, counters, its own RNG);
a batch of worlds is an array of such records. The rules of a task are one record of ``rules_dtype(n)``:
every task-specific behaviour is a table indexed by object code (what a code grows into, how it moves,
what it is worth), filled in by the task's module. The compiled kernels read only those tables, so the
five tasks share one implementation, and the single environment is the batched one with one world.

The engine is four modules: `gridtasks.records` (the record layouts and constants), `gridtasks.cells` (the
random stream, the shaping strength, cell and move helpers), `gridtasks.phases` (the phases of a step) and
this one (a world's reset and step, and the batched loops, on one thread or across numba's threads), which
re-exports the others' interface.

A step is the sequence of phases
    act -> move_creatures -> move_predators -> grow_resources -> replenish_predators -> wither -> reward
    -> observe
each a small compiled function of (world, rules) that tests can call on its own. The order is the original
code's: new objects grow before everything ages, so an object with lifespan L can be picked up on L - 1
steps after the one it grew in. In hunting (``creatures_before_hands``) the deer move between the
agent's move and its pick-up / place, as in the original.

Randomness: each world owns a SplitMix64 stream (``world.rng``), seeded from the environment's
``np_random``. Every draw of a world comes from its own stream, so a world behaves identically whether it
is stepped alone or in a batch of 4 096, on one thread or many.
"""

from __future__ import annotations

import numba as nb

from gridtasks.cells import (
    count_code,
    count_codes,
    directed_step,
    free_cell,
    move_object,
    nearest_distance,
    place_random,
    randint,
    random_step,
    shaping_strength,
    spawn,
    uniform,
    window_side,
)
from gridtasks.codes import DISPENSES, GROUP, PASSABLE, PICKABLE, Code
from gridtasks.phases import (
    act,
    grow_resources,
    move_creatures,
    move_predators,
    observe,
    predator_alive,
    predator_caught,
    replenish_predators,
    respawn_predator,
    task_reward,
    wither,
)
from gridtasks.records import (
    _EMPTY,
    ACTION_NAMES,
    DISTANCE,
    DISTANCE_COEF,
    DX,
    DY,
    EAST,
    INTERACT,
    LOST_PROGRESS_PENALTY,
    MAX_BREAKPOINTS,
    MAX_PREDATORS,
    MAX_STAGES,
    NC,
    NORTH,
    NUM_ACTIONS,
    NUM_TARGET_GROUPS,
    ONE_TIME,
    PICK_UP,
    PLACE,
    PREDATOR_RESPAWN_IDS,
    REWARD_MODE_IDS,
    SOUTH,
    SPARSE,
    STEP_DX,
    STEP_DY,
    SUBGOAL,
    SUBGOAL_REWARD,
    TASK_REWARD,
    VIEW,
    VIEW_CELLS,
    WAYPOINT,
    WEST,
    code_mask,
    new_rules,
    rules_dtype,
    world_dtype,
)

__all__ = [
    "ACTION_NAMES",
    "Code",
    "DISPENSES",
    "DISTANCE",
    "DISTANCE_COEF",
    "DX",
    "DY",
    "EAST",
    "GROUP",
    "INTERACT",
    "LOST_PROGRESS_PENALTY",
    "MAX_BREAKPOINTS",
    "MAX_PREDATORS",
    "MAX_STAGES",
    "NC",
    "NORTH",
    "NUM_ACTIONS",
    "NUM_TARGET_GROUPS",
    "ONE_TIME",
    "PASSABLE",
    "PICKABLE",
    "PICK_UP",
    "PLACE",
    "PREDATOR_RESPAWN_IDS",
    "REWARD_MODE_IDS",
    "SOUTH",
    "SPARSE",
    "STEP_DX",
    "STEP_DY",
    "SUBGOAL",
    "SUBGOAL_REWARD",
    "TASK_REWARD",
    "VIEW",
    "VIEW_CELLS",
    "WAYPOINT",
    "WEST",
    "act",
    "advance_world",
    "begin_episode",
    "code_mask",
    "count_code",
    "count_codes",
    "directed_step",
    "free_cell",
    "grow_resources",
    "move_creatures",
    "move_object",
    "move_predators",
    "nearest_distance",
    "new_rules",
    "observe",
    "place_random",
    "predator_alive",
    "predator_caught",
    "randint",
    "random_step",
    "replenish_predators",
    "reset_world",
    "reset_worlds",
    "reset_worlds_threaded",
    "respawn_predator",
    "rules_dtype",
    "shaping_strength",
    "spawn",
    "step_world",
    "step_worlds",
    "step_worlds_threaded",
    "task_reward",
    "uniform",
    "window_side",
    "wither",
    "world_dtype",
]
"""The engine's interface: the records and constants (`gridtasks.records`), the helpers (`gridtasks.cells`) and
the phases and world lifecycle defined here."""


# ------------------------------------------------------------------------------------ world lifecycle


@nb.njit(cache=True)
def reset_world(w, r, obs) -> None:
    """Start a new episode: the fixed layout, the initial objects anywhere, then the agent on a random
    empty cell, then the predators (`respawn_predator`'s cells). The RNG stream and the lifetime clock carry on.
    """
    n = r.n
    w.grid[:, :] = r.layout
    w.age[:, :] = 0
    w.inventory, w.carried_age = 0, 0
    w.episode_step, w.completions = 0, 0
    w.needs_reset = False
    w.stage_done[:] = 0
    w.pickups[:] = 0
    w.made[:] = 0
    w.agent[0], w.agent[1] = -1, -1
    w.start[0], w.start[1] = -1, -1
    s = shaping_strength(r, w.lifetime_step)
    for code in range(NC):
        for _ in range(r.initial[code]):
            spawn(w, r, code, False, s)
    free = 0
    for y in range(n):
        for x in range(n):
            if w.grid[y, x] == _EMPTY:
                free += 1
    k = randint(w, free)
    for y in range(n):
        for x in range(n):
            if w.grid[y, x] == _EMPTY:
                if k == 0:
                    w.agent[0], w.agent[1] = x, y
                    w.start[0], w.start[1] = x, y
                k -= 1
    for i in range(r.num_predators):
        respawn_predator(w, r, i, True)
    observe(w, r, obs)


@nb.njit(cache=True)
def step_world(w, r, action: int, obs):
    """One step of one world. Returns (reward, terminated, truncated, solved, caught)."""
    s = shaping_strength(r, w.lifetime_step)
    start_x, start_y = w.agent[0], w.agent[1]
    creatures_first = r.creatures_before_hands and action >= PICK_UP
    if creatures_first:
        move_creatures(w, r, s, start_x, start_y)
    picked, made, placed_on, dropped, delivered = act(w, r, action)
    solved = delivered or (picked != 0 and picked == r.goal_pickup) or (made != 0 and made == r.goal_made)
    if solved:
        w.completions += 1
        if r.reset_free and made != 0:
            w.grid[w.agent[1], w.agent[0]], w.age[w.agent[1], w.agent[0]] = 0, 0  # the product made is used up
        elif r.reset_free and not delivered:
            w.inventory = 0  # the world goes on: the completed task's object is consumed (and regrows)
    if not creatures_first:
        move_creatures(w, r, s, start_x, start_y)
    move_predators(w, r, start_x, start_y)
    grow_resources(w, r, s)
    replenish_predators(w, r)
    caught = predator_caught(w, r)
    wither(w, r)
    reward = task_reward(w, r, picked, made, placed_on, dropped, solved)
    if caught:
        reward -= r.predator_penalty
    w.episode_step += 1
    w.lifetime_step += 1
    terminated = solved and not r.reset_free
    truncated = (not r.reset_free) and (not terminated) and w.episode_step >= r.horizon
    if r.replay_unsolved > 0 and not r.reset_free and not terminated:
        boundary = w.lifetime_step % r.replay_unsolved == 0  # a new collection starts with a fresh layout
        w.replay_layout = truncated and not boundary
        truncated = truncated or boundary
    observe(w, r, obs)
    return reward, terminated, truncated, solved, caught


@nb.njit(cache=True)
def begin_episode(w, r, obs) -> None:
    """Reset a world: a fresh layout, or (the original's episodic rule, ``replay_unsolved``) the layout
    of the episode that just ended unsolved, redrawn from the same point of the world's stream.
    """
    if r.replay_unsolved > 0 and w.replay_layout:
        w.rng = w.layout_rng
    else:
        w.layout_rng = w.rng
    w.replay_layout = False
    reset_world(w, r, obs)


@nb.njit(cache=True, inline="always")
def advance_world(w, r, action: int, obs, autoreset: bool):
    """One call of the batched step for one world: a step, or with ``autoreset`` the reset of a world whose
    episode ended on the previous call (Gymnasium's next-step autoreset: reward 0, neither terminated nor
    truncated). Returns (reward, terminated, truncated, solved, caught).
    """
    if autoreset and w.needs_reset:
        begin_episode(w, r, obs)
        return 0.0, False, False, False, False
    rew, term, trunc, solv, cau = step_world(w, r, action, obs)
    w.needs_reset = term or trunc
    return rew, term, trunc, solv, cau


@nb.njit(cache=True)
def step_worlds(state, rules, actions, obs, rewards, terminated, truncated, solved, caught, autoreset):
    """Step every world of ``state`` with its action, writing observations and outcomes in place.

    With ``autoreset`` a world whose episode ended on the previous call is reset instead of stepped
    (see `advance_world`).
    """
    r = rules[0]
    for b in range(state.shape[0]):
        out = advance_world(state[b], r, actions[b], obs[b], autoreset)
        rewards[b], terminated[b], truncated[b], solved[b], caught[b] = out


@nb.njit(cache=True)
def reset_worlds(state, rules, mask, obs) -> None:
    """Reset the worlds selected by ``mask`` (their RNG streams carry on; see `begin_episode`)."""
    r = rules[0]
    for b in range(state.shape[0]):
        if mask[b]:
            begin_episode(state[b], r, obs[b])


# ------------------------------------------------------------------- the batched loops across threads
# The same loops with the worlds shared out among numba's threads. A world touches only its own record
# (its random stream included), its own rows of the outputs and the read-only rules, so the result is
# bit-identical to the sequential loop whatever the number of threads. Compiled on first use (a parallel
# compilation takes seconds) and cached. The rules record is read inside the loop body: numba 0.68
# cannot pass a record value defined outside a parallel loop into it.


@nb.njit(cache=True, parallel=True)
def step_worlds_threaded(state, rules, actions, obs, rewards, terminated, truncated, solved, caught, autoreset):
    """`step_worlds` across numba's threads (as many as ``numba.set_num_threads`` last set in this thread)."""
    for b in nb.prange(state.shape[0]):
        out = advance_world(state[b], rules[0], actions[b], obs[b], autoreset)
        rewards[b], terminated[b], truncated[b], solved[b], caught[b] = out


@nb.njit(cache=True, parallel=True)
def reset_worlds_threaded(state, rules, mask, obs) -> None:
    """`reset_worlds` across numba's threads."""
    for b in nb.prange(state.shape[0]):
        if mask[b]:
            begin_episode(state[b], rules[0], obs[b])
