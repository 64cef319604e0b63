"""Hand-drawn worlds for the grid-rule tests.

A world is drawn as an ASCII map, one character per cell, row 0 at the top (north), column 0 at the left
(west); cell (x, y) is row y, column x, as in the engine (``grid[y, x]``, ``agent = (x, y)``)::

    #######
    #.L.C.#
    #..@..#
    #.....#
    #######

Symbols (see ``SYMBOLS``): ``#`` wall, ``.`` empty, ``@`` the agent on an empty cell, ``P`` a predator on an
empty cell, ``L`` lettuce, ``C`` carrot, ``S`` salad, ``A`` axe, ``D`` (wander) deer, ``E`` easy deer,
``H`` hard deer, ``F`` food, ``M`` metal, ``W`` wood, ``m`` metal worker, ``w`` wood worker, ``X`` depot.
An agent (or predator) standing on an object is given separately: ``agent=(x, y)``, ``predators=[...]``.

Usage: build the env with a ``grid_size`` equal to the map's side, ``env.reset(seed=0)`` (``make`` does
both), overwrite the world with ``world_from_map``, then ``env.step(action)`` and compare with
``assert_map``, which prints both maps on a mismatch.
"""

from __future__ import annotations

import textwrap

import numpy as np

from gridtasks.codes import Code

SYMBOLS: dict[str, int] = {
    "#": Code.WALL,
    ".": Code.EMPTY,
    "@": Code.EMPTY,
    "P": Code.EMPTY,
    "L": Code.LETTUCE,
    "C": Code.CARROT,
    "S": Code.SALAD,
    "A": Code.AXE,
    "D": Code.DEER,
    "E": Code.DEER_EASY,
    "H": Code.DEER_HARD,
    "F": Code.FOOD,
    "M": Code.METAL,
    "W": Code.WOOD,
    "m": Code.METAL_WORKER,
    "w": Code.WOOD_WORKER,
    "X": Code.DEPOT,
}
"""Map character -> object code of the cell."""

CHARS: dict[int, str] = {int(code): ch for ch, code in SYMBOLS.items() if ch not in "@P"}
"""Object code -> map character (the inverse of ``SYMBOLS``, without the agent and predator marks)."""


def make(cls, grid_size: int, seed: int = 0, **kwargs):
    """An env of task class ``cls`` on a ``grid_size`` grid, already reset with ``seed``."""
    env = cls(grid_size=grid_size, **kwargs)
    env.reset(seed=seed)
    return env


def parse_map(text: str) -> tuple[np.ndarray, tuple[int, int] | None, list[tuple[int, int]]]:
    """(grid codes indexed [y, x], the agent's '@' cell or None, the predators' 'P' cells) of a map."""
    lines = [line.strip() for line in textwrap.dedent(text).strip("\n").splitlines() if line.strip()]
    n = len(lines)
    if any(len(line) != n for line in lines):
        raise ValueError(f"map must be square, got rows of lengths {[len(line) for line in lines]}")
    grid = np.zeros((n, n), dtype=np.uint8)
    agent, predators = None, []
    for y, line in enumerate(lines):
        for x, ch in enumerate(line):
            if ch not in SYMBOLS:
                raise ValueError(f"unknown map symbol {ch!r} at (x={x}, y={y})")
            grid[y, x] = SYMBOLS[ch]
            if ch == "@":
                if agent is not None:
                    raise ValueError("map has more than one '@'")
                agent = (x, y)
            elif ch == "P":
                predators.append((x, y))
    return grid, agent, predators


def world_from_map(env, text: str, agent: tuple[int, int] | None = None, inventory: int = 0,
                   predators: list[tuple[int, int]] | None = None, ages: dict | None = None,
                   pred_ages: list[int] | None = None, start: tuple[int, int] = (-1, -1)):
    """Overwrite the live world of ``env`` with the drawn map and return the world record.

    ``agent``: the agent's (x, y) when it stands on an object (otherwise mark it '@'). ``inventory``: the
    carried code. ``predators``: (x, y) per predator (in addition to 'P' marks); a task with predators
    needs every one of them placed. ``ages``: {(x, y): age} of objects (others get age 0). ``start``: the
    agent's start cell, where nothing grows (default: none).
    """
    u = env.unwrapped
    world = u.world
    grid, at, marked = parse_map(text)
    n = u.config.grid_size
    if grid.shape != (n, n):
        raise ValueError(f"map is {grid.shape[0]}x{grid.shape[1]} but the env's grid_size is {n}")
    if (at is None) == (agent is None):
        raise ValueError("give the agent exactly once: an '@' on the map or agent=(x, y)")
    agent = at if agent is None else agent
    world["grid"][:, :] = grid
    world["age"][:, :] = 0
    for (x, y), age in (ages or {}).items():
        world["age"][y, x] = age
    world["agent"][:] = agent
    world["start"][:] = start
    world["inventory"] = inventory
    world["carried_age"] = 0
    preds = marked + list(predators or [])
    num = int(u.rules[0]["num_predators"])
    if len(preds) != num:
        raise ValueError(f"the env has {num} predators but the map places {len(preds)}")
    for i, (x, y) in enumerate(preds):
        world["pred"][i] = (x, y)
        world["pred_age"][i] = 0 if pred_ages is None else pred_ages[i]
    return world


def map_of(world, predators: int = 0) -> str:
    """The world's grid as a map string ('@' where the agent stands on an empty cell, 'P' for the first
    ``predators`` predators on empty cells), plus a line naming the agent's cell and inventory.
    """
    grid = world["grid"]
    rows = [[CHARS.get(int(c), "?") for c in row] for row in grid]
    for i in range(predators):
        x, y = (int(v) for v in world["pred"][i])
        if grid[y, x] == Code.EMPTY:
            rows[y][x] = "P"
    ax, ay = (int(v) for v in world["agent"])
    if grid[ay, ax] == Code.EMPTY:
        rows[ay][ax] = "@"
    inv = int(world["inventory"])
    tail = f"agent=({ax}, {ay}) on {Code(int(grid[ay, ax])).name}, carrying {Code(inv).name if inv else 'nothing'}"
    return "\n".join("".join(r) for r in rows) + "\n" + tail


def assert_map(world, expected: str, agent: tuple[int, int] | None = None) -> None:
    """Assert the world's grid equals the drawn map and the agent stands at its '@' (or ``agent``)."""
    grid, at, _ = parse_map(expected)
    agent = at if agent is None else agent
    actual_agent = tuple(int(v) for v in world["agent"])
    ok = np.array_equal(world["grid"], grid) and (agent is None or actual_agent == tuple(agent))
    if not ok:
        want = textwrap.dedent(expected).strip("\n")
        raise AssertionError(f"world differs from the expected map\nexpected:\n{want}\n(agent {agent})\n"
                             f"actual:\n{map_of(world)}")


def cells(world, *codes: int) -> list[tuple[int, int]]:
    """(x, y) cells holding any of ``codes``, in row-major order."""
    ys, xs = np.nonzero(np.isin(world["grid"], [int(c) for c in codes]))
    return [(int(x), int(y)) for x, y in zip(xs, ys)]
