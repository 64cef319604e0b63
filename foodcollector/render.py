"""Top-down RGB frames of the arena drawn with OpenCV: walls, spheres, the agent, its heading and rays."""

from __future__ import annotations

import math

import cv2
import numpy as np

from foodcollector.arena import FRACTION_SLOT, MISS_SLOT, NUM_TAGS, RAY_VALUES, Tag
from foodcollector.params import RAY_ANGLES_DEG, FoodCollectorParams

FRAME_SIZE = 512  # pixels, square
MARGIN = 16  # pixels of wall drawn around the arena

BACKGROUND = (236, 232, 220)  # RGB floor
WALL = (70, 70, 80)
GREEN = (40, 170, 60)
RED = (210, 50, 50)
AGENT = (120, 60, 200)
HEADING = (255, 255, 255)
RAY_MISS = (170, 170, 170)
TAG_COLORS = {Tag.FOOD: GREEN, Tag.WALL: WALL, Tag.BAD_FOOD: RED, Tag.AGENT: AGENT, Tag.FROZEN_AGENT: AGENT}
MIN_SPHERE_PIXELS = 3  # radius; spheres stay visible on small frames
MIN_AGENT_PIXELS = 14  # side; the 1-unit agent would be 5 px on a 512 px frame
OUTLINE = (20, 20, 30)


class _Canvas:
    """World (units, y up) → pixel (x right, y down) mapping for a square frame."""

    def __init__(self, params: FoodCollectorParams, size: int) -> None:
        self.size = size
        self.half = params.arena_half_size
        self.scale = (size - 2 * MARGIN) / (2.0 * self.half)

    def px(self, x: float, y: float) -> tuple[int, int]:
        """Pixel coordinates of the world point (x, y)."""
        return (int(round(MARGIN + (x + self.half) * self.scale)),
                int(round(MARGIN + (self.half - y) * self.scale)))


def draw_frame(params: FoodCollectorParams, pose: tuple[float, float, float, float], sphere_pos: np.ndarray,
               green: np.ndarray, ray_values: np.ndarray, size: int = FRAME_SIZE) -> np.ndarray:
    """Draw one (size, size, 3) uint8 RGB frame.

    ``pose`` is (x, y, cos, sin) of the agent's right axis; ``ray_values`` the 49 ray observations, used
    to draw each ray up to its hit point in the colour of what it hit (grey when it missed).
    """
    canvas = _Canvas(params, size)
    frame = np.empty((size, size, 3), dtype=np.uint8)
    frame[:] = WALL
    cv2.rectangle(frame, canvas.px(-canvas.half, canvas.half), canvas.px(canvas.half, -canvas.half),
                  BACKGROUND, thickness=-1)
    _draw_rays(frame, canvas, params, pose, ray_values)
    radius = max(MIN_SPHERE_PIXELS, int(round(params.sphere_radius * canvas.scale)))
    for (x, y), is_green in zip(sphere_pos.tolist(), green.tolist(), strict=True):
        color = GREEN if is_green else RED
        cv2.circle(frame, canvas.px(x, y), radius, color, thickness=-1, lineType=cv2.LINE_AA)
    _draw_agent(frame, canvas, params, pose)
    return frame


def _draw_rays(frame: np.ndarray, canvas: _Canvas, params: FoodCollectorParams,
               pose: tuple[float, float, float, float], ray_values: np.ndarray) -> None:
    """Each ray as a line from the agent to where its swept circle stopped."""
    x, y, c, s = pose
    rays = np.asarray(ray_values).reshape(-1, RAY_VALUES)
    for angle, row in zip(RAY_ANGLES_DEG, rays, strict=True):
        a = math.radians(angle)
        lx, ly = math.cos(a), math.sin(a)
        dist = float(row[FRACTION_SLOT]) * params.ray_length
        end = (x + dist * (lx * c - ly * s), y + dist * (lx * s + ly * c))
        if row[MISS_SLOT] > 0:
            color = RAY_MISS
        else:
            color = TAG_COLORS.get(Tag(int(np.argmax(row[:NUM_TAGS]))), RAY_MISS)
        cv2.line(frame, canvas.px(x, y), canvas.px(*end), color, thickness=1, lineType=cv2.LINE_AA)


def _draw_agent(frame: np.ndarray, canvas: _Canvas, params: FoodCollectorParams,
                pose: tuple[float, float, float, float]) -> None:
    """The agent's square (drawn at least ``MIN_AGENT_PIXELS`` wide) with a line toward its forward side."""
    x, y, c, s = pose
    half = max(0.5 * params.agent_size, 0.5 * MIN_AGENT_PIXELS / canvas.scale)
    corners = [(x + u * c - v * s, y + u * s + v * c) for u, v in ((-half, -half), (half, -half),
                                                                 (half, half), (-half, half))]
    poly = np.array([canvas.px(*p) for p in corners], dtype=np.int32)
    cv2.fillConvexPoly(frame, poly, AGENT, lineType=cv2.LINE_AA)
    cv2.polylines(frame, [poly], isClosed=True, color=OUTLINE, thickness=1, lineType=cv2.LINE_AA)
    nose = (x - 1.6 * half * s, y + 1.6 * half * c)  # forward = (−sin, cos) of the right axis angle
    cv2.line(frame, canvas.px(x, y), canvas.px(*nose), HEADING, thickness=2, lineType=cv2.LINE_AA)
