"""The grid engine's small compiled helpers: each world's random stream, the shaping strength, cells and moves."""

from __future__ import annotations

import numba as nb
import numpy as np

from ecology import schedule_value
from gridtasks.codes import GROUP
from gridtasks.records import (
    _DEER,
    _DEER_EASY,
    _EMPTY,
    STEP_DX,
    STEP_DY,
)

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
    """Add one object of ``group``: anywhere, or inside the shaping window around the agent if ``near``
    (``r.shifted_window``: `SpawnRules.spawn_window`).

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
    if r.shifted_window:  # moved inside the wall ring: always side × side interior cells
        x0 = max(1, min(w.agent[0] - side // 2, n - 1 - side))
        y0 = max(1, min(w.agent[1] - side // 2, n - 1 - side))
    else:  # the original's: clipped at the grid's edge, its walls taking nothing (in a corner, at side 2, one cell)
        x0 = max(0, w.agent[0] - side // 2)
        y0 = max(0, w.agent[1] - side // 2)
    return place_random(w, n, code, max(x0, 1), max(y0, 1), min(x0 + side, n - 1), min(y0 + side, n - 1), ex, ey)


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
def directed_step(w, n: int, x: int, y: int, direction: int, ax: int, ay: int, blocked_stays: bool):
    """The step toward (+1) or away from (-1) the cell (ax, ay): the first best of N, W, S, E, stay. With
    ``blocked_stays`` (the original's rule) every interior step competes and a best step onto an object is not
    taken (the creature stays); otherwise only free cells compete.
    """
    best_x, best_y = x, y
    best = direction * (abs(x - ax) + abs(y - ay))
    for k in range(4):
        nx, ny = x + STEP_DX[k], y + STEP_DY[k]
        inside = 0 < nx < n - 1 and 0 < ny < n - 1  # the original clips a step into the wall: a stay
        if inside if blocked_stays else free_cell(w, n, nx, ny):
            score = direction * (abs(nx - ax) + abs(ny - ay))
            if score < best:
                best, best_x, best_y = score, nx, ny
    if blocked_stays and (best_x != x or best_y != y) and not free_cell(w, n, best_x, best_y):
        return x, y
    return best_x, best_y


@nb.njit(cache=True)
def random_step(w, n: int, x: int, y: int, moves: int):
    """The original's random step: one of the first ``moves`` of N, W, S, E, stay, uniformly, taken only if
    the target is free (a blocked creature stays where it is).
    """
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
