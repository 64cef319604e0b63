"""The spheres as numpy struct-of-arrays: where they spawn (shaping), how they move (dynamism), contacts.

Source of truth: ``SphereField.pos`` / ``vel``. The pymunk shapes in `arena.Arena` are only a mirror
so that ray casts see the spheres. Spheres ``[0, num_green)`` are green, the rest red; a sphere keeps its
colour for ever (an eaten sphere is teleported, never replaced). The two per-physics-step loops (motion
and contacts) are small numba kernels: numpy's per-call overhead on 50 spheres cost 5x more.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from foodcollector.params import FoodCollectorParams

SPAWN_BATCH_MIN = 16
"""Smallest batch of candidate points drawn per rejection round when sampling spawns."""
SPAWN_MAX_ROUNDS = 1000
"""Rejection rounds before giving up; unreachable for validated parameters (acceptance is >> 1%)."""


def sample_spawn_points(rng: np.random.Generator, count: int, agent_xy: tuple[float, float],
                        max_dist: float, params: FoodCollectorParams) -> np.ndarray:
    """Draw ``count`` points uniformly over the spawn square, within ``max_dist`` of the agent.

    Points closer than ``params.spawn_clearance`` to the agent's centre are rejected too, so a sphere
    never spawns touching the agent. Sampling is rejection from the bounding box of the reachable part of
    the square, in vectorised batches. Returns a float64 array of shape (count, 2).
    """
    half = params.spawn_half_size
    agent = np.asarray(agent_xy, dtype=np.float64)
    lo = np.maximum(agent - max_dist, -half)
    hi = np.minimum(agent + max_dist, half)
    out = np.empty((count, 2), dtype=np.float64)
    filled = 0
    for _ in range(SPAWN_MAX_ROUNDS):
        if filled == count:
            return out
        cand = rng.uniform(lo, hi, size=(max(2 * (count - filled), SPAWN_BATCH_MIN), 2))
        d2 = np.einsum("ij,ij->i", cand - agent, cand - agent)
        ok = cand[(d2 <= max_dist * max_dist) & (d2 > params.spawn_clearance ** 2)]
        take = min(len(ok), count - filled)
        out[filled:filled + take] = ok[:take]
        filled += take
    if filled == count:
        return out
    raise RuntimeError(f"found no spawn point within {max_dist} of the agent at {agent_xy} after "
                       f"{SPAWN_MAX_ROUNDS} rounds; near_radius is too small for this arena")


def random_velocities(rng: np.random.Generator, count: int, speed: float) -> np.ndarray:
    """Velocities of magnitude ``speed`` in uniformly random directions, shape (count, 2).

    The directions are drawn even at speed 0, so static and dynamic runs consume the RNG alike.
    """
    angle = rng.uniform(0.0, 2.0 * math.pi, size=count)
    return speed * np.stack([np.cos(angle), np.sin(angle)], axis=1)


@nb.njit(cache=True)
def _advance_kernel(pos, vel, dt, bound, bounced):  # pragma: no cover - compiled
    """Move every sphere by vel·dt, mirroring overshoots at ±bound; write bounced indices, return count."""
    n = 0
    for i in range(pos.shape[0]):
        hit = False
        for k in range(2):
            p = pos[i, k] + vel[i, k] * dt
            if p > bound:
                p = 2.0 * bound - p
                vel[i, k] = -vel[i, k]
                hit = True
            elif p < -bound:
                p = -2.0 * bound - p
                vel[i, k] = -vel[i, k]
                hit = True
            pos[i, k] = p
        if hit:
            bounced[n] = i
            n += 1
    return n


@nb.njit(cache=True)
def _touching_kernel(pos, x, y, cos_a, sin_a, half, radius2, reach2, hits):  # pragma: no cover - compiled
    """Write the indices of spheres overlapping the agent's square into ``hits``; return their count."""
    n = 0
    for i in range(pos.shape[0]):
        dx = pos[i, 0] - x
        dy = pos[i, 1] - y
        if dx * dx + dy * dy >= reach2:
            continue  # broad phase: too far for any orientation of the square
        # The sphere centre in the agent's frame, minus the closest point of the square.
        lx = dx * cos_a + dy * sin_a
        ly = -dx * sin_a + dy * cos_a
        ex = lx - min(max(lx, -half), half)
        ey = ly - min(max(ly, -half), half)
        if ex * ex + ey * ey < radius2:
            hits[n] = i
            n += 1
    return n


class SphereField:
    """Positions, velocities and colours of every sphere; the dynamism and contact rules live here."""

    def __init__(self, params: FoodCollectorParams, speed: float) -> None:
        self.params = params
        self.speed = float(speed)
        """Speed of every sphere, units/s (dynamism × max_sphere_speed)."""
        n = params.num_spheres
        self.pos = np.zeros((n, 2), dtype=np.float64)
        self.vel = np.zeros((n, 2), dtype=np.float64)
        self.green = np.arange(n) < params.num_green
        self.bound = params.arena_half_size - params.sphere_radius
        """Sphere centres stay within [−bound, bound]² (they touch a wall at the bound)."""
        # Broad phase: a sphere can touch the agent only if its centre is this close to the agent's.
        self._reach2 = (params.agent_half_diagonal + params.sphere_radius) ** 2
        self._indices = np.zeros(n, dtype=np.int64)  # scratch output of the kernels

    def respawn(self, rng: np.random.Generator, idx: np.ndarray | list[int], agent_xy: tuple[float, float],
                max_dist: float) -> None:
        """Teleport spheres ``idx`` to new spawn points (see `sample_spawn_points`) with new directions."""
        k = len(idx)
        self.pos[idx] = sample_spawn_points(rng, k, agent_xy, max_dist, self.params)
        self.vel[idx] = random_velocities(rng, k, self.speed)

    def advance(self, dt: float) -> list[int]:
        """Move every sphere in a straight line for ``dt`` seconds, reflecting elastically off the walls.

        Returns the indices of the spheres that bounced (their position and velocity were changed).
        """
        if self.speed == 0.0:
            return []
        n = _advance_kernel(self.pos, self.vel, dt, self.bound, self._indices)
        return self._indices[:n].tolist()

    def touching(self, x: float, y: float, cos_a: float, sin_a: float) -> list[int]:
        """Indices of spheres overlapping the agent's square (centre x, y; right axis (cos_a, sin_a))."""
        n = _touching_kernel(self.pos, x, y, cos_a, sin_a, 0.5 * self.params.agent_size,
                             self.params.sphere_radius ** 2, self._reach2, self._indices)
        return self._indices[:n].tolist()
