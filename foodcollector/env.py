"""The Gymnasium environment: one decision = ``substeps`` physics steps with the action repeated."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ecology import (
    Ecology,
    VisitGrid,
    can_render,
    check_action,
    check_render_mode,
    make_test_mdp_kwargs,
    schedule_value,
)
from foodcollector.arena import RAY_VALUES, Arena
from foodcollector.params import NUM_RAYS, PARAM_NAMES, UNITY_EPISODE_DECISIONS, FoodCollectorParams
from foodcollector.render import FRAME_SIZE, draw_frame
from foodcollector.spheres import SphereField, random_velocities, sample_spawn_points

NUM_ACTIONS = 27
ACTION_TABLE = tuple((a // 9, (a // 3) % 3, a % 3) for a in range(NUM_ACTIONS))
"""Action → (forward, strafe, turn) branch values, each 0 none, 1 positive, 2 negative."""

RAY_OBS = NUM_RAYS * RAY_VALUES  # 49
VECTOR_OBS = 4  # local velocity (right, forward), frozen flag, shoot flag
OBS_SIZE = RAY_OBS + VECTOR_OBS  # 53
VELOCITY_BOUND_MARGIN = 1.05  # the terminal speed is a strict bound; 5% headroom for pymunk rounding

REWARD_GREEN = 1.0
REWARD_RED = -1.0

VISIT_BINS = 20
"""Visitation maps bin the arena into this many cells per side."""


def decode_action(action: Any) -> tuple[int, int, int]:
    """Validate an action and split it into (forward, strafe, turn) branch values."""
    return ACTION_TABLE[check_action(action, NUM_ACTIONS)]


def encode_action(forward: int = 0, strafe: int = 0, turn: int = 0) -> int:
    """The action index of branch values (0 none, 1 positive, 2 negative): 9·forward + 3·strafe + turn."""
    for name, v in (("forward", forward), ("strafe", strafe), ("turn", turn)):
        if v not in (0, 1, 2):
            raise ValueError(f"{name} must be 0 (none), 1 (positive) or 2 (negative), got {v!r}")
    return 9 * forward + 3 * strafe + turn


def _resolve_params(params: FoodCollectorParams | None, overrides: dict[str, Any]) -> FoodCollectorParams:
    """Task parameters from a `FoodCollectorParams` and/or its fields as keyword arguments."""
    unknown = sorted(set(overrides) - set(PARAM_NAMES))
    if unknown:
        raise TypeError(f"unknown food collector argument(s) {unknown}; the knobs are dynamism, shaping, "
                        "reset_free, reward, render_mode, params, and the task parameters "
                        f"{list(PARAM_NAMES)}")
    base = params.as_kwargs() if params is not None else {}
    return FoodCollectorParams(**{**base, **overrides})


def _check_reward(reward: Any) -> str:
    """The food collector has only its native ±1 reward; anything but "sparse" is an error."""
    if reward != "sparse":
        raise ValueError(f"reward={reward!r}: the food collector has only its native ±1 reward "
                         "(+1 green, −1 red); pass reward='sparse'")
    return reward


class FoodCollectorEnv(gym.Env):
    """Unity ML-Agents' FoodCollector in 2D (pymunk): eat green spheres, avoid red ones.

    Paper: Co-Reyes et al. 2020, "Ecological Reinforcement Learning", §5.1 (the fifth task, "Unity food
    collector": dynamism = sphere speed, shaping = distance at which spheres appear from the agent).
    Numbers: Unity ML-Agents Release 3-7 FoodCollector (its differences from Unity: docs/fidelity.md).

    ## Description
    A 100 × 100 arena (walls at ±50) holds 25 green and 25 red spheres (radius 0.75). The agent is a
    1 × 1 square of mass 10 with Unity's drag 0.5. One decision is 5 physics steps of 0.02 s with the
    action repeated. On each physics step, as Unity's ``MoveAgent``: if speed > 5 the velocity is scaled
    by 0.95; then it changes by 2 units/s along the chosen direction (strafe *overrides* forward); the
    heading turns by 6° (30° per decision); drag keeps 0.99 of the velocity. Terminal speed ≈33 units/s.

    ## Action space: ``Discrete(27)``, ``a = 9·forward + 3·strafe + turn``
    | branch  | 0    | 1                          | 2                           |
    |---------|------|----------------------------|-----------------------------|
    | forward | none | forward (+2 u/s per step)  | backward                    |
    | strafe  | none | right (overrides forward)  | left (overrides forward)    |
    | turn    | none | left, counter-clockwise 6° | right, clockwise 6°         |
    E.g. 9 = forward, 10 = forward + turn left, 3 = strafe right. Anything but an integer in [0, 27)
    raises `ecology.InvalidAction` (both a TypeError and a ValueError). Unity's laser branch is dropped (single agent).

    ## Observation space: ``Box(53,)`` float32 (Unity's layout)
    | index       | meaning                                                                           |
    |-------------|-----------------------------------------------------------------------------------|
    | 7·k + 0..4  | ray k one-hot tag: food (green), agent, wall, badFood (red), frozenAgent          |
    | 7·k + 5     | ray k miss flag (1 if the ray hit nothing within its length)                      |
    | 7·k + 6     | ray k hit fraction: distance travelled / 50 (1 on a miss)                         |
    | 49, 50      | velocity in the agent's frame: rightward, forward (units/s, not normalised)       |
    | 51, 52      | frozen flag, shoot flag (always 0: no laser, no other agents)                     |
    Rays k = 0..6 point at 90, 66.7, 113.3, 43.3, 136.7, 20, 160 degrees counter-clockwise from the
    agent's right (90 = straight ahead); each is a circle of radius 0.5 swept from the agent's centre
    for 50 units, the agent's own body ignored; the first wall or sphere it touches is reported. The
    trainer's view branch reads the first 49 values, its inventory branch the last 4
    (``observation_split``).

    ## Rewards
    +1 per green sphere touched, −1 per red one (a contact is any overlap of a sphere with the agent's
    square after a physics step; several per decision add up). An eaten sphere is teleported to a new
    spawn point at once, with a new random direction. No other reward; the ``reward`` knob accepts only
    ``"sparse"``.

    ## Starting state
    The agent at a uniform point of [−45, 45]², facing a uniform whole number of degrees, at rest.
    Spheres at uniform points of [−45, 45]² not touching the agent (subject to shaping, below).

    ## Episode end
    Never terminates. Episodic (``reset_free=False``): truncated after ``horizon`` decisions (default
    1000 = Unity's 5000 physics steps); stepping again before ``reset()`` raises. Reset-free: never
    truncated either. ``reset(seed=...)`` starts a new lifetime (the lifetime counter returns to 0), so a
    seed alone determines a trajectory; ``reset()`` without a seed keeps counting.

    ## Ecology knobs (``env.unwrapped.ecology``)
    - ``dynamism`` p ∈ [0, 1]: every sphere moves at p · ``max_sphere_speed`` (10 units/s) in a straight
      line from a random direction, reflecting elastically off the walls; 0 is Unity's static field.
    - ``shaping``: strength s(t) ∈ [0, 1] (number or schedule string, e.g. ``"linear:1:0:280000"``) over
      the lifetime decision counter t. Every spawn (initial and respawn) is uniform over the part of the
      spawn square within d(s) of the agent, d(s) = (1 − s) · arena diagonal + s · ``near_radius``
      (141.4 → 10 units): s = 0 is the original uniform spawn, s = 1 keeps spawns within 10 units.
    - ``reset_free``: True = one reset, never ends; False = episodic with ``horizon``.
    - ``reward``: only ``"sparse"``.

    ## Arguments
    ``gymnasium.make("foodcollector/FoodCollector-v0", dynamism=0.0, shaping=0.0, reset_free=False,
    reward="sparse", render_mode=None, params=None, **task_params)``; ``task_params`` are the fields of
    `FoodCollectorParams` (arena size, counts, radii, speeds, ``near_radius``, ``max_sphere_speed``,
    ``horizon``, ``physics_dt``, ``substeps``, ...). ``render_mode="rgb_array"`` gives a 512 × 512 frame.

    ## Info (every step)
    ``green_eaten``, ``red_eaten`` (cumulative since reset), ``agent_pos`` (float64 array [x, y]),
    ``lifetime_step`` (decisions since the last seeded reset, never reset otherwise), ``episode_step``,
    ``solved`` (always False: the metric is the return).

    ## Version history
    v0: first version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}  # one decision = 0.1 s simulated

    def __init__(self, dynamism: float = 0.0, shaping: Any = 0.0, reset_free: bool = False,
                 reward: str = "sparse", render_mode: str | None = None,
                 params: FoodCollectorParams | None = None, **task_params: Any) -> None:
        self.params = _resolve_params(params, task_params)
        self.ecology = Ecology(dynamism=dynamism, shaping=shaping, reset_free=reset_free,
                               reward=_check_reward(reward))
        self.render_mode = check_render_mode(render_mode, self.metadata["render_modes"])
        self.action_space = spaces.Discrete(NUM_ACTIONS)
        self.observation_space = self._make_observation_space()
        self.observation_split = (RAY_OBS, VECTOR_OBS)
        self.spheres = SphereField(self.params, self.ecology.dynamism * self.params.max_sphere_speed)
        self.arena = Arena(self.params, self.spheres.green, moving=self.spheres.speed > 0)
        self._shaping_breakpoints = self.ecology.shaping.breakpoints
        self._lifetime_step = 0
        self._episode_step = 0
        self._green_eaten = 0
        self._red_eaten = 0
        self._needs_reset = True
        self._laid_out = False  # no frame before the first reset: nothing is placed yet
        self._ray_values = np.zeros(RAY_OBS, dtype=np.float32)

    def _make_observation_space(self) -> spaces.Box:
        """Rays in [0, 1], velocities within ± the terminal speed, flags in [0, 1]."""
        vmax = VELOCITY_BOUND_MARGIN * self.params.max_agent_speed
        low = np.zeros(OBS_SIZE, dtype=np.float32)
        high = np.ones(OBS_SIZE, dtype=np.float32)
        low[RAY_OBS:RAY_OBS + 2] = -vmax
        high[RAY_OBS:RAY_OBS + 2] = vmax
        return spaces.Box(low, high, dtype=np.float32)

    # ---- gymnasium API ------------------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Place the agent and every sphere anew; a seed also restarts the lifetime counter."""
        super().reset(seed=seed)
        self._laid_out = True
        if seed is not None:  # a new life: a fresh physics space too, so that a seeded reset is a pure
            self._lifetime_step = 0  # function of the seed (pymunk warm-starts from its contact cache)
            self.arena = Arena(self.params, self.spheres.green, moving=self.spheres.speed > 0)
        rng = self.np_random
        half = self.params.spawn_half_size
        x, y = rng.uniform(-half, half, size=2).tolist()
        heading = float(rng.integers(0, 360))  # Unity: Random.Range(0, 360), the int overload
        self.arena.place_agent(x, y, math.radians(heading - 90.0))
        n = self.params.num_spheres
        self.spheres.pos[:] = sample_spawn_points(rng, n, (x, y), self.max_spawn_distance, self.params)
        self.spheres.vel[:] = random_velocities(rng, n, self.spheres.speed)
        self.arena.teleport_spheres(self.spheres.pos, self.spheres.vel)
        self._episode_step = 0
        self._green_eaten = 0
        self._red_eaten = 0
        self._needs_reset = False
        return self._observe(), self._info()

    def step(self, action: Any):
        """Repeat the action for ``substeps`` physics steps; reward = green − red spheres touched."""
        forward, strafe, turn = decode_action(action)
        if self._needs_reset:
            ended = f"the episode ended (truncated at horizon {self.params.horizon}); call reset()"
            raise RuntimeError("call reset() before step()" if self._episode_step == 0 else ended)
        reward = self._simulate(forward, strafe, turn)
        self._lifetime_step += 1
        self._episode_step += 1
        truncated = not self.ecology.reset_free and self._episode_step >= self.params.horizon
        self._needs_reset = truncated
        return self._observe(), reward, False, truncated, self._info()

    def render(self) -> np.ndarray | None:
        """A top-down RGB frame (``render_mode="rgb_array"``), or None with a warning otherwise."""
        if not can_render(self.render_mode, self._laid_out):
            return None
        return self.frame()

    def frame(self, size: int = FRAME_SIZE) -> np.ndarray:
        """Draw the current state as a (size, size, 3) uint8 RGB image, whatever the render mode."""
        return draw_frame(self.params, self.arena.pose(), self.spheres.pos, self.spheres.green,
                          self._ray_values, size)

    # ---- the decision pipeline ----------------------------------------------------------------------

    def _simulate(self, forward: int, strafe: int, turn: int) -> float:
        """Physics steps with the action repeated: drive, step pymunk, move spheres, eat what touches."""
        arena, spheres = self.arena, self.spheres
        dt = self.params.physics_dt
        reward = 0.0
        for _ in range(self.params.substeps):
            arena.drive(forward, strafe, turn)
            arena.step_physics()  # also moves the kinematic sphere mirrors by v·dt
            bounced = spheres.advance(dt)
            x, y, c, s = arena.pose()
            eaten = spheres.touching(x, y, c, s)
            if eaten:
                reward += self._eat(eaten, (x, y))
            if bounced or eaten:
                arena.teleport_spheres(spheres.pos, spheres.vel, sorted(set(bounced + eaten)))
        return reward

    def _eat(self, eaten: list[int], agent_xy: tuple[float, float]) -> float:
        """Count and reward the touched spheres, then respawn them (shaping decides how far away)."""
        greens = int(self.spheres.green[eaten].sum())
        reds = len(eaten) - greens
        self._green_eaten += greens
        self._red_eaten += reds
        self.spheres.respawn(self.np_random, eaten, agent_xy, self.max_spawn_distance)
        return greens * REWARD_GREEN + reds * REWARD_RED

    def _observe(self) -> np.ndarray:
        """The 53-value observation (fresh array): rays, local velocity, frozen and shoot flags."""
        rays = self.arena.cast_rays()
        right, fwd = self.arena.local_velocity()
        obs = np.array(rays + [right, fwd, 0.0, 0.0], dtype=np.float32)
        self._ray_values = obs[:RAY_OBS].copy()  # for render(); callers may modify obs
        return obs

    def _info(self) -> dict[str, Any]:
        """Per-step diagnostics shared with the grid tasks' contract."""
        # agent_pos is an array so that vector envs stack it to (num_envs, 2) for visitation maps.
        return {"green_eaten": self._green_eaten, "red_eaten": self._red_eaten,
                "agent_pos": np.array(self.arena.agent.position, dtype=np.float64),
                "lifetime_step": self._lifetime_step, "episode_step": self._episode_step, "solved": False}

    # ---- the shared contract ------------------------------------------------------------------------

    @property
    def shaping_strength(self) -> float:
        """Shaping strength s(t) at the current lifetime decision t."""
        return float(schedule_value(self._shaping_breakpoints, float(self._lifetime_step)))

    @property
    def max_spawn_distance(self) -> float:
        """How far from the agent a sphere may spawn right now: d(s(t)), see `FoodCollectorParams`."""
        return self.params.max_spawn_distance(self.shaping_strength)

    @property
    def lifetime_step(self) -> int:
        """Decisions taken since the last seeded reset (never reset by an unseeded one)."""
        return self._lifetime_step

    def test_mdp_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``gymnasium.make`` giving this task's evaluation MDP.

        The same task parameters with `ecology.TEST_MDP` knobs: static spheres, uniform spawns,
        episodic, truncated at Unity's 1000 decisions.
        """
        return make_test_mdp_kwargs(self.params.as_kwargs(), UNITY_EPISODE_DECISIONS)

    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        """The task parameters this environment takes as keyword arguments: the fields of `FoodCollectorParams`."""
        return tuple(PARAM_NAMES)

    @property
    def visit_grid(self) -> VisitGrid:
        """Visitation maps bin the arena into `VISIT_BINS` x `VISIT_BINS` cells (row from y, column from x)."""
        half = self.params.arena_half_size
        return VisitGrid((VISIT_BINS, VISIT_BINS), (-half, -half), VISIT_BINS / (2 * half))

    # ---- saving and restoring ---------------------------------------------------------------------

    def get_state(self) -> dict[str, Any]:
        """Everything that determines what happens next, as plain data (numbers, lists, float arrays).

        Agent body (position, angle, velocity), sphere arrays, counters, the random generator's state
        and pymunk's contact cache; `set_state` on an environment made with the same arguments continues
        exactly as this one would. Nothing here is code: it can be stored as JSON plus ``.npz`` arrays.
        """
        return {
            "rng": self.np_random.bit_generator.state, "lifetime_step": self._lifetime_step,
            "episode_step": self._episode_step, "green_eaten": self._green_eaten, "red_eaten": self._red_eaten,
            "needs_reset": self._needs_reset, "ray_values": self._ray_values.copy(),
            "sphere_pos": self.spheres.pos.copy(), "sphere_vel": self.spheres.vel.copy(),
            "arena": self.arena.get_state(),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        """Continue from `get_state` output: rebuild the pymunk space and restore every value."""
        rng_state = state["rng"]
        if rng_state.get("bit_generator") != "PCG64":
            raise ValueError(f"saved random state is {rng_state.get('bit_generator')!r}, expected 'PCG64'")
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = rng_state
        pos, vel = np.asarray(state["sphere_pos"], np.float64), np.asarray(state["sphere_vel"], np.float64)
        if pos.shape != self.spheres.pos.shape or vel.shape != pos.shape:
            raise ValueError(f"saved spheres have shape {pos.shape}, this environment has {self.spheres.pos.shape}")
        self.np_random = rng
        self._lifetime_step, self._episode_step = int(state["lifetime_step"]), int(state["episode_step"])
        self._green_eaten, self._red_eaten = int(state["green_eaten"]), int(state["red_eaten"])
        self._needs_reset = bool(state["needs_reset"])
        self._laid_out = True
        self._ray_values = np.asarray(state["ray_values"], dtype=np.float32).copy()
        self.spheres.pos[:], self.spheres.vel[:] = pos, vel
        self.arena = Arena(self.params, self.spheres.green, moving=self.spheres.speed > 0)
        self.arena.set_state(state["arena"])

    # ---- small, documented test hooks ---------------------------------------------------------------

    def place_agent(self, position: tuple[float, float], heading: float = 90.0,
                    velocity: tuple[float, float] = (0.0, 0.0)) -> None:
        """Teleport the agent; ``heading`` is its forward direction in degrees counter-clockwise from +x."""
        self._require_reset()
        self.arena.place_agent(float(position[0]), float(position[1]), math.radians(heading - 90.0),
                               float(velocity[0]), float(velocity[1]))

    def place_sphere(self, index: int, position: tuple[float, float], direction: float | None = None) -> None:
        """Teleport sphere ``index`` (green below ``num_green``); ``direction`` (degrees) sets its heading."""
        self._require_reset()
        if not 0 <= index < self.params.num_spheres:
            raise IndexError(f"sphere index {index} outside [0, {self.params.num_spheres})")
        self.spheres.pos[index] = position
        if direction is not None:
            a = math.radians(direction)
            self.spheres.vel[index] = (self.spheres.speed * math.cos(a), self.spheres.speed * math.sin(a))
        self.arena.teleport_spheres(self.spheres.pos, self.spheres.vel, [index])

    @property
    def agent_heading(self) -> float:
        """The agent's forward direction, degrees counter-clockwise from world +x (not wrapped)."""
        return math.degrees(self.arena.agent.angle) + 90.0

    @property
    def agent_velocity(self) -> tuple[float, float]:
        """The agent's world velocity (vx, vy), units/s."""
        vx, vy = self.arena.agent.velocity
        return vx, vy

    @property
    def sphere_positions(self) -> np.ndarray:
        """A copy of the sphere centres, shape (num_spheres, 2); green first."""
        return self.spheres.pos.copy()

    @property
    def sphere_velocities(self) -> np.ndarray:
        """A copy of the sphere velocities, shape (num_spheres, 2), units/s."""
        return self.spheres.vel.copy()

    @property
    def sphere_is_green(self) -> np.ndarray:
        """A copy of the colour mask: True for green (food), False for red (badFood)."""
        return self.spheres.green.copy()

    def _require_reset(self) -> None:
        if self._needs_reset and self._episode_step == 0:
            raise RuntimeError("call reset() before placing objects")

