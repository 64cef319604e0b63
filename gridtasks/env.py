"""The Gymnasium front end of the grid engine for one world (`GridTaskEnv`; many: `gridtasks.vector`).

Both hold the same rules record and call the same compiled kernels; the single environment is a batch
of one. A task is a subclass of `GridTaskEnv` that names its parameter dataclass (`Config`), its
observation channels, and fills the rules tables in `fill_rules`.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass
from typing import ClassVar

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
)
from gridtasks import engine
from gridtasks.batch import (  # noqa: F401 (check_* are re-exported for the task modules)
    StepBuffers,
    check_actions,
    check_choice,
    check_flag,
    check_positive_int,
    check_probability,
    check_threads,
    world_key,
)
from gridtasks.codes import NAMES, Code

MAX_GRID_SIZE = 256
"""Largest grid side a task accepts (the paper's grids are 8 to 10 cells; a world costs 5 bytes per cell)."""


@dataclass(frozen=True)
class EpisodeRules:
    """How episodic worlds restart (every grid task inherits these fields)."""

    replay_unsolved: int = 0
    """The original training loop's episodic reset rule: after an episode that ended unsolved the same
    layout is played again, and every ``replay_unsolved`` steps of the world's clock (the original's
    500-step collections) the episode is cut and a fresh layout drawn. 0 (default): a fresh layout every
    episode. Ignored by reset-free worlds and off in the test MDP."""

    def __post_init__(self) -> None:
        check_positive_int("replay_unsolved", self.replay_unsolved, 0)
        for f in dataclasses.fields(self):  # every task's on/off parameters (walls, replenish, ...)
            if f.type == "bool":
                check_flag(f.name, getattr(self, f.name))
                object.__setattr__(self, f.name, bool(getattr(self, f.name)))


SPAWN_WINDOWS = ("original", "shifted")
"""The rules of the shaping window beside a wall (`SpawnRules.spawn_window`)."""


@dataclass(frozen=True)
class SpawnRules(EpisodeRules):
    """Where and how many new objects grow: the original code's rules by default, ours as options.

    Task parameter dataclasses whose objects grow or are replenished (salad, hunting, scavenging)
    inherit these fields; docs/fidelity.md gives each option's measured effect.
    """

    spawn_on_agent: bool = True
    """New objects may grow on the agent's own cell (only its start cell is excluded), as in the original,
    where the agent can pick one up on the next step without moving. False: never under the agent."""
    count_carried: bool = False
    """Replenishment also counts the carried object. False (original): only the grid counts, so picking up
    the last lettuce grows a new one at once and hunting keeps 2 axes on the grid while one is carried."""
    spawn_window: str = "original"
    """Where the shaping window lies beside a wall. 'original' (the original code's rule): its corner is the
    agent's cell minus half its side, clipped at the grid's edge, and the wall cells in it take nothing, so
    near a wall it holds fewer interior cells (in a corner a 2-cell window holds only the agent's cell).
    'shifted' (ecorl's rule until 2026-12-07): moved inside the wall ring, so it always holds side × side
    interior cells."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_choice("spawn_window", self.spawn_window, SPAWN_WINDOWS)


DIRECTED_MOVES = ("original", "current-free")
"""The rules of a step toward or away from the agent (`DirectedMoves.directed_moves`)."""


@dataclass(frozen=True)
class DirectedMoves(EpisodeRules):
    """How creatures that step toward or away from the agent choose the step (hunting's easy and hard deer,
    factory's cooperative workers); docs/fidelity.md gives the rules' measured effect.
    """

    directed_moves: str = "original"
    """'original' (the original code's rule): the first best of N, W, S, E, stay for the creature's aim, taken
    only if its cell holds no object (a blocked creature stays); workers and hard deer aim at the agent's cell
    before its move this step, easy deer at its cell after it. 'current-free' (ecorl's rule until 2026-12-07):
    the best step among the free cells, aiming at the agent's cell after its move."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_choice("directed_moves", self.directed_moves, DIRECTED_MOVES)

    def fill_directed_rules(self, r: np.void, aim_before_move: tuple[int, ...]) -> None:
        """Set the engine's directed-step rule; ``aim_before_move``: the codes that the original code aims at the
        agent's cell before its move.
        """
        original = self.directed_moves == "original"
        r["blocked_directed_stays"] = original
        for code in aim_before_move:
            r["aim_before_move"][code] = original


class GridTaskEnv(gym.Env):
    """Base class of the grid tasks (see each task's docstring for its rules).

    Every task takes the four ecology knobs (``dynamism``, ``shaping``, ``reset_free``, ``reward``),
    ``render_mode`` and its own parameters (the fields of its ``Config``), all as keyword arguments.
    ``reset(seed=s)`` starts a new life (lifetime clock at 0, a world stream seeded from ``s``);
    ``reset()`` without a seed starts a new episode in the same life. After an episode ends, ``step`` refuses
    until ``reset``. ``info["agent_pos"]`` is an int64 array (x, y).

    The ids are registered without ``max_episode_steps``: an episodic world truncates itself at ``horizon``
    and a reset-free one never ends, so a wrapper that reads ``spec.max_episode_steps`` (``TimeAwareObservation``)
    needs ``gymnasium.make(id, horizon=H, max_episode_steps=H)``.
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 8}
    Config: ClassVar[type]
    channels: ClassVar[tuple[Code, ...]]
    counted: ClassVar[tuple[Code, ...]] = ()
    """Codes whose pick-ups are reported in ``info`` (``pickup_<name>``)."""
    products: ClassVar[tuple[Code, ...]] = ()
    """Codes whose products are reported in ``info`` (``made_<name>``)."""

    def __init__(self, dynamism=0.0, shaping=0.0, reset_free=False, reward="sparse", render_mode=None,
                 **params):
        self.ecology = Ecology(dynamism=dynamism, shaping=shaping, reset_free=reset_free, reward=reward)
        self.config = self._make_config(params)
        if self.config.grid_size > MAX_GRID_SIZE:
            raise ValueError(f"grid_size must be at most {MAX_GRID_SIZE}, got {self.config.grid_size}")
        self.render_mode = check_render_mode(render_mode, self.metadata["render_modes"])
        self.rules = self._build_rules()
        c = len(self.channels)
        self.observation_space = spaces.Box(0.0, 1.0, (c * engine.VIEW_CELLS + c,), np.float32)
        self.action_space = spaces.Discrete(engine.NUM_ACTIONS)
        self._state = np.zeros(1, dtype=engine.world_dtype(self.config.grid_size))
        self._buffers = StepBuffers(1, self.observation_space.shape[0])
        self._seeded = False
        self._ended: str | None = None
        self._info_keys = [(f"pickup_{NAMES[c]}", int(c)) for c in self.counted]

    # ---------------------------------------------------------------- construction

    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        """The task parameters this task takes as keyword arguments: the fields of its ``Config``."""
        return tuple(f.name for f in dataclasses.fields(cls.Config))

    @classmethod
    def _make_config(cls, params: dict):
        names = cls.parameter_names()
        unknown = sorted(set(params) - set(names))
        if unknown:
            knobs = ("dynamism", "shaping", "reset_free", "reward", "render_mode")
            near = [m for u in unknown for m in difflib.get_close_matches(u, (*knobs, *names), n=1)]
            hint = f" (did you mean {', '.join(near)}?)" if near else ""
            raise TypeError(f"{cls.__name__} got unknown parameter(s) {unknown}{hint}; the knobs: {', '.join(knobs)}; "
                            f"valid task parameters: {', '.join(names)}")
        return cls.Config(**params)

    def _build_rules(self) -> np.ndarray:
        n = self.config.grid_size
        rules = engine.new_rules(n)
        r = rules[0]
        r["num_channels"] = len(self.channels)
        for index, code in enumerate(self.channels):
            r["channel"][code] = index
        r["reset_free"] = self.ecology.reset_free
        r["horizon"] = self.config.horizon
        r["reward_mode"] = engine.REWARD_MODE_IDS[self.ecology.reward]
        bp = self.ecology.shaping.breakpoints
        if len(bp) > engine.MAX_BREAKPOINTS:
            raise ValueError(f"a shaping schedule may have at most {engine.MAX_BREAKPOINTS} breakpoints")
        r["shaping"][: len(bp)] = bp
        r["num_breakpoints"] = len(bp)
        if isinstance(self.config, SpawnRules):
            r["spawn_on_agent"] = self.config.spawn_on_agent
            r["count_carried"] = self.config.count_carried
            r["shifted_window"] = self.config.spawn_window == "shifted"
        if isinstance(self.config, EpisodeRules):
            r["replay_unsolved"] = self.config.replay_unsolved
        self.fill_rules(r)
        self._check_room(r)
        return rules

    def _check_room(self, r: np.void) -> None:
        # Reset fills the grid before it draws the agent's cell (and the predators'): with no cell left
        # for them it would put the agent off the grid or search forever.
        free = int((r["layout"] == Code.EMPTY).sum())
        objects = int(r["initial"].sum())
        needed = objects + 1 + (1 if r["num_predators"] else 0)
        if needed > free:
            what = f"{objects} objects, the agent and a predator" if r["num_predators"] else \
                f"{objects} objects and the agent"
            size = self.config.grid_size
            raise ValueError(f"{type(self).__name__} needs {needed} free cells at reset ({what}), but its "
                             f"{size}x{size} grid has {free}; lower the object counts or raise grid_size")

    def fill_rules(self, r: np.void) -> None:
        """Write the task's tables into the rules record ``r`` (dynamism and shaping included)."""
        raise NotImplementedError

    def test_overrides(self) -> dict:
        """Task parameters that differ between this task's training env and its test MDP."""
        return {}

    def test_mdp_kwargs(self) -> dict:
        """Keyword arguments that make this environment's evaluation MDP with ``gymnasium.make``: the same
        task parameters, the test MDP's knobs, the task's test overrides and its test horizon (the
        ``horizon`` default of its ``Config``, whatever episode length this env trains with).
        """
        test_horizon = {f.name: f.default for f in dataclasses.fields(self.Config)}["horizon"]
        replay = {"replay_unsolved": 0} if isinstance(self.config, EpisodeRules) else {}
        overrides = {**replay, **self.test_overrides()}
        return make_test_mdp_kwargs(dataclasses.asdict(self.config), test_horizon, **overrides)

    @property
    def observation_split(self) -> tuple[int, int]:
        """(view inputs, inventory inputs) of the observation: the two branches of the paper's network."""
        c = len(self.channels)
        return c * engine.VIEW_CELLS, c

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(rows, columns) of the grid, the shape of visitation maps indexed [y, x]."""
        return self.config.grid_size, self.config.grid_size

    @property
    def reward_bound(self) -> float:
        """The largest |reward| one step can give: completing the task (or reaching the best-paid stage) plus 100
        for a subgoal or a lost-progress penalty, or plus a predator's cost where that is larger, on the same step;
        200 unless a task's ladder or its predators cost more.
        """
        r = self.rules[0]
        return float(max(r["completion_reward"], r["stage_reward"].max())) + max(100.0, float(r["predator_penalty"]))

    @property
    def visit_grid(self) -> VisitGrid:
        """Visitation maps of the grid tasks count whole cells: the agent's (x, y) is cell [y, x], inside a
        one-cell wall ring.
        """
        return VisitGrid(self.grid_shape, wall=1)

    @property
    def world(self) -> np.void:
        """The live state record of this environment's world (for inspection and tests)."""
        return self._state[0]

    # ---------------------------------------------------------------- gymnasium API

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode; with a seed (or on first use) also start a new life. Returns (obs, info)."""
        super().reset(seed=seed)
        if seed is not None or not self._seeded:
            self._state["rng"][0] = world_key(self.np_random)
            self._state["lifetime_step"][0] = 0
            self._state["replay_layout"][0] = False
            self._seeded = True
        engine.reset_worlds(self._state, self.rules, np.ones(1, dtype=np.bool_), self._buffers.obs)
        self._ended = None
        return self._buffers.obs[0].copy(), self._info(False, False)

    def step(self, action):
        """Advance the world one step. Returns (obs, reward, terminated, truncated, info).

        After an episode ends (terminated or truncated) the next call must be ``reset()``, as in the food
        collector; a reset-free world never ends.
        """
        if not self._seeded:
            raise RuntimeError("call reset() before step()")
        if self._ended:
            raise RuntimeError(f"the episode ended ({self._ended}); call reset()")
        b = self._buffers
        b.actions[0] = check_action(action, engine.NUM_ACTIONS, engine.ACTION_NAMES)
        engine.step_worlds(self._state, self.rules, b.actions, b.obs, b.rewards, b.terminated, b.truncated,
                           b.solved, b.caught, False)
        terminated, truncated = bool(b.terminated[0]), bool(b.truncated[0])
        if terminated or truncated:
            self._ended = "terminated" if terminated else "truncated"
        info = self._info(bool(b.solved[0]), bool(b.caught[0]))
        return b.obs[0].copy(), float(b.rewards[0]), terminated, truncated, info

    def _info(self, solved: bool, caught: bool) -> dict:
        w = self._state[0]
        agent = w["agent"]
        info = {
            "solved": solved,
            "caught": caught,
            "agent_pos": agent.astype(np.int64),  # an array (x, y), so that every vector mode stacks it
            "lifetime_step": int(w["lifetime_step"]),
            "completions": int(w["completions"]),
        }
        pickups, made = w["pickups"], w["made"]
        for key, code in self._info_keys:
            info[key] = int(pickups[code])
        for code in self.products:
            info[f"made_{NAMES[code]}"] = int(made[code])
        return info

    def render(self):
        """An RGB frame of the world (``render_mode='rgb_array'``), or None without a render mode."""
        if not can_render(self.render_mode, self._seeded):
            return None
        from gridtasks.render import render_world

        return render_world(self._state[0], self.rules[0], self.channels)
