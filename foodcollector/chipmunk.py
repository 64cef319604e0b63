"""The arena's per-physics-step calls into Chipmunk, made through pymunk's own C bindings.

pymunk's public properties wrap each Chipmunk call in Python (a ``Vec2d`` per read, an attribute hook and
an assertion per write, a ``SegmentQueryInfo`` per ray hit); at the food collector's five physics steps
and seven rays per decision those wrappers cost more than the physics. `ChipmunkCalls` makes the very same
Chipmunk calls on the same bodies and space (``lib.cpBodyGetVelocity`` is what ``body.velocity`` calls), so
every number is unchanged (`tests/foodcollector/test_fc_chipmunk.py` steps both versions side by side);
only the wrappers' work is skipped (``python benchmarks/bench_foodcollector.py --calls`` times both).

`CALLS` is the version the arena uses: `ChipmunkCalls` where pymunk exposes its bindings as 7.x does,
else `PublicCalls` (the same functions through pymunk's public API).
"""

from __future__ import annotations

import threading

import pymunk

Vec = tuple[float, float]


class PublicCalls:
    """The calls through pymunk's public API."""

    @staticmethod
    def position(body: pymunk.Body) -> Vec:
        """The body's position (x, y)."""
        return tuple(body.position)

    @staticmethod
    def velocity(body: pymunk.Body) -> Vec:
        """The body's velocity (vx, vy)."""
        return tuple(body.velocity)

    @staticmethod
    def set_velocity(body: pymunk.Body, vx: float, vy: float) -> None:
        """Set the body's velocity."""
        body.velocity = (vx, vy)

    @staticmethod
    def angle(body: pymunk.Body) -> float:
        """The body's angle (radians)."""
        return body.angle

    @staticmethod
    def set_angle(body: pymunk.Body, angle: float) -> None:
        """Set the body's angle (radians)."""
        body.angle = angle

    @staticmethod
    def step(space: pymunk.Space, dt: float) -> None:
        """Advance the space by ``dt`` seconds."""
        space.step(dt)

    @staticmethod
    def ray_first(space: pymunk.Space, start: Vec, end: Vec, shape_filter: pymunk.ShapeFilter
                  ) -> tuple[int, float] | None:
        """The first shape a thin ray from ``start`` to ``end`` touches: (its collision type, the fraction of
        the way travelled), or None.
        """
        hit = space.segment_query_first(start, end, 0.0, shape_filter)
        return None if hit is None else (hit.shape.collision_type, hit.alpha)


try:
    from pymunk._chipmunk import ffi, lib

    HAS_BINDINGS = all(hasattr(lib, name) for name in (
        "cpBodyGetPosition", "cpBodyGetVelocity", "cpBodySetVelocity", "cpBodyGetAngle", "cpBodySetAngle",
        "cpSpaceStep", "cpSpaceSegmentQueryFirst", "cpShapeGetCollisionType"))
    HAS_BINDINGS = HAS_BINDINGS and hasattr(pymunk.Body(), "_body") and hasattr(pymunk.Space(), "_space")
except (ImportError, AttributeError):  # pragma: no cover - another pymunk layout
    HAS_BINDINGS = False
"""Whether this pymunk exposes Chipmunk's bindings as pymunk 7.x does (`ChipmunkCalls` needs them)."""
_SCRATCH = threading.local()  # each thread's output buffer of `ChipmunkCalls.ray_first` (cffi calls drop the GIL)


class ChipmunkCalls(PublicCalls):
    """The same calls straight to Chipmunk, through the bindings pymunk's properties use."""

    @staticmethod
    def position(body: pymunk.Body) -> Vec:
        """The body's position (x, y)."""
        v = lib.cpBodyGetPosition(body._body)
        return v.x, v.y

    @staticmethod
    def velocity(body: pymunk.Body) -> Vec:
        """The body's velocity (vx, vy)."""
        v = lib.cpBodyGetVelocity(body._body)
        return v.x, v.y

    @staticmethod
    def set_velocity(body: pymunk.Body, vx: float, vy: float) -> None:
        """Set the body's velocity."""
        lib.cpBodySetVelocity(body._body, (vx, vy))

    @staticmethod
    def angle(body: pymunk.Body) -> float:
        """The body's angle (radians)."""
        return lib.cpBodyGetAngle(body._body)

    @staticmethod
    def set_angle(body: pymunk.Body, angle: float) -> None:
        """Set the body's angle (radians)."""
        lib.cpBodySetAngle(body._body, angle)

    @staticmethod
    def step(space: pymunk.Space, dt: float) -> None:
        """Advance the space by ``dt`` seconds. pymunk's ``Space.step`` around this call also asserts that
        the dynamic bodies added since its last step have a mass and a moment (the arena's one, the agent,
        has both) and adds or removes what collision callbacks queued (the arena has none).
        """
        lib.cpSpaceStep(space._space, dt)

    @staticmethod
    def ray_first(space: pymunk.Space, start: Vec, end: Vec, shape_filter: pymunk.ShapeFilter
                  ) -> tuple[int, float] | None:
        """The first shape a thin ray from ``start`` to ``end`` touches: (its collision type, the fraction of
        the way travelled), or None.
        """
        info = getattr(_SCRATCH, "query", None)
        if info is None:
            info = _SCRATCH.query = ffi.new("cpSegmentQueryInfo *")
        shape = lib.cpSpaceSegmentQueryFirst(space._space, start, end, 0.0, shape_filter, info)
        return (lib.cpShapeGetCollisionType(shape), info.alpha) if shape else None


CALLS: type[PublicCalls] = ChipmunkCalls if HAS_BINDINGS else PublicCalls
"""The calls the arena makes (looked up at each use, so a test can swap in `PublicCalls`)."""
