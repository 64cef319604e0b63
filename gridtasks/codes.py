"""Object codes shared by every grid task, and the lookup tables indexed by code.

A grid cell holds one small integer code. Properties of a code live in tables (``PASSABLE[code]``), never in
per-cell objects. Predators are not grid objects (they share cells with food); they have a code only so
that observations and renderings can name them.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Code(IntEnum):
    """Every object that can stand on a grid cell (plus PREDATOR, which is drawn over cells)."""

    EMPTY = 0
    WALL = 1
    LETTUCE = 2
    CARROT = 3
    SALAD = 4
    AXE = 5
    DEER = 6  # wanders only by dynamism
    DEER_EASY = 7  # steps toward the agent with probability deer_speed
    DEER_HARD = 8  # steps away from the agent with probability deer_speed
    FOOD = 9
    METAL = 10
    WOOD = 11
    METAL_WORKER = 12
    WOOD_WORKER = 13
    DEPOT = 14
    PREDATOR = 15


NUM_CODES = len(Code)

NAMES = tuple(c.name.lower() for c in Code)
"""Lower-case name per code, used in info keys (``pickup_lettuce``) and docs."""

PASSABLE = np.ones(NUM_CODES, dtype=np.bool_)
"""Whether the agent can step onto a cell holding this code (everything but walls)."""
PASSABLE[Code.WALL] = False

PICKABLE = np.zeros(NUM_CODES, dtype=np.bool_)
"""Whether ``pick up`` moves this object into the agent's (single-slot) inventory."""
PICKABLE[[Code.LETTUCE, Code.CARROT, Code.SALAD, Code.AXE, Code.FOOD, Code.METAL, Code.WOOD]] = True

DISPENSES = np.zeros(NUM_CODES, dtype=np.uint8)
"""The material a worker hands to an empty-handed agent that interacts with it (0: not a worker)."""
DISPENSES[Code.METAL_WORKER] = Code.METAL
DISPENSES[Code.WOOD_WORKER] = Code.WOOD

GROUP = np.arange(NUM_CODES, dtype=np.uint8)
"""The population a code counts toward when populations are replenished (all deer kinds count as deer)."""
GROUP[[Code.DEER_EASY, Code.DEER_HARD]] = Code.DEER

COLORS = np.array(
    [
        (236, 236, 236),  # empty
        (70, 70, 78),  # wall
        (96, 186, 70),  # lettuce
        (240, 140, 40),  # carrot
        (170, 220, 90),  # salad
        (150, 110, 70),  # axe
        (150, 100, 60),  # deer
        (200, 150, 100),  # easy deer
        (110, 70, 40),  # hard deer
        (220, 60, 90),  # food
        (150, 160, 175),  # metal
        (180, 130, 80),  # wood
        (90, 110, 160),  # metal worker
        (130, 90, 50),  # wood worker
        (230, 80, 40),  # depot
        (200, 30, 30),  # predator
    ],
    dtype=np.uint8,
)
"""RGB colour per code for rendering."""

LABELS = ("", "", "L", "C", "S", "A", "D", "De", "Dh", "F", "M", "W", "MW", "WW", "X", "P")
"""Short text drawn on a cell holding each code."""
