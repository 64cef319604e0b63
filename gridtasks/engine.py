"""The grid engine: world state as numpy records, the rules as lookup tables, `step` as named phases.

One world is one record of ``world_dtype(n)`` (grid codes, ages, agent, inventory, counters, its own RNG);
a batch of worlds is an array of such records. The rules of a task are one record of ``rules_dtype(n)``:
every task-specific behaviour is a table indexed by object code (what a code grows into, how it moves,
what it is worth), filled in by the task's module. The compiled kernels below read only those tables, so
the five tasks share one implementation, and the single environment is the batched one with one world.

A step is the sequence of phases
    act -> move_creatures -> move_predators -> grow_resources -> wither -> reward -> observe
each a small compiled function of (world, rules) that tests can call on its own. The order is the original
code's: new objects grow before everything ages, so an object with lifespan L can be picked up on L - 1
steps after the one it grew in. In hunting (``creatures_before_hands``) the deer move between the
agent's move and its pick-up / place, as in the original.

Randomness: each world owns a SplitMix64 stream (``world.rng``), seeded from the environment's
``np_random``. Every draw of a world comes from its own stream, so a world behaves identically whether it
is stepped alone or in a batch of 4 096.
"""

from __future__ import annotations

import hashlib

import numba as nb
import numpy as np
from numba.core import types as nb_types

from ecology import schedule_value
from gridtasks.codes import DISPENSES, GROUP, NUM_CODES, PASSABLE, PICKABLE, Code


def _stable_record_mangling(self) -> tuple:
    """Mangle a numpy record type by a digest of its layout, not by numba's per-process type counter.

    numba names a compiled kernel after its argument types, and names a record type by a counter that
    each process starts afresh. Kernels cached by two processes for two grid sizes (two record types) can
    then carry the same symbol name, and a third process that loads both crashes inside LLVM
    ("Didn't find key?", "free(): invalid pointer"). A digest of the record's layout is the same in every
    process and differs between layouts."""
    return type(self).__name__, (hashlib.blake2b(self.name.encode(), digest_size=8).hexdigest(),)


nb_types.Record.mangling_args = property(_stable_record_mangling)

VIEW = 5
"""Side of the egocentric, north-up observation window."""
VIEW_CELLS = VIEW * VIEW
MAX_STAGES = 4
"""Most intermediate stages a task can reward (subgoal / one-time modes)."""
MAX_PREDATORS = 4
MAX_BREAKPOINTS = 16
"""Most breakpoints of a shaping schedule the engine stores."""
NUM_TARGET_GROUPS = 3
"""Priority groups of the distance reward's target table."""

WEST, EAST, NORTH, SOUTH, PICK_UP, INTERACT, PLACE = range(7)
NUM_ACTIONS = 7
ACTION_NAMES = ("west", "east", "north", "south", "pick up", "interact", "place")
DX = np.array([-1, 1, 0, 0], dtype=np.int64)
DY = np.array([0, 0, -1, 1], dtype=np.int64)
# Creature step candidates, in the tie-breaking order of the original code: N, W, S, E, stay.
STEP_DX = np.array([0, -1, 0, 1, 0], dtype=np.int64)
STEP_DY = np.array([-1, 0, 1, 0, 0], dtype=np.int64)

SPARSE, SUBGOAL, ONE_TIME, DISTANCE, WAYPOINT = range(5)
REWARD_MODE_IDS = {"sparse": SPARSE, "subgoal": SUBGOAL, "one_time": ONE_TIME, "distance": DISTANCE,
                   "waypoint": WAYPOINT}
TASK_REWARD = 100.0
SUBGOAL_REWARD = 1.0
LOST_PROGRESS_PENALTY = -100.0
DISTANCE_COEF = 0.01

NC = NUM_CODES
_EMPTY = np.uint8(Code.EMPTY)
_WALL = int(Code.WALL)
_DEER = int(Code.DEER)
_DEER_EASY = np.uint8(Code.DEER_EASY)


def world_dtype(n: int) -> np.dtype:
    """The record type of one n×n world."""
    return np.dtype(
        [
            ("grid", np.uint8, (n, n)),  # object code per cell, indexed [y, x]
            ("age", np.int32, (n, n)),  # steps an object has existed (for withering)
            ("agent", np.int64, (2,)),  # (x, y)
            ("start", np.int64, (2,)),  # the agent's cell at the last reset; (-1, -1) while placing objects
            ("inventory", np.uint8),  # carried code, 0 = empty hands
            ("carried_age", np.int32),
            ("rng", np.uint64),  # SplitMix64 state of this world
            ("episode_step", np.int64),
            ("lifetime_step", np.int64),  # never reset: the clock of shaping schedules
            ("needs_reset", np.bool_),  # episode over; the vector env resets it on the next step
            ("layout_rng", np.uint64),  # the stream's state when the current layout was drawn
            ("replay_layout", np.bool_),  # the next reset redraws the current layout (replay_unsolved)
            ("stage_done", np.uint8, (MAX_STAGES,)),  # subgoals rewarded in the current cycle
            ("pickups", np.int64, (NC,)),  # since the last reset, per code (dispensed materials count)
            ("made", np.int64, (NC,)),  # products made since the last reset, per code
            ("completions", np.int64),  # tasks completed since the last reset
            ("pred", np.int64, (MAX_PREDATORS, 2)),  # predator (x, y)
            ("pred_age", np.int64, (MAX_PREDATORS,)),
        ]
    )


def rules_dtype(n: int) -> np.dtype:
    """The record type of a task's rules on an n×n grid (see the field comments)."""
    return np.dtype(
        [
            ("n", np.int64),
            ("layout", np.uint8, (n, n)),  # fixed cells at every reset: wall ring, inner walls, depot
            ("num_channels", np.int64),
            ("channel", np.int64, (NC,)),  # observation channel of each code, -1 if absent
            ("reset_free", np.bool_),
            ("horizon", np.int64),
            ("reward_mode", np.int64),
            ("shaping", np.float64, (MAX_BREAKPOINTS, 2)),  # (step, strength) breakpoints
            ("num_breakpoints", np.int64),
            ("initial", np.int64, (NC,)),  # objects of each code placed at reset
            ("replenish", np.int64, (NC,)),  # keep at least this many of a group: add one per step if fewer
            ("grow_prob", np.float64, (NC,)),  # per-step probability that one more grows
            ("growth_cap", np.int64),  # no growth while a group already has more than this many
            ("lifespan", np.int64, (NC,)),  # steps until an object withers, 0 = permanent
            ("near_spawn", np.uint8, (NC,)),  # new objects of this group grow in the shaping window
            ("wander_prob", np.float64, (NC,)),  # per-step probability of a random step
            ("wander_moves", np.int64, (NC,)),  # candidates of that step: 4 (N, W, S, E) or 5 (and stay)
            ("creatures_before_hands", np.bool_),  # creatures move before pick-up / place (hunting)
            ("spawn_on_agent", np.bool_),  # new objects may grow under the agent (not on its start cell)
            ("count_carried", np.bool_),  # replenishment counts the carried object too
            ("waypoint_repeats", np.bool_),  # waypoint mode pays every pick-up / product, not once a cycle
            ("replay_unsolved", np.int64),  # episodic: replay an unsolved layout within collections this long
            ("directed", np.int64, (NC,)),  # +1 steps toward the agent, -1 away, 0 never
            ("directed_prob", np.float64, (NC,)),  # probability of that directed step
            ("directed_by_shaping", np.uint8, (NC,)),  # directed probability is the shaping strength
            ("base_deer", np.int64),  # code of newly spawned deer
            ("easy_deer_shaping", np.bool_),  # a fraction s(t) of new deer are easy
            ("recipe", np.uint8, (NC, NC)),  # product of placing carried [row] on object [col]
            ("deliver_item", np.int64),  # placing this item on deliver_target completes the task
            ("deliver_target", np.int64),
            ("goal_pickup", np.int64),  # picking up this code completes the task (0: none)
            ("max_material", np.int64),  # workers dispense only while at most this many of the material are on the grid
            ("num_predators", np.int64),
            ("predator_lifespan", np.int64),
            ("predator_wander_prob", np.float64),
            ("predator_penalty", np.float64),
            ("stage_on_pickup", np.int64, (NC,)),  # subgoal stage reached by picking up a code, -1 none
            ("stage_on_made", np.int64, (NC,)),  # subgoal stage reached by making a code, -1 none
            ("loses_progress_on_drop", np.uint8, (NC,)),
            ("targets", np.int64, (NC, NUM_TARGET_GROUPS)),  # per carried code: code bitmasks, by priority
        ]
    )


def new_rules(n: int) -> np.ndarray:
    """A blank rules record (array of length 1) for an n×n grid: nothing grows, moves or rewards."""
    rules = np.zeros(1, dtype=rules_dtype(n))
    r = rules[0]
    r["n"] = n
    layout = np.zeros((n, n), dtype=np.uint8)
    layout[[0, -1], :] = Code.WALL
    layout[:, [0, -1]] = Code.WALL
    r["layout"] = layout
    r["channel"] = -1
    r["stage_on_pickup"] = -1
    r["stage_on_made"] = -1
    r["growth_cap"] = (n - 2) ** 2 // 8
    r["base_deer"] = Code.DEER
    r["wander_moves"] = 4
    r["spawn_on_agent"] = True
    return rules


def code_mask(*codes: int) -> int:
    """A bitmask over object codes, for the distance reward's target table."""
    mask = 0
    for c in codes:
        mask |= 1 << int(c)
    return mask


# ----------------------------------------------------------------------------------------------- RNG

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)


@nb.njit(cache=True)
def uniform(w) -> float:
    """Next float in [0, 1) from the world's SplitMix64 stream."""
    w.rng = w.rng + _GOLDEN
    z = w.rng
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    z = z ^ (z >> _S31)
    return (z >> _S11) * (1.0 / 9007199254740992.0)


@nb.njit(cache=True)
def randint(w, k: int) -> int:
    """Uniform integer in [0, k)."""
    return min(int(uniform(w) * k), k - 1)


# ------------------------------------------------------------------------------------------ helpers


_schedule_value = nb.njit(cache=True)(schedule_value)
"""`ecology.schedule_value` compiled for the kernels."""


@nb.njit(cache=True)
def shaping_strength(r, t: float) -> float:
    """Shaping strength s(t) of the rules' piecewise-linear schedule at lifetime step t."""
    return _schedule_value(r.shaping[: r.num_breakpoints], t)


@nb.njit(cache=True)
def window_side(n: int, s: float) -> int:
    """Side of the spawn window: the whole grid reach (2n) at strength 0 down to 2 cells at strength 1."""
    return 2 + int((1.0 - s) * (2 * n - 2) + 1e-9)


@nb.njit(cache=True)
def count_codes(w, n: int, out) -> None:
    """Count the objects of each group on the grid into ``out`` (length NC)."""
    out[:] = 0
    for y in range(n):
        for x in range(n):
            out[GROUP[w.grid[y, x]]] += 1


@nb.njit(cache=True)
def count_code(w, n: int, code: int) -> int:
    """Number of cells holding exactly ``code``."""
    total = 0
    for y in range(n):
        for x in range(n):
            if w.grid[y, x] == code:
                total += 1
    return total


@nb.njit(cache=True)
def place_random(w, n: int, code: int, x0: int, y0: int, x1: int, y1: int, ax: int, ay: int) -> bool:
    """Put ``code`` on a uniformly chosen empty cell of [x0, x1) × [y0, y1) other than (ax, ay).

    Returns False (and places nothing) when no such cell exists.
    """
    free = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            if w.grid[y, x] == _EMPTY and not (x == ax and y == ay):
                free += 1
    if free == 0:
        return False
    k = randint(w, free)
    for y in range(y0, y1):
        for x in range(x0, x1):
            if w.grid[y, x] == _EMPTY and not (x == ax and y == ay):
                if k == 0:
                    w.grid[y, x] = code
                    w.age[y, x] = 0
                    return True
                k -= 1
    return False


@nb.njit(cache=True)
def spawn(w, r, group: int, near: bool, s: float) -> bool:
    """Add one object of ``group``: anywhere, or inside the shaping window around the agent if ``near``.

    Never on the agent's start cell (the original's rule, so an object may grow under the agent), or,
    with ``spawn_on_agent`` off, never under the agent.
    """
    n = r.n
    if r.spawn_on_agent:
        ex, ey = w.start[0], w.start[1]
    else:
        ex, ey = w.agent[0], w.agent[1]
    code = group
    if group == _DEER:
        code = r.base_deer
        if r.easy_deer_shaping and uniform(w) < s:
            code = _DEER_EASY
    if not near:
        return place_random(w, n, code, 1, 1, n - 1, n - 1, ex, ey)
    side = window_side(n, s)
    # The window is shifted (not cut) at the walls so that it always covers side × side interior cells.
    x0 = max(1, min(w.agent[0] - side // 2, n - 1 - side))
    y0 = max(1, min(w.agent[1] - side // 2, n - 1 - side))
    return place_random(w, n, code, x0, y0, min(x0 + side, n - 1), min(y0 + side, n - 1), ex, ey)


@nb.njit(cache=True)
def move_object(w, x: int, y: int, nx: int, ny: int) -> None:
    """Move the object at (x, y), with its age, to the empty cell (nx, ny)."""
    w.grid[ny, nx] = w.grid[y, x]
    w.age[ny, nx] = w.age[y, x]
    w.grid[y, x] = _EMPTY
    w.age[y, x] = 0


@nb.njit(cache=True)
def free_cell(w, n: int, x: int, y: int) -> bool:
    """True if (x, y) is an interior cell holding no object (creatures may share the agent's cell)."""
    return 0 < x < n - 1 and 0 < y < n - 1 and w.grid[y, x] == _EMPTY


@nb.njit(cache=True)
def directed_step(w, n: int, x: int, y: int, direction: int):
    """Best of N, W, S, E, stay (free targets only) for moving toward (+1) or away from (-1) the agent."""
    ax, ay = w.agent[0], w.agent[1]
    best_x, best_y = x, y
    best = direction * (abs(x - ax) + abs(y - ay))
    for k in range(4):
        nx, ny = x + STEP_DX[k], y + STEP_DY[k]
        if free_cell(w, n, nx, ny):
            score = direction * (abs(nx - ax) + abs(ny - ay))
            if score < best:
                best, best_x, best_y = score, nx, ny
    return best_x, best_y


@nb.njit(cache=True)
def random_step(w, n: int, x: int, y: int, moves: int):
    """The original's random step: one of the first ``moves`` of N, W, S, E, stay, uniformly, taken only if
    the target is free (a blocked creature stays where it is)."""
    k = randint(w, moves)
    nx, ny = x + STEP_DX[k], y + STEP_DY[k]
    if free_cell(w, n, nx, ny):
        return nx, ny
    return x, y


@nb.njit(cache=True)
def nearest_distance(w, n: int, mask: int) -> int:
    """L1 distance from the agent to the nearest object whose code is in ``mask``; -1 if there is none."""
    ax, ay = w.agent[0], w.agent[1]
    best = -1
    for y in range(n):
        for x in range(n):
            if (mask >> w.grid[y, x]) & 1:
                d = abs(x - ax) + abs(y - ay)
                if best < 0 or d < best:
                    best = d
    return best


# -------------------------------------------------------------------------------------------- phases


@nb.njit(cache=True)
def act(w, r, action: int):
    """Apply the agent's action. Returns the step's events (picked, made, dropped, delivered)."""
    x, y = w.agent[0], w.agent[1]
    picked = made = dropped = 0
    delivered = False
    if action < 4:
        nx, ny = x + DX[action], y + DY[action]
        if PASSABLE[w.grid[ny, nx]]:
            w.agent[0], w.agent[1] = nx, ny
    elif action == PICK_UP:
        c = w.grid[y, x]
        if w.inventory == 0 and PICKABLE[c]:
            w.inventory, w.carried_age = c, w.age[y, x]
            w.grid[y, x], w.age[y, x] = _EMPTY, 0
            w.pickups[c] += 1
            picked = c
    elif action == INTERACT:
        material = DISPENSES[w.grid[y, x]]
        if w.inventory == 0 and material != 0 and count_code(w, r.n, material) <= r.max_material:
            w.inventory, w.carried_age = material, 0
            w.pickups[material] += 1
            picked = material
    elif action == PLACE and w.inventory != 0:
        item, target = w.inventory, w.grid[y, x]
        if target == _EMPTY:
            w.grid[y, x], w.age[y, x] = item, w.carried_age
            w.inventory = 0
            dropped = item
        elif item == r.deliver_item and target == r.deliver_target:
            w.inventory = 0
            delivered = True
        elif r.recipe[item, target] != 0:
            product = r.recipe[item, target]
            w.grid[y, x], w.age[y, x] = product, 0
            w.inventory = 0
            w.made[product] += 1
            made = product
    return picked, made, dropped, delivered


@nb.njit(cache=True)
def move_creatures(w, r, s: float) -> None:
    """Move every grid creature once: a directed step (toward/away from the agent) or a random step."""
    n = r.n
    xs = np.empty(n * n, dtype=np.int64)
    ys = np.empty(n * n, dtype=np.int64)
    count = 0
    for y in range(1, n - 1):
        for x in range(1, n - 1):
            c = w.grid[y, x]
            if r.wander_prob[c] > 0.0 or r.directed[c] != 0:
                xs[count], ys[count] = x, y
                count += 1
    for i in range(count):
        x, y = xs[i], ys[i]
        c = w.grid[y, x]
        p_directed = s if r.directed_by_shaping[c] != 0 else r.directed_prob[c]
        if r.directed[c] != 0 and uniform(w) < p_directed:
            nx, ny = directed_step(w, n, x, y, r.directed[c])
        elif uniform(w) < r.wander_prob[c]:
            nx, ny = random_step(w, n, x, y, r.wander_moves[c])
        else:
            continue
        if nx != x or ny != y:
            move_object(w, x, y, nx, ny)


@nb.njit(cache=True)
def respawn_predator(w, r, i: int) -> None:
    """Put predator i, newborn, on a uniformly chosen non-wall interior cell other than the agent's."""
    n = r.n
    while True:
        x, y = 1 + randint(w, n - 2), 1 + randint(w, n - 2)
        if PASSABLE[w.grid[y, x]] and not (x == w.agent[0] and y == w.agent[1]):
            break
    w.pred[i, 0], w.pred[i, 1], w.pred_age[i] = x, y, 0


@nb.njit(cache=True)
def move_predators(w, r, tx: int, ty: int) -> bool:
    """Predators chase the cell (tx, ty) the agent stood on before its move (greedy L1 step) or, with
    probability p, take a random one of N, W, S, E, stay; they live ``predator_lifespan`` steps and then
    reappear at random. Returns True if one ends the step on the agent's cell."""
    for i in range(r.num_predators):
        x, y = w.pred[i, 0], w.pred[i, 1]
        if uniform(w) < r.predator_wander_prob:
            k = randint(w, 5)  # N, W, S, E or stay, as the original's monsters
            nx, ny = x + STEP_DX[k], y + STEP_DY[k]
        else:
            nx, ny = x, y
            best = abs(x - tx) + abs(y - ty)
            for k in range(4):
                cx, cy = x + STEP_DX[k], y + STEP_DY[k]
                d = abs(cx - tx) + abs(cy - ty)
                if d < best and PASSABLE[w.grid[cy, cx]]:
                    best, nx, ny = d, cx, cy
        if PASSABLE[w.grid[ny, nx]]:
            w.pred[i, 0], w.pred[i, 1] = nx, ny
        w.pred_age[i] += 1
        if w.pred_age[i] >= r.predator_lifespan:
            respawn_predator(w, r, i)
    caught = False
    ax, ay = w.agent[0], w.agent[1]
    for i in range(r.num_predators):
        if w.pred[i, 0] == ax and w.pred[i, 1] == ay:
            caught = True
    return caught


@nb.njit(cache=True)
def grow_resources(w, r, s: float) -> None:
    """Replenish depleted populations (one object per group per step) and grow new ones with their
    per-step probability, inside the shaping window for groups that spawn near the agent. Populations
    are counted on the grid, as in the original (a carried object is not counted unless
    ``count_carried``), so picking up the last lettuce grows a new one at once."""
    counts = np.empty(NC, dtype=np.int64)
    count_codes(w, r.n, counts)
    if r.count_carried and w.inventory != 0:
        counts[GROUP[w.inventory]] += 1
    for g in range(NC):
        keep, p = r.replenish[g], r.grow_prob[g]
        if keep == 0 and p == 0.0:
            continue
        if counts[g] < keep:
            spawn(w, r, g, r.near_spawn[g] != 0, s)
        elif p > 0.0 and counts[g] <= r.growth_cap and uniform(w) < p:
            spawn(w, r, g, r.near_spawn[g] != 0, s)


@nb.njit(cache=True)
def wither(w, r) -> None:
    """Age every mortal object by one step and remove those that reached their lifespan."""
    n = r.n
    for y in range(1, n - 1):
        for x in range(1, n - 1):
            life = r.lifespan[w.grid[y, x]]
            if life > 0:
                w.age[y, x] += 1
                if w.age[y, x] >= life:
                    w.grid[y, x], w.age[y, x] = _EMPTY, 0


@nb.njit(cache=True)
def task_reward(w, r, picked: int, made: int, dropped: int, solved: bool) -> float:
    """Reward of the task under the rules' reward mode (completion is +100 in every mode)."""
    if solved:
        w.stage_done[:] = 0
        return TASK_REWARD
    if r.reward_mode == SPARSE:
        return 0.0
    stage = -1
    if picked != 0:
        stage = r.stage_on_pickup[picked]
    if made != 0:
        stage = max(stage, r.stage_on_made[made])
    if stage >= 0 and r.reward_mode == WAYPOINT and r.waypoint_repeats:
        return SUBGOAL_REWARD  # the original's waypoint reward: every pick-up and product pays, farmable
    if stage >= 0 and w.stage_done[stage] == 0:
        w.stage_done[stage] = 1
        return SUBGOAL_REWARD
    penalised = r.reward_mode == ONE_TIME or r.reward_mode == DISTANCE
    if penalised and dropped != 0 and r.loses_progress_on_drop[dropped] != 0:
        return LOST_PROGRESS_PENALTY
    if r.reward_mode == DISTANCE:
        for k in range(NUM_TARGET_GROUPS):
            mask = r.targets[w.inventory, k]
            if mask != 0:
                d = nearest_distance(w, r.n, mask)
                if d >= 0:
                    return -DISTANCE_COEF * d
    return 0.0


@nb.njit(cache=True)
def observe(w, r, obs) -> None:
    """Write the observation: the 5×5 north-up view one-hot per channel (index c·25 + row·5 + col),
    predators overlaid on their channel, then the one-hot inventory (all zeros when empty-handed)."""
    n = r.n
    obs[:] = 0.0
    ax, ay = w.agent[0], w.agent[1]
    wall = r.channel[_WALL]
    half = VIEW // 2
    for vy in range(VIEW):
        gy = ay - half + vy
        for vx in range(VIEW):
            gx = ax - half + vx
            if 0 <= gx < n and 0 <= gy < n:
                ch = r.channel[w.grid[gy, gx]]
            else:
                ch = wall
            obs[ch * VIEW_CELLS + vy * VIEW + vx] = 1.0
    pch = r.channel[Code.PREDATOR]
    for i in range(r.num_predators):
        vx, vy = w.pred[i, 0] - ax + half, w.pred[i, 1] - ay + half
        if 0 <= vx < VIEW and 0 <= vy < VIEW:
            obs[pch * VIEW_CELLS + vy * VIEW + vx] = 1.0
    if w.inventory != 0:
        obs[r.num_channels * VIEW_CELLS + r.channel[w.inventory]] = 1.0


# ------------------------------------------------------------------------------------ world lifecycle


@nb.njit(cache=True)
def reset_world(w, r, obs) -> None:
    """Start a new episode: the fixed layout, the initial objects anywhere, then the agent on a random
    empty cell, then the predators. The RNG stream and the lifetime clock carry on."""
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
        respawn_predator(w, r, i)
    observe(w, r, obs)


@nb.njit(cache=True)
def step_world(w, r, action: int, obs):
    """One step of one world. Returns (reward, terminated, truncated, solved, caught)."""
    s = shaping_strength(r, w.lifetime_step)
    start_x, start_y = w.agent[0], w.agent[1]
    creatures_first = r.creatures_before_hands and action >= PICK_UP
    if creatures_first:
        move_creatures(w, r, s)
    picked, made, dropped, delivered = act(w, r, action)
    solved = delivered or (picked != 0 and picked == r.goal_pickup)
    if solved:
        w.completions += 1
        if r.reset_free and not delivered:
            w.inventory = 0  # the world goes on: the completed task's object is consumed (and regrows)
    if not creatures_first:
        move_creatures(w, r, s)
    caught = move_predators(w, r, start_x, start_y) if r.num_predators > 0 else False
    grow_resources(w, r, s)
    wither(w, r)
    reward = task_reward(w, r, picked, made, dropped, solved)
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
    of the episode that just ended unsolved, redrawn from the same point of the world's stream."""
    if r.replay_unsolved > 0 and w.replay_layout:
        w.rng = w.layout_rng
    else:
        w.layout_rng = w.rng
    w.replay_layout = False
    reset_world(w, r, obs)


@nb.njit(cache=True)
def step_worlds(state, rules, actions, obs, rewards, terminated, truncated, solved, caught, autoreset):
    """Step every world of ``state`` with its action, writing observations and outcomes in place.

    With ``autoreset`` a world whose episode ended on the previous call is reset instead of stepped
    (Gymnasium's next-step autoreset): its reward is 0 and it is neither terminated nor truncated.
    """
    r = rules[0]
    for b in range(state.shape[0]):
        w = state[b]
        if autoreset and w.needs_reset:
            begin_episode(w, r, obs[b])
            rewards[b], terminated[b], truncated[b], solved[b], caught[b] = 0.0, False, False, False, False
            continue
        rew, term, trunc, solv, cau = step_world(w, r, actions[b], obs[b])
        rewards[b], terminated[b], truncated[b], solved[b], caught[b] = rew, term, trunc, solv, cau
        w.needs_reset = term or trunc


@nb.njit(cache=True)
def reset_worlds(state, rules, mask, obs) -> None:
    """Reset the worlds selected by ``mask`` (their RNG streams carry on; see `begin_episode`)."""
    r = rules[0]
    for b in range(state.shape[0]):
        if mask[b]:
            begin_episode(state[b], r, obs[b])
