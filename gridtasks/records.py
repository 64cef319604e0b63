"""The grid engine's data: one world as a numpy record, the rules of a task as one record of lookup tables.

One world is one record of ``world_dtype(n)`` (grid codes, ages, agent, inventory, counters, its own RNG);
a batch of worlds is an array of such records. The rules of a task are one record of ``rules_dtype(n)``:
every task-specific behaviour is a table indexed by object code, filled in by the task's module.
"""

from __future__ import annotations

import hashlib

import numpy as np
from numba.core import types as nb_types

from gridtasks.codes import NUM_CODES, Code


def _stable_record_mangling(self) -> tuple:
    """Mangle a numpy record type by a digest of its layout, not by numba's per-process type counter.

    numba names a compiled kernel after its argument types, and names a record type by a counter that
    each process starts afresh. Kernels cached by two processes for two grid sizes (two record types) can
    then carry the same symbol name, and a third process that loads both crashes inside LLVM
    ("Didn't find key?", "free(): invalid pointer"). A digest of the record's layout is the same in every
    process and differs between layouts.
    """
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
RESPAWN_ORIGINAL, RESPAWN_OFF_AGENT = range(2)
PREDATOR_RESPAWN_IDS = {"original": RESPAWN_ORIGINAL, "off-agent": RESPAWN_OFF_AGENT}
"""How dead predators come back (`ScavengingConfig.predator_respawn`)."""
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
            ("shifted_window", np.bool_),  # the spawn window is shifted inside the wall ring (not clipped)
            ("waypoint_repeats", np.bool_),  # waypoint mode pays every pick-up / product, not once a cycle
            ("replay_unsolved", np.int64),  # episodic: replay an unsolved layout within collections this long
            ("directed", np.int64, (NC,)),  # +1 steps toward the agent, -1 away, 0 never
            ("directed_prob", np.float64, (NC,)),  # probability of that directed step
            ("directed_by_shaping", np.uint8, (NC,)),  # directed probability is the shaping strength
            ("aim_before_move", np.uint8, (NC,)),  # a directed step aims at the agent's cell before its move
            ("blocked_directed_stays", np.bool_),  # the original: the best step, taken only if its cell is free
            ("base_deer", np.int64),  # code of newly spawned deer
            ("easy_deer_shaping", np.bool_),  # a fraction s(t) of new deer are easy
            ("recipe", np.uint8, (NC, NC)),  # product of placing carried [row] on object [col]
            ("deliver_item", np.int64),  # placing this item on deliver_target completes the task
            ("deliver_target", np.int64),
            ("goal_pickup", np.int64),  # picking up this code completes the task (0: none)
            ("goal_made", np.int64),  # making this code completes the task (0: none); reset-free, it is used up
            ("max_material", np.int64),  # workers dispense only while at most this many of the material are on the grid
            ("num_predators", np.int64),
            ("predator_lifespan", np.int64),
            ("predator_wander_prob", np.float64),
            ("predator_penalty", np.float64),
            ("predator_respawn", np.int64),  # RESPAWN_ORIGINAL or RESPAWN_OFF_AGENT
            ("stage_on_pickup", np.int64, (NC,)),  # subgoal stage reached by picking up a code, -1 none
            ("stage_on_made", np.int64, (NC,)),  # subgoal stage reached by making a code, -1 none
            ("stage_on_placed", np.int64, (NC,)),  # stage reached by combining the carried item onto a code, -1 none
            ("stage_reward", np.float64, (MAX_STAGES,)),  # reward of reaching each stage (subgoal modes)
            ("completion_reward", np.float64),  # reward of completing the task (every mode)
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
    r["stage_on_placed"] = -1
    r["stage_reward"] = SUBGOAL_REWARD
    r["completion_reward"] = TASK_REWARD
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


MAX_COUNT = 2**62
"""Largest step or event count a world may hold (the engine adds to them without overflow checks)."""
MAX_AGE = 2**30
"""Largest object age a restored world may hold (ages are 32-bit)."""


def _refuse(index: int, what: str) -> ValueError:
    return ValueError(f"world {index} of the saved state is impossible for this task: {what}")


def check_worlds(worlds: np.ndarray, rules: np.ndarray, headroom: int = 0) -> None:
    """Raise ValueError (one line) unless every record of ``worlds`` is a state this task's engine can reach.

    The compiled kernels index arrays by these values without bounds checks, so a state read from a file
    must pass here before it is stepped: positions inside the wall ring, cell and inventory codes the
    task observes, the walls where the task's layout has them, counters and ages not negative, flags 0/1.
    Step and event counters must leave ``headroom`` below `MAX_COUNT`: each grows by at most one per step, so
    a caller that passes the steps a run may still take keeps every later state it saves acceptable too.
    """
    r = rules[0] if rules.ndim else rules
    n = int(r["n"])
    if worlds.dtype != world_dtype(n):
        raise ValueError(f"the saved worlds are not {n}x{n} worlds of this task")
    observed = np.asarray(r["channel"]) >= 0
    cell_ok = observed.copy()
    cell_ok[Code.PREDATOR] = False
    carry_ok = cell_ok.copy()
    carry_ok[[Code.EMPTY, Code.WALL]] = False
    carry_ok[Code.EMPTY] = True  # 0 = empty hands
    walls = np.asarray(r["layout"]) == Code.WALL
    for i, w in enumerate(worlds):
        _check_one(i, w, r, n, cell_ok, carry_ok, walls, MAX_COUNT - max(0, int(headroom)))


def _inside(xy: np.ndarray, n: int) -> bool:
    """True if (x, y) lies strictly inside the wall ring of an n×n grid."""
    return bool(np.all((1 <= xy) & (xy <= n - 2)))


def _check_one(i: int, w: np.void, r: np.void, n: int, cell_ok: np.ndarray, carry_ok: np.ndarray,
               walls: np.ndarray, max_count: int) -> None:
    """`check_worlds` for world ``i``."""
    grid = w["grid"]
    bad = grid[~cell_ok[np.minimum(grid, NC - 1)] | (grid >= NC)]
    if bad.size:
        raise _refuse(i, f"cell code {int(bad[0])} is not one of this task's objects")
    if not np.array_equal(grid == Code.WALL, walls):
        raise _refuse(i, "its walls differ from the task's layout")
    if not _inside(w["agent"], n) or grid[w["agent"][1], w["agent"][0]] == Code.WALL:
        raise _refuse(i, f"agent at {tuple(int(v) for v in w['agent'])} is not on a free cell of the {n}x{n} grid")
    start = w["start"]
    if not (np.all(start == -1) or np.all((0 <= start) & (start < n))):
        raise _refuse(i, f"start cell {tuple(int(v) for v in start)} is off the grid")
    inventory = int(w["inventory"])
    if inventory >= NC or not carry_ok[inventory]:
        raise _refuse(i, f"inventory code {inventory} is not an object of this task that can be carried")
    for name in ("age", "carried_age", "episode_step", "lifetime_step", "pickups", "made", "completions",
                 "pred_age"):
        high = MAX_AGE if name in ("age", "carried_age") else max_count
        if np.any(w[name] < 0) or np.any(w[name] > high):
            raise _refuse(i, f"{name} lies outside [0, {high}]")
    for name in ("needs_reset", "replay_layout", "stage_done"):
        if np.any(np.asarray(w[name]).view(np.uint8) > 1):
            raise _refuse(i, f"{name} is not 0 or 1")
    for k in range(int(r["num_predators"])):
        if not _inside(w["pred"][k], n):
            raise _refuse(i, f"predator {k} at {tuple(int(v) for v in w['pred'][k])} is off the grid")
