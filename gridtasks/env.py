"""Gymnasium front ends of the grid engine: one world (`GridTaskEnv`) and many (`GridTaskVectorEnv`).

Both hold the same rules record and call the same compiled kernels; the single environment is a batch
of one. A task is a subclass of `GridTaskEnv` that names its parameter dataclass (`Config`), its
observation channels, and fills the rules tables in `fill_rules`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ecology import Ecology, VisitGrid, check_action, check_render_mode, make_test_mdp_kwargs
from gridtasks import engine
from gridtasks.batch import (  # noqa: F401 (check_* are re-exported for the task modules)
    StepBuffers,
    check_actions,
    check_choice,
    check_flag,
    check_positive_int,
    check_probability,
    check_threads,
    reset_batch,
    step_batch,
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


class GridTaskEnv(gym.Env):
    """Base class of the grid tasks (see each task's docstring for its rules).

    Every task takes the four ecology knobs (``dynamism``, ``shaping``, ``reset_free``, ``reward``),
    ``render_mode`` and its own parameters (the fields of its ``Config``), all as keyword arguments.
    ``reset(seed=s)`` starts a new life (lifetime clock at 0, a world stream seeded from ``s``);
    ``reset()`` without a seed starts a new episode in the same life.
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
            raise TypeError(f"{cls.__name__} got unknown parameter(s) {unknown}; valid task parameters: "
                            f"{', '.join(names)} (plus dynamism, shaping, reset_free, reward, render_mode)")
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
        if isinstance(self.config, EpisodeRules):
            r["replay_unsolved"] = self.config.replay_unsolved
        self.fill_rules(r)
        self._check_room(r)
        return rules

    def _check_room(self, r: np.void) -> None:
        # Reset fills the grid before it draws the agent's cell (and the predators'): with no cell left
        # for them it would put the agent off the grid or search forever.
        free = int((r["layout"] == Code.EMPTY).sum())
        needed = int(r["initial"].sum()) + 1 + (1 if r["num_predators"] else 0)
        if needed > free:
            who = "the agent and a predator" if r["num_predators"] else "the agent"
            raise ValueError(f"{type(self).__name__} places {int(r['initial'].sum())} objects at reset, but its "
                             f"{self.config.grid_size}x{self.config.grid_size} grid has {free} free cells, "
                             f"{needed} with {who}; lower the object counts or raise grid_size")

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
        for a subgoal, a lost-progress penalty or a predator on the same step; 200 unless a task's ladder pays more.
        """
        r = self.rules[0]
        return float(max(r["completion_reward"], r["stage_reward"].max())) + 100.0

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
        return self._buffers.obs[0].copy(), self._info(False, False)

    def step(self, action):
        """Advance the world one step. Returns (obs, reward, terminated, truncated, info)."""
        if not self._seeded:
            raise RuntimeError("call reset() before step()")
        b = self._buffers
        b.actions[0] = check_action(action, engine.NUM_ACTIONS, engine.ACTION_NAMES)
        engine.step_worlds(self._state, self.rules, b.actions, b.obs, b.rewards, b.terminated, b.truncated,
                           b.solved, b.caught, False)
        info = self._info(bool(b.solved[0]), bool(b.caught[0]))
        return b.obs[0].copy(), float(b.rewards[0]), bool(b.terminated[0]), bool(b.truncated[0]), info

    def _info(self, solved: bool, caught: bool) -> dict:
        w = self._state[0]
        agent = w["agent"]
        info = {
            "solved": solved,
            "caught": caught,
            "agent_pos": (int(agent[0]), int(agent[1])),
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
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array'")
            return None
        if not self._seeded:
            raise RuntimeError("call reset() before render(): no world has been laid out yet")
        from gridtasks.render import render_world

        return render_world(self._state[0], self.rules[0], self.channels)


class GridTaskVectorEnv(VectorEnv):
    """Many worlds of one grid task stepped by one compiled call (Gymnasium next-step autoreset).

    ``reset(seed=s)`` seeds world i with ``s + i`` (or with ``seed[i]`` given a list); world i then
    follows exactly the trajectory of ``gymnasium.make(id)`` reset with that seed under the same actions.

    ``threads`` (default 1) shares the worlds of every step and reset out among that many of numba's
    threads (at most ``NUMBA_NUM_THREADS``, by default the number of CPUs). Each world draws only from its
    own random stream, so every number is the same as with one thread; the threaded kernels compile on
    first use. Threads pay only with cores to spare: on a machine whose cores other work keeps busy, waiting
    threads slow each call down (``benchmarks/bench_gridtasks.py --threads N`` measures the ratio; with
    numba's OpenMP layer, ``OMP_WAIT_POLICY=passive`` limits the loss). Trainers that step in a hot loop can
    call `step_arrays`, which skips the info dict.
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 8,
                                "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, env_class: type[GridTaskEnv], num_envs: int, copy: bool = True, threads: int = 1,
                 **kwargs):
        check_positive_int("num_envs", num_envs)
        self.threads = check_threads(threads)
        self.template = env_class(**kwargs)
        self.num_envs = int(num_envs)
        self.copy = copy
        self.render_mode = self.template.render_mode
        self.single_observation_space = self.template.observation_space
        self.single_action_space = self.template.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.rules = self.template.rules
        self._state = np.zeros(self.num_envs, dtype=engine.world_dtype(self.template.config.grid_size))
        self._buffers = StepBuffers(self.num_envs, self.single_observation_space.shape[0])
        self._seeded = False

    @property
    def ecology(self) -> Ecology:
        """The resolved ecology knobs shared by every world."""
        return self.template.ecology

    @property
    def worlds(self) -> np.ndarray:
        """The live state records of all worlds."""
        return self._state

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        """Reset every world (a new life for each when seeded). Returns (obs, info)."""
        if seed is None and self._seeded:
            keys = None
        elif seed is None:
            self._np_random, _ = seeding.np_random(None)
            keys = [world_key(self._np_random) for _ in range(self.num_envs)]
        else:
            seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, (int, np.integer)) else seed
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset got {len(seeds)} seeds for {self.num_envs} worlds")
            keys = [world_key(seeding.np_random(int(s))[0]) for s in seeds]
            self._np_random, _ = seeding.np_random(int(seeds[0]))
        if keys is not None:
            self._state["rng"] = np.array(keys, dtype=np.uint64)
            self._state["lifetime_step"] = 0
            self._state["replay_layout"] = False
            self._seeded = True
        reset_batch(self._state, self.rules, np.ones(self.num_envs, dtype=np.bool_), self._buffers.obs,
                    self.threads)
        return self._out(self._buffers.obs), self._info()

    def step(self, actions):
        """Step all worlds. Returns batched (obs, rewards, terminated, truncated, info)."""
        b = self._step_all(actions, "step")
        return (self._out(b.obs), self._out(b.rewards), self._out(b.terminated), self._out(b.truncated),
                self._info())

    def step_arrays(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """`step` without the info dict, for a trainer's hot loop: the same worlds, the same numbers.

        ``actions`` is an integer array of shape (num_envs,). Returns (obs, reward, terminated, truncated,
        agent_pos): float32 (num_envs, obs_dim), float64, bool, bool (num_envs,) and int64 (num_envs, 2)
        positions (x, y), as ``info["agent_pos"]``. With ``copy=False`` the first four are the env's own
        buffers, overwritten by the next call. ``info["solved"]`` and ``info["caught"]`` of the same step are
        `last_solved` and `last_caught`. Call it on the env itself (``vec.unwrapped``), not a wrapper.
        """
        b = self._step_all(actions, "step_arrays")
        return (self._out(b.obs), self._out(b.rewards), self._out(b.terminated), self._out(b.truncated),
                self._state["agent"].copy())

    def _step_all(self, actions, caller: str) -> StepBuffers:
        """Check ``actions``, step every world (next-step autoreset) and return the filled buffers."""
        if not self._seeded:
            raise RuntimeError(f"call reset() before {caller}()")
        b = self._buffers
        b.actions[:] = check_actions(actions, self.num_envs)
        step_batch(self._state, self.rules, b, True, self.threads)
        return b

    @property
    def last_solved(self) -> np.ndarray:
        """Which worlds completed their task on the last step (``info["solved"]``)."""
        return self._buffers.solved.copy()

    @property
    def last_caught(self) -> np.ndarray:
        """Which worlds were caught by a predator on the last step (``info["caught"]``)."""
        return self._buffers.caught.copy()

    def _out(self, array: np.ndarray) -> np.ndarray:
        return array.copy() if self.copy else array

    def _info(self) -> dict:
        s = self._state
        products = list(self.template.products)
        return {"solved": self.last_solved, "caught": self.last_caught, "agent_pos": s["agent"].copy(),
                "lifetime_step": s["lifetime_step"].copy(), "completions": s["completions"].copy(),
                "made": s["made"][:, products].sum(1),  # every product: what the trainer logs
                **{f"made_{NAMES[code]}": s["made"][:, code].copy() for code in products}}  # as the single env

    def render(self):
        """A tuple with one RGB frame per world."""
        from gridtasks.render import render_world

        if self.render_mode is None:
            return None
        if not self._seeded:
            raise RuntimeError("call reset() before render(): no world has been laid out yet")
        return tuple(render_world(w, self.rules[0], self.template.channels) for w in self._state)
