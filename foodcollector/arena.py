"""The pymunk world: four walls, the agent's body and its movement model, and the seven ray casts.

Coordinates: Unity's top-down (x, z) becomes our (x, y), so counter-clockwise seen from above is the
positive angle. The agent's body frame is Unity's local frame: local +x is the agent's *right*, local +y
its *forward*; ``body.angle`` is the angle of the right axis from world +x.

Pymunk simulates only the agent against the walls. The spheres are pymunk bodies that mirror
`spheres.SphereField` so the ray casts see them; they never collide with the agent physically (their
filter only admits ray queries), contacts are tested in `SphereField`. Static spheres are STATIC bodies;
moving ones are KINEMATIC bodies with the same velocity, so pymunk moves the mirror exactly as numpy moves
the truth (p + v·dt in both), and only bounced or respawned spheres are copied over (`teleport_spheres`).

Ray casts are sphere casts done as thin rays against *sight* shapes inflated by the cast radius (the
Minkowski sum: a circle of radius ``ray_radius`` first touches a sphere of radius r exactly when its
centre line first touches a circle of radius r + ``ray_radius``; likewise for the walls). The result is
the same alpha; the reason is that pymunk 7.3.1's fat segment queries (radius > 0) prune its bounding-box
tree with the thin centre line, so they miss a shape whose box that line does not cross and the answer
depends on the tree's history. Thin queries are exact.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
import pymunk

from foodcollector import chipmunk
from foodcollector.params import RAY_ANGLES_DEG, FoodCollectorParams


class Tag(IntEnum):
    """Unity's detectable tags, in the order of the one-hot block of every ray."""

    FOOD = 0
    AGENT = 1
    WALL = 2
    BAD_FOOD = 3
    FROZEN_AGENT = 4


NUM_TAGS = len(Tag)
MISS_SLOT = NUM_TAGS
"""Index of the miss flag inside one ray's values."""
FRACTION_SLOT = NUM_TAGS + 1
"""Index of the hit fraction inside one ray's values."""
RAY_VALUES = NUM_TAGS + 2
"""Values per ray: one-hot tag, miss flag, hit fraction."""
MISS_ROW = (0.0,) * NUM_TAGS + (1.0, 1.0)
"""A ray that hit nothing: no tag, miss flag 1, fraction 1."""
HIT_PREFIX = tuple(tuple(float(t == tag) for t in range(NUM_TAGS)) + (0.0,) for tag in range(NUM_TAGS))
"""Per tag, a hit's one-hot and miss flag 0 (the fraction follows)."""

WALL_THICKNESS = 10.0  # units; Unity's is 1; thick so a 33 u/s agent cannot tunnel (rays see only the face)
# The agent re-adds 2 u/s into a wall every physics step; with pymunk's defaults (slop 0.1 units, ~12% of the
# overlap corrected per step) it settles 0.44 units deep. These keep it within ~0.06 units.
COLLISION_SLOP = 0.01  # units of overlap allowed before correction
OVERLAP_KEPT_PER_STEP = 0.2  # fraction of an overlap left after one physics step's correction

# Shape-filter categories: the agent collides with the physical walls only; rays see only sight shapes.
CAT_WALL, CAT_AGENT, CAT_SIGHT, CAT_RAY = 1, 2, 4, 8
WALL_FILTER = pymunk.ShapeFilter(categories=CAT_WALL, mask=CAT_AGENT)
AGENT_FILTER = pymunk.ShapeFilter(categories=CAT_AGENT, mask=CAT_WALL)
SIGHT_FILTER = pymunk.ShapeFilter(categories=CAT_SIGHT, mask=CAT_RAY)
RAY_FILTER = pymunk.ShapeFilter(categories=CAT_RAY, mask=CAT_SIGHT)

BRANCH_SIGN = (0.0, 1.0, -1.0)
"""Action branch value → sign: 0 none, 1 positive (forward / right / turn left), 2 negative."""


class Arena:
    """A pymunk space holding the walls, the agent (dynamic box) and the spheres' sight mirrors."""

    def __init__(self, params: FoodCollectorParams, green: np.ndarray, moving: bool) -> None:
        self.params = params
        self.moving = moving
        """Whether the spheres move (kinematic mirrors carrying their velocity) or not (static)."""
        self.space = pymunk.Space()
        # space.damping is the velocity fraction kept per second; per step pymunk applies damping**dt.
        self.space.damping = params.drag_per_step ** (1.0 / params.physics_dt)
        self.space.collision_slop = COLLISION_SLOP
        self.space.collision_bias = OVERLAP_KEPT_PER_STEP ** (1.0 / params.physics_dt)  # per second
        self._add_walls()
        self.agent = self._add_agent()
        self.sphere_bodies = self._add_spheres(green)
        rad = np.radians(RAY_ANGLES_DEG)
        # Ray end points in the agent's frame (right, forward), scaled to the ray length.
        self.ray_ends = tuple((params.ray_length * math.cos(a), params.ray_length * math.sin(a)) for a in rad)

    def _add_walls(self) -> None:
        """Four static segments whose inner faces lie at ±arena_half_size, plus their inflated sight twins."""
        r = 0.5 * WALL_THICKNESS
        c = self.params.arena_half_size + r
        ends = [((-c, -c), (-c, c)), ((c, -c), (c, c)), ((-c, -c), (c, -c)), ((-c, c), (c, c))]
        for a, b in ends:
            seg = pymunk.Segment(self.space.static_body, a, b, r)
            seg.friction, seg.elasticity = 0.0, 0.0
            seg.filter, seg.collision_type = WALL_FILTER, Tag.WALL
            sight = pymunk.Segment(self.space.static_body, a, b, r + self.params.ray_radius)
            sight.filter, sight.collision_type = SIGHT_FILTER, Tag.WALL
            self.space.add(seg, sight)

    def _add_agent(self) -> pymunk.Body:
        """The agent: a dynamic square that never spins from contacts (infinite moment)."""
        body = pymunk.Body(self.params.agent_mass, math.inf)
        side = self.params.agent_size
        shape = pymunk.Poly.create_box(body, (side, side))
        shape.friction, shape.elasticity = 0.0, 0.0
        shape.filter, shape.collision_type = AGENT_FILTER, Tag.AGENT
        self.space.add(body, shape)
        return body

    def _add_spheres(self, green: np.ndarray) -> list[pymunk.Body]:
        """One body + sight circle (inflated by the ray radius) per sphere, in index order."""
        bodies = []
        body_type = pymunk.Body.KINEMATIC if self.moving else pymunk.Body.STATIC
        for is_green in green.tolist():
            body = pymunk.Body(body_type=body_type)
            shape = pymunk.Circle(body, self.params.sphere_radius + self.params.ray_radius)
            shape.filter = SIGHT_FILTER
            shape.collision_type = Tag.FOOD if is_green else Tag.BAD_FOOD
            self.space.add(body, shape)
            bodies.append(body)
        return bodies

    # ---- state --------------------------------------------------------------------------------------

    def pose(self) -> tuple[float, float, float, float]:
        """The agent's centre and right axis: (x, y, cos angle, sin angle)."""
        calls = chipmunk.CALLS
        x, y = calls.position(self.agent)
        a = calls.angle(self.agent)
        return x, y, math.cos(a), math.sin(a)

    def place_agent(self, x: float, y: float, angle: float, vx: float = 0.0, vy: float = 0.0) -> None:
        """Teleport the agent (angle of its right axis in radians) and set its velocity."""
        self.agent.position = (x, y)
        self.agent.angle = angle
        self.agent.velocity = (vx, vy)
        self.space.reindex_shapes_for_body(self.agent)

    def teleport_spheres(self, pos: np.ndarray, vel: np.ndarray, idx: list[int] | None = None) -> None:
        """Copy sphere positions (and velocities, if moving) of all spheres or ``idx`` into the mirrors."""
        bodies = self.sphere_bodies
        reindex = self.space.reindex_shapes_for_body
        rows = list(range(len(bodies)) if idx is None else idx)
        for i, p, v in zip(rows, pos[rows].tolist(), vel[rows].tolist(), strict=True):
            body = bodies[i]
            body.position = p
            if self.moving:
                body.velocity = v
            reindex(body)

    def local_velocity(self) -> tuple[float, float]:
        """The agent's velocity in its own frame: (rightward, forward), units/s."""
        calls = chipmunk.CALLS
        vx, vy = calls.velocity(self.agent)
        a = calls.angle(self.agent)
        c, s = math.cos(a), math.sin(a)
        return vx * c + vy * s, -vx * s + vy * c

    # ---- dynamics -----------------------------------------------------------------------------------

    def drive(self, forward: int, strafe: int, turn: int) -> None:
        """Unity's ``MoveAgent`` for one physics step (branch values 0 none, 1 positive, 2 negative).

        Velocity is first scaled by ``slowdown_factor`` if the speed exceeds ``slowdown_speed`` (Unity
        reads the velocity before its queued force), then changed by ``move_speed`` along the chosen
        direction; strafe *replaces* forward (Unity assigns, not adds). The heading used is the one
        before this step's turn; the turn is applied to the body directly.
        """
        p, calls = self.params, chipmunk.CALLS
        body = self.agent
        vx, vy = calls.velocity(body)
        if vx * vx + vy * vy > p.slowdown_speed * p.slowdown_speed:
            vx *= p.slowdown_factor
            vy *= p.slowdown_factor
        a = calls.angle(body)
        if strafe:
            dv = BRANCH_SIGN[strafe] * p.move_speed
            vx += dv * math.cos(a)
            vy += dv * math.sin(a)
        elif forward:
            dv = BRANCH_SIGN[forward] * p.move_speed
            vx -= dv * math.sin(a)
            vy += dv * math.cos(a)
        calls.set_velocity(body, vx, vy)
        if turn:
            calls.set_angle(body, a + BRANCH_SIGN[turn] * p.turn_step_radians)

    def step_physics(self) -> None:
        """Advance pymunk by one physics step (drag on the agent, contacts with the walls)."""
        chipmunk.CALLS.step(self.space, self.params.physics_dt)

    # ---- sensing ------------------------------------------------------------------------------------

    def cast_rays(self) -> list[float]:
        """The 7 × 7 ray values, flattened: per ray [one-hot(tag), miss flag, hit fraction].

        Each ray is a swept circle (``ray_radius``) from the agent's centre along its direction for
        ``ray_length``; the first shape touched decides the tag and the fraction of the length travelled.
        Cast as a thin ray against the inflated sight shapes (see the module docstring).
        """
        x, y, c, s = self.pose()
        ray_first, space = chipmunk.CALLS.ray_first, self.space
        values: list[float] = []
        for rx, ry in self.ray_ends:
            start, end = (x, y), (x + rx * c - ry * s, y + rx * s + ry * c)
            hit = ray_first(space, start, end, RAY_FILTER)
            if hit is not None and hit[1] == 0.0:
                hit = self._first_hit_from_outside(start, end)
            if hit is None:
                values += MISS_ROW
            else:
                values += HIT_PREFIX[hit[0]]
                values.append(hit[1])
        return values

    def _first_hit_from_outside(self, start: tuple[float, float], end: tuple[float, float]
                                ) -> tuple[int, float] | None:
        """The nearest hit, as (collision type, fraction), ignoring shapes the cast starts inside of (Unity's
        SphereCast does the same).

        Only needed when the agent is pressed against a wall: its centre is then within ``ray_radius``
        of the wall face, inside the inflated sight wall, and pymunk would report that wall at alpha 0.
        A ray heading into the ignored wall travels through solid wall: wall hits beyond the wall faces
        (the other walls' outer extensions) are discarded, so such a ray sees only spheres, or nothing.
        """
        lim = self.params.arena_half_size
        hits = [h for h in self.space.segment_query(start, end, 0.0, RAY_FILTER) if h.alpha > 0.0 and (
                h.shape.collision_type != Tag.WALL or (abs(h.point.x) <= lim and abs(h.point.y) <= lim))]
        first = min(hits, key=lambda h: h.alpha) if hits else None
        return None if first is None else (first.shape.collision_type, first.alpha)

    # ---- saving and restoring ------------------------------------------------------------------------

    def get_state(self) -> dict:
        """The agent body and the sphere mirrors as plain data (see `set_state`).

        pymunk's contact cache (the impulses it warm-starts its solver with) is not part of it: an arena
        restored into a fresh space starts its solver cold, which can change the next step's position by
        a rounding error while the agent touches a wall. The trainer therefore continues from the restored
        state after every checkpoint, so a resumed run and an uninterrupted one stay identical.
        """
        agent = self.agent
        return {
            "agent_position": [float(v) for v in agent.position], "agent_angle": float(agent.angle),
            "agent_velocity": [float(v) for v in agent.velocity],
            "agent_angular_velocity": float(agent.angular_velocity),
            "sphere_body_pos": np.array([tuple(b.position) for b in self.sphere_bodies], dtype=np.float64),
            "sphere_body_vel": np.array([tuple(b.velocity) for b in self.sphere_bodies], dtype=np.float64),
        }

    def set_state(self, state: dict) -> None:
        """Restore `get_state` output into this arena (built fresh, nothing stepped yet)."""
        agent = self.agent
        agent.position = tuple(float(v) for v in state["agent_position"])
        agent.angle = float(state["agent_angle"])
        agent.velocity = tuple(float(v) for v in state["agent_velocity"])
        agent.angular_velocity = float(state["agent_angular_velocity"])
        self.space.reindex_shapes_for_body(agent)
        pos, vel = np.asarray(state["sphere_body_pos"]), np.asarray(state["sphere_body_vel"])
        if pos.shape != (len(self.sphere_bodies), 2) or vel.shape != pos.shape:
            raise ValueError(f"saved sphere state has shape {pos.shape}, this arena has "
                             f"{len(self.sphere_bodies)} spheres")
        for body, p, v in zip(self.sphere_bodies, pos.tolist(), vel.tolist()):
            body.position = p
            if self.moving:
                body.velocity = v
            self.space.reindex_shapes_for_body(body)
