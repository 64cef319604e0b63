"""Drawing a grid world with OpenCV: cells by palette, the agent, predators, the 5×5 view, the inventory."""

from __future__ import annotations

import cv2
import numpy as np

from gridtasks.codes import COLORS, LABELS, NAMES, Code
from gridtasks.engine import VIEW

TILE = 48
"""Pixels per grid cell."""
PANEL = 40
"""Height of the status strip under the grid."""
AGENT_COLOR = (40, 90, 220)
VIEW_SHADE = 0.18


def render_world(world: np.void, rules: np.void, channels=(), tile: int = TILE) -> np.ndarray:
    """An RGB uint8 frame of one world: the grid, the agent's 5×5 view brightened, predators, and a strip
    showing the carried object, the lifetime step and the completions.
    """
    grid = world["grid"]
    n = grid.shape[0]
    cells = COLORS[grid]  # (n, n, 3), a copy: shaded per cell, then scaled up to pixels
    _shade_outside_view(cells, world["agent"], n)
    frame = np.repeat(np.repeat(cells, tile, axis=0), tile, axis=1)
    _draw_grid_lines(frame, n, tile)
    _draw_labels(frame, grid, tile)
    for i in range(int(rules["num_predators"])):
        if world["pred_age"][i] < rules["predator_lifespan"]:  # a dead one waits, unseen, to be reborn
            _draw_predator(frame, world["pred"][i], tile)
    ax, ay = (int(v) for v in world["agent"])
    centre = (ax * tile + tile // 2, ay * tile + tile // 2)
    cv2.circle(frame, centre, tile // 3, AGENT_COLOR, -1, cv2.LINE_AA)
    cv2.circle(frame, centre, tile // 3, (255, 255, 255), 2, cv2.LINE_AA)
    return np.concatenate([frame, _status_strip(world, n * tile)], axis=0)


def _shade_outside_view(cells: np.ndarray, agent, n: int) -> None:
    """Darken (in place) the cell colours (n, n, 3) outside the agent's view."""
    half = VIEW // 2
    mask = np.ones(cells.shape[:2], dtype=bool)
    x0, y0 = max(int(agent[0]) - half, 0), max(int(agent[1]) - half, 0)
    x1, y1 = min(int(agent[0]) + half + 1, n), min(int(agent[1]) + half + 1, n)
    mask[y0:y1, x0:x1] = False
    cells[mask] = (cells[mask] * (1 - VIEW_SHADE * 2.5)).astype(np.uint8)


def _draw_grid_lines(frame: np.ndarray, n: int, tile: int) -> None:
    for k in range(n + 1):
        cv2.line(frame, (k * tile, 0), (k * tile, n * tile), (120, 120, 120), 1)
        cv2.line(frame, (0, k * tile), (n * tile, k * tile), (120, 120, 120), 1)


def _draw_labels(frame: np.ndarray, grid: np.ndarray, tile: int) -> None:
    for y, x in zip(*np.nonzero(grid > Code.WALL)):
        label = LABELS[grid[y, x]]
        size = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1)[0]
        org = (x * tile + (tile - size[0]) // 2, y * tile + (tile + size[1]) // 2)
        cv2.putText(frame, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.5, (20, 20, 20), 1, cv2.LINE_AA)


def _draw_predator(frame: np.ndarray, pos, tile: int) -> None:
    x, y = int(pos[0]) * tile, int(pos[1]) * tile
    pts = np.array([(x + tile // 2, y + 4), (x + 4, y + tile - 4), (x + tile - 4, y + tile - 4)], np.int32)
    cv2.fillPoly(frame, [pts], tuple(int(c) for c in COLORS[Code.PREDATOR]), cv2.LINE_AA)


def _status_strip(world: np.void, width: int) -> np.ndarray:
    strip = np.full((PANEL, width, 3), 250, dtype=np.uint8)
    item = int(world["inventory"])
    cv2.rectangle(strip, (6, 6), (PANEL - 6, PANEL - 6), tuple(int(c) for c in COLORS[item]), -1)
    cv2.rectangle(strip, (6, 6), (PANEL - 6, PANEL - 6), (60, 60, 60), 1)
    text = f"holding: {NAMES[item] if item else '-'}   t={int(world['lifetime_step'])}   " \
           f"done={int(world['completions'])}"
    cv2.putText(strip, text, (PANEL + 4, PANEL // 2 + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (30, 30, 30), 1,
                cv2.LINE_AA)
    return strip
