"""Task parameters of the food collector, with Unity ML-Agents' FoodCollector values as defaults.

Every default is a number of Unity ML-Agents' FoodCollector (Release 3-7) unless its docstring says it is ours;
docs/fidelity.md lists where the task departs from Unity.
Derived quantities (per-step factors, ray angles, bounds) are properties, never stored fields.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

UNITY_EPISODE_DECISIONS = 1000
"""Unity's episode and the test MDP's: ``MaxStep`` 5000 physics steps / ``DecisionPeriod`` 5 decisions."""

RAYS_PER_DIRECTION = 3
"""Unity ``m_RaysPerDirection``: rays on each side of the central one (7 rays in all)."""
MAX_RAY_DEGREES = 70.0
"""Unity ``m_MaxRayDegrees``: angle of the outermost rays from straight ahead, degrees."""


def unity_ray_angles(rays_per_direction: int = RAYS_PER_DIRECTION, max_degrees: float = MAX_RAY_DEGREES):
    """Ray angles in degrees counter-clockwise from the agent's right, in ML-Agents' order.

    Unity's ``GetRayAngles``: 90 first, then alternately right and left of it in steps of
    ``max_degrees / rays_per_direction``: [90, 66.7, 113.3, 43.3, 136.7, 20, 160] for the defaults.
    """
    delta = max_degrees / rays_per_direction
    angles = [90.0]
    for k in range(1, rays_per_direction + 1):
        angles += [90.0 - k * delta, 90.0 + k * delta]
    return tuple(angles)


RAY_ANGLES_DEG = unity_ray_angles()
NUM_RAYS = len(RAY_ANGLES_DEG)


@dataclass(frozen=True)
class FoodCollectorParams:
    """Static task parameters (geometry, counts, physics, horizon); every field is also an env kwarg."""

    arena_half_size: float = 50.0
    """Inner faces of the four walls at ±this, units (Unity court 100 × 100)."""
    spawn_half_size: float = 45.0
    """Spheres and the agent spawn uniformly in [−this, this]², units (Unity ``range``)."""
    num_green: int = 25
    """Green spheres (Unity ``numFood``, tag ``food``, +1 when touched)."""
    num_red: int = 25
    """Red spheres (Unity ``numBadFood``, tag ``badFood``, −1 when touched)."""
    sphere_radius: float = 0.75
    """Radius of every sphere, units (Unity SphereCollider)."""
    agent_size: float = 1.0
    """Side of the agent's square body, units (Unity 1 × 1 × 1 BoxCollider)."""
    agent_mass: float = 10.0
    """Agent mass, kg (Unity Rigidbody); only matters for contacts with the walls."""
    agent_drag: float = 0.5
    """Unity Rigidbody drag, 1/s: velocity is multiplied by (1 − drag·dt) every physics step."""
    move_speed: float = 2.0
    """Velocity change per physics step along the chosen direction, units/s (Unity ``moveSpeed``)."""
    turn_speed: float = 300.0
    """Turning rate, degrees/s (Unity ``turnSpeed``): 6° per physics step, 30° per decision."""
    slowdown_speed: float = 5.0
    """Above this speed (units/s) velocity is scaled by ``slowdown_factor`` every physics step (Unity)."""
    slowdown_factor: float = 0.95
    """Unity's "slow it down" factor applied while speed > ``slowdown_speed``."""
    physics_dt: float = 0.02
    """One physics step, seconds (Unity ``Fixed Timestep``)."""
    substeps: int = 5
    """Physics steps per decision, the action repeated on each (Unity ``DecisionPeriod``)."""
    ray_length: float = 50.0
    """Length of each ray, units (Unity ``m_RayLength``)."""
    ray_radius: float = 0.5
    """Radius of the swept circle of each ray cast, units (Unity ``m_SphereCastRadius``)."""
    max_sphere_speed: float = 10.0
    """Ours (dynamism): sphere speed at ``dynamism=1``, units/s; speed is dynamism × this."""
    near_radius: float = 10.0
    """Ours (shaping): maximum spawn distance from the agent at shaping strength 1, units."""
    horizon: int = UNITY_EPISODE_DECISIONS
    """Episodic only: decisions before truncation (Unity 5000 physics steps = 1000 decisions)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type == "int":
                if isinstance(value, bool) or not isinstance(value, int):
                    raise TypeError(f"FoodCollectorParams.{f.name} must be an int, got {value!r}")
            elif isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise TypeError(f"FoodCollectorParams.{f.name} must be a finite number, got {value!r}")
        self._check_ranges()
        self._check_geometry()

    def _check_ranges(self) -> None:
        """Raise ValueError for a field outside its meaningful range."""
        positive = ("arena_half_size", "spawn_half_size", "sphere_radius", "agent_size", "agent_mass",
                    "move_speed", "slowdown_speed", "physics_dt", "ray_length", "ray_radius", "near_radius")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"FoodCollectorParams.{name} must be > 0, got {getattr(self, name)}")
        for name in ("num_green", "num_red", "turn_speed", "max_sphere_speed"):
            if getattr(self, name) < 0:
                raise ValueError(f"FoodCollectorParams.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("substeps", "horizon"):
            if getattr(self, name) < 1:
                raise ValueError(f"FoodCollectorParams.{name} must be >= 1, got {getattr(self, name)}")
        if self.num_green + self.num_red < 1:
            raise ValueError("the food collector needs at least one sphere (num_green + num_red >= 1)")
        if not 0 < self.slowdown_factor <= 1:
            raise ValueError(f"slowdown_factor must lie in (0, 1], got {self.slowdown_factor}")
        if not 0 <= self.agent_drag * self.physics_dt < 1:
            raise ValueError(f"agent_drag · physics_dt must lie in [0, 1), got {self.drag_per_step}")

    def _check_geometry(self) -> None:
        """Raise ValueError when spheres or the agent could not fit, or shaped spawns could be impossible."""
        if self.spawn_half_size + self.sphere_radius > self.arena_half_size:
            raise ValueError("spawn_half_size + sphere_radius must not exceed arena_half_size "
                             f"({self.spawn_half_size} + {self.sphere_radius} > {self.arena_half_size})")
        if self.spawn_half_size + self.agent_half_diagonal > self.arena_half_size:
            raise ValueError("the agent must fit inside the walls anywhere in the spawn square "
                             f"(spawn_half_size + agent half-diagonal > {self.arena_half_size})")
        if self.max_sphere_speed * self.physics_dt >= 2 * (self.arena_half_size - self.sphere_radius):
            raise ValueError("max_sphere_speed · physics_dt must be smaller than the arena's width "
                             "(a sphere would cross the arena in one physics step); "
                             f"got {self.max_sphere_speed}")
        if self.near_radius < self.min_near_radius:
            raise ValueError(f"near_radius must be >= {self.min_near_radius:.3f} (the farthest the agent "
                             "can be from the spawn square plus the spawn clearance), "
                             f"or shaped spawns could find no room; got {self.near_radius}")

    # ---- derived quantities -------------------------------------------------------------------------

    @property
    def num_spheres(self) -> int:
        """Green plus red spheres."""
        return self.num_green + self.num_red

    @property
    def agent_half_diagonal(self) -> float:
        """Largest distance from the agent's centre to its boundary, units."""
        return self.agent_size * math.sqrt(0.5)

    @property
    def spawn_clearance(self) -> float:
        """Spheres never spawn with their centre closer than this to the agent's centre (so not touching)."""
        return self.agent_half_diagonal + self.sphere_radius

    @property
    def min_near_radius(self) -> float:
        """Smallest ``near_radius`` for which a spawn point near the agent always exists, units.

        The agent's centre can be ``arena_half_size - agent_size/2`` from the centre on both axes, i.e.
        outside the spawn square; the nearest spawn point is then the square's corner.
        """
        gap = max(0.0, self.arena_half_size - 0.5 * self.agent_size - self.spawn_half_size)
        return math.sqrt(2.0) * gap + self.spawn_clearance + self.sphere_radius

    @property
    def full_spawn_distance(self) -> float:
        """The arena's diagonal: a maximum spawn distance that never binds (shaping strength 0), units."""
        return 2.0 * math.sqrt(2.0) * self.arena_half_size

    @property
    def decision_seconds(self) -> float:
        """Simulated time of one decision, seconds."""
        return self.substeps * self.physics_dt

    @property
    def turn_step_radians(self) -> float:
        """Rotation per physics step while turning, radians."""
        return math.radians(self.turn_speed * self.physics_dt)

    @property
    def drag_per_step(self) -> float:
        """Velocity factor per physics step from drag: 1 − drag·dt (0.99 for Unity's values)."""
        return 1.0 - self.agent_drag * self.physics_dt

    @property
    def max_agent_speed(self) -> float:
        """Terminal speed of the movement model, units/s: fixed point of v = (f·v + dv)·(1 − drag·dt).

        The speed can never exceed it (|f·v + dv| <= f·|v| + dv), ≈33.3 for Unity's values.
        """
        keep = self.drag_per_step
        shrink = self.slowdown_factor * keep
        terminal = self.move_speed * keep / (1.0 - shrink) if shrink < 1 else math.inf
        return max(terminal, (self.slowdown_speed + self.move_speed) * keep)

    def max_spawn_distance(self, strength: float) -> float:
        """Maximum spawn distance from the agent at shaping strength s: the diagonal (s=0) to near (s=1).

        d(s) = (1 − s) · ``full_spawn_distance`` + s · ``near_radius``.
        """
        return (1.0 - strength) * self.full_spawn_distance + strength * self.near_radius

    def as_kwargs(self) -> dict:
        """The fields as plain keyword arguments (for ``gymnasium.make`` and configs)."""
        return asdict(self)


PARAM_NAMES = tuple(f.name for f in fields(FoodCollectorParams))
