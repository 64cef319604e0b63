"""The phases of a grid step, each a compiled function of (world, rules): act, move creatures and predators,
grow and wither resources, reward, observe (their order is `gridtasks.engine.step_world`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from gridtasks.cells import (
    count_code,
    count_codes,
    directed_step,
    move_object,
    nearest_distance,
    randint,
    random_step,
    spawn,
    uniform,
)
from gridtasks.codes import (
    DISPENSES,
    GROUP,
    PASSABLE,
    PICKABLE,
    Code,
)
from gridtasks.records import (
    _EMPTY,
    _WALL,
    DISTANCE,
    DISTANCE_COEF,
    DX,
    DY,
    INTERACT,
    LOST_PROGRESS_PENALTY,
    NC,
    NUM_TARGET_GROUPS,
    ONE_TIME,
    PICK_UP,
    PLACE,
    RESPAWN_ORIGINAL,
    SPARSE,
    STEP_DX,
    STEP_DY,
    VIEW,
    VIEW_CELLS,
    WAYPOINT,
)

# -------------------------------------------------------------------------------------------- phases


@nb.njit(cache=True)
def act(w, r, action: int):
    """Apply the agent's action. Returns the step's events (picked, made, placed_on, dropped, delivered):
    ``placed_on`` is the object a carried item was combined with (the recipe's second ingredient).
    """
    x, y = w.agent[0], w.agent[1]
    picked = made = placed_on = dropped = 0
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
            made, placed_on = product, target
    return picked, made, placed_on, dropped, delivered


@nb.njit(cache=True)
def move_creatures(w, r, s: float, before_x: int, before_y: int) -> None:
    """Move every grid creature once: a directed step (toward/away from the agent's cell, after its move or,
    where ``aim_before_move``, before it: (before_x, before_y)) or a random step.
    """
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
            before = r.aim_before_move[c] != 0
            ax, ay = (before_x, before_y) if before else (w.agent[0], w.agent[1])
            nx, ny = directed_step(w, n, x, y, r.directed[c], ax, ay, r.blocked_directed_stays)
        elif uniform(w) < r.wander_prob[c]:
            nx, ny = random_step(w, n, x, y, r.wander_moves[c])
        else:
            continue
        if nx != x or ny != y:
            move_object(w, x, y, nx, ny)


@nb.njit(cache=True)
def respawn_predator(w, r, i: int, at_reset: bool = False) -> None:
    """Put predator i, newborn, on a uniformly chosen interior cell: under the original rule one holding no
    object, other than the agent's start cell (so possibly the agent's own; at a reset any, as the original places
    its monsters before the agent); under ``off-agent`` any non-wall cell other than the agent's.
    """
    n = r.n
    original = r.predator_respawn == RESPAWN_ORIGINAL
    while True:
        x, y = 1 + randint(w, n - 2), 1 + randint(w, n - 2)
        if original:
            if w.grid[y, x] == _EMPTY and (at_reset or not (x == w.start[0] and y == w.start[1])):
                break
        elif PASSABLE[w.grid[y, x]] and not (x == w.agent[0] and y == w.agent[1]):
            break
    w.pred[i, 0], w.pred[i, 1], w.pred_age[i] = x, y, 0


@nb.njit(cache=True)
def predator_alive(w, r, i: int) -> bool:
    """Predator i has lived fewer than ``predator_lifespan`` steps (a dead one waits in place, unseen and
    harmless, for `replenish_predators`).
    """
    return w.pred_age[i] < r.predator_lifespan


@nb.njit(cache=True)
def move_predators(w, r, tx: int, ty: int) -> None:
    """Live predators chase the cell (tx, ty) the agent stood on before its move (greedy L1 step) or, with
    probability p, take a random one of N, W, S, E, stay. After ``predator_lifespan`` steps a predator dies:
    under ``off-agent`` it is reborn at once; under the original rule `replenish_predators` brings it back.
    """
    for i in range(r.num_predators):
        if not predator_alive(w, r, i):
            continue
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
        if not predator_alive(w, r, i) and r.predator_respawn != RESPAWN_ORIGINAL:
            respawn_predator(w, r, i)


@nb.njit(cache=True)
def replenish_predators(w, r) -> None:
    """The original rule's replenishment, after the resources grew: one dead predator (the first) is reborn
    per step, so two that die on the same step come back a step apart.
    """
    if r.predator_respawn != RESPAWN_ORIGINAL:
        return
    for i in range(r.num_predators):
        if not predator_alive(w, r, i):
            respawn_predator(w, r, i)
            return


@nb.njit(cache=True)
def predator_caught(w, r) -> bool:
    """A live predator ends the step on the agent's cell (a newborn there included)."""
    for i in range(r.num_predators):
        if predator_alive(w, r, i) and w.pred[i, 0] == w.agent[0] and w.pred[i, 1] == w.agent[1]:
            return True
    return False


@nb.njit(cache=True)
def grow_resources(w, r, s: float) -> None:
    """Replenish depleted populations (one object per group per step) and grow new ones with their
    per-step probability, inside the shaping window for groups that spawn near the agent. Populations
    are counted on the grid, as in the original (a carried object is not counted unless
    ``count_carried``), so picking up the last lettuce grows a new one at once.
    """
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
def task_reward(w, r, picked: int, made: int, placed_on: int, dropped: int, solved: bool) -> float:
    """Reward of the task under the rules' reward mode: ``completion_reward`` (+100 unless a task's ladder says
    otherwise) in every mode, and in the subgoal modes the ``stage_reward`` of the furthest stage this step reached.
    """
    if solved:
        w.stage_done[:] = 0
        return r.completion_reward
    if r.reward_mode == SPARSE:
        return 0.0
    stage = -1
    if picked != 0:
        stage = r.stage_on_pickup[picked]
    if made != 0:
        stage = max(stage, r.stage_on_made[made], r.stage_on_placed[placed_on])
    if stage >= 0 and r.reward_mode == WAYPOINT and r.waypoint_repeats:
        return r.stage_reward[stage]  # the original's waypoint reward: every pick-up and product pays, farmable
    if stage >= 0 and w.stage_done[stage] == 0:
        w.stage_done[stage] = 1
        return r.stage_reward[stage]
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
    predators overlaid on their channel, then the one-hot inventory (all zeros when empty-handed).
    """
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
        if not predator_alive(w, r, i):
            continue
        vx, vy = w.pred[i, 0] - ax + half, w.pred[i, 1] - ay + half
        if 0 <= vx < VIEW and 0 <= vy < VIEW:
            obs[pch * VIEW_CELLS + vy * VIEW + vx] = 1.0
    if w.inventory != 0:
        obs[r.num_channels * VIEW_CELLS + r.channel[w.inventory]] = 1.0
