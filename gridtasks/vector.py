"""Many worlds of one grid task stepped by one compiled call: `GridTaskVectorEnv`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ecology import Ecology, can_render, check_autoreset_mode, check_reset_mask
from gridtasks import engine
from gridtasks.batch import (
    StepBuffers,
    check_actions,
    check_flag,
    check_positive_int,
    check_threads,
    reset_batch,
    step_batch,
    world_key,
)
from gridtasks.codes import NAMES
from gridtasks.env import GridTaskEnv


def _is_int(value) -> bool:
    """An integer seed (Python's or numpy's; not a bool)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


class GridTaskVectorEnv(VectorEnv):
    """Many worlds of one grid task stepped by one compiled call (Gymnasium next-step autoreset by default).

    ``reset(seed=s)`` seeds world i with ``s + i`` (or with ``seed[i]`` given a list); world i then
    follows exactly the trajectory of ``gymnasium.make(id)`` reset with that seed under the same actions.

    ``threads`` (default 1) shares the worlds of every step and reset out among that many of numba's
    threads (at most ``NUMBA_NUM_THREADS``, by default the number of CPUs). Each world draws only from its
    own random stream, so every number is the same as with one thread; the threaded kernels compile on
    first use. Threads pay only with cores to spare: on a machine whose cores other work keeps busy, waiting
    threads slow each call down (``benchmarks/bench_gridtasks.py --threads N`` measures the ratio; with
    numba's OpenMP layer, ``OMP_WAIT_POLICY=passive`` limits the loss). Trainers that step in a hot loop can
    call `step_arrays`, which skips the info dict.

    ``autoreset_mode`` (`gymnasium.vector.AutoresetMode`, passed to ``make_vec`` as a keyword) chooses what
    follows an episode's end, as ``SyncVectorEnv`` does: ``NEXT_STEP`` (default) resets the world on the next
    step, which returns reward 0 and ignores its action; ``SAME_STEP`` resets it at once, returning the reset
    observation and info, the last ones in ``info["final_obs"]`` and ``info["final_info"]`` (masks
    ``"_final_obs"``, ``"_final_info"``); ``DISABLED`` leaves the reset to you (``reset(options={"reset_mask":
    ...})``), and stepping an ended world is an error. Reset-free worlds never end, so the modes agree there.
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 8,
                                "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, env_class: type[GridTaskEnv], num_envs: int, copy: bool = True, threads: int = 1,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, **kwargs):
        check_positive_int("num_envs", num_envs)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        check_flag("copy", copy)
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

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Reset every world, or those ``options["reset_mask"]`` selects (Gymnasium's boolean mask of shape
        (num_envs,)); a seed starts a new life in each world it resets (world i takes ``seed + i``, or
        ``seed[i]`` given one int or None per world: None continues that world's life, as ``reset()`` does).
        Returns (obs, info) of every world.
        """
        mask = self._reset_mask(options)
        keys, lives = self._new_lives(seed)
        lives &= mask
        self._state["rng"][lives] = keys[lives]
        self._state["lifetime_step"][lives] = 0
        self._state["replay_layout"][lives] = False
        self._seeded = True
        reset_batch(self._state, self.rules, mask, self._buffers.obs, self.threads)
        self._buffers.solved[mask] = False  # a fresh episode has solved nothing and met no predator yet
        self._buffers.caught[mask] = False
        return self._out(self._buffers.obs), self._info()

    def _reset_mask(self, options: dict | None) -> np.ndarray:
        """The worlds a reset resets: all, or ``options["reset_mask"]`` (other options are ignored)."""
        mask = check_reset_mask(options, self.num_envs)
        if mask is None:
            return np.ones(self.num_envs, dtype=np.bool_)
        if not self._seeded and not mask.all():
            raise RuntimeError("the first reset() lays out every world: call it without reset_mask")
        return mask.copy()

    def _new_lives(self, seed) -> tuple[np.ndarray, np.ndarray]:
        """(each world's new random-stream key, which worlds start a new life) for ``seed``: the worlds given an
        int, and on the first reset every world (fresh entropy where its seed is None).
        """
        if seed is None or _is_int(seed):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        elif isinstance(seed, (list, tuple, range, np.ndarray)) and all(s is None or _is_int(s) for s in seed):
            seeds = [None if s is None else int(s) for s in seed]
        else:
            held = {type(s).__name__ for s in seed} if isinstance(seed, (list, tuple, np.ndarray)) else set()
            raise TypeError(f"reset's seed must be an int, or one int or None per world, got "
                            f"{type(seed).__name__}" + (f" of {', '.join(sorted(held))}" if held else ""))
        if len(seeds) != self.num_envs:
            raise ValueError(f"reset got {len(seeds)} seeds for {self.num_envs} worlds")
        lives = np.array([s is not None or not self._seeded for s in seeds], dtype=np.bool_)
        if lives.any():
            self._np_random, _ = seeding.np_random(next((s for s in seeds if s is not None), None))
        keys = [world_key(seeding.np_random(s)[0]) if new else 0 for s, new in zip(seeds, lives)]
        return np.array(keys, dtype=np.uint64), lives

    def step(self, actions):
        """Step all worlds. Returns batched (obs, rewards, terminated, truncated, info)."""
        b = self._step_all(actions, "step")
        ended = b.terminated | b.truncated
        if self.autoreset_mode != AutoresetMode.SAME_STEP or not ended.any():
            return (self._out(b.obs), self._out(b.rewards), self._out(b.terminated), self._out(b.truncated),
                    self._info())
        final_obs = np.full(self.num_envs, None, dtype=object)  # one array per ended world, as Sync gives
        for i in np.flatnonzero(ended):
            final_obs[i] = b.obs[i].copy()
        final_info = self._info()
        reset_batch(self._state, self.rules, ended, b.obs, self.threads)
        info = self._info(solved=b.solved & ~ended, caught=b.caught & ~ended)  # the reset worlds' info is their reset's
        info.update(final_obs=final_obs, _final_obs=ended.copy(), _final_info=ended.copy(),
                    final_info=_masked(final_info, ended))
        return (self._out(b.obs), self._out(b.rewards), self._out(b.terminated), self._out(b.truncated), info)

    def step_arrays(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """`step` without the info dict, for a trainer's hot loop: the same worlds, the same numbers.

        ``actions`` is an integer array of shape (num_envs,). Returns (obs, reward, terminated, truncated,
        agent_pos): float32 (num_envs, obs_dim), float64, bool, bool (num_envs,) and int64 (num_envs, 2)
        positions (x, y), as ``info["agent_pos"]``. With ``copy=False`` the first four are the env's own
        buffers, overwritten by the next call. ``info["solved"]`` and ``info["caught"]`` of the same step are
        `last_solved` and `last_caught`. Call it on the env itself (``vec.unwrapped``), not a wrapper.
        """
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            raise RuntimeError("step_arrays() returns no final observation, which autoreset_mode SAME_STEP needs: "
                               "call step(), or make the env with NEXT_STEP or DISABLED")
        b = self._step_all(actions, "step_arrays")
        return (self._out(b.obs), self._out(b.rewards), self._out(b.terminated), self._out(b.truncated),
                self._state["agent"].copy())

    def _step_all(self, actions, caller: str) -> StepBuffers:
        """Check ``actions``, step every world (next-step autoreset) and return the filled buffers."""
        if not self._seeded:
            raise RuntimeError(f"call reset() before {caller}()")
        b = self._buffers
        b.actions[:] = check_actions(actions, self.num_envs)
        if self.autoreset_mode == AutoresetMode.DISABLED and self._state["needs_reset"].any():
            ended = np.flatnonzero(self._state["needs_reset"]).tolist()
            raise RuntimeError(f"world(s) {ended} ended on an earlier step and autoreset_mode is DISABLED: reset "
                               f"them with reset(options={{'reset_mask': ...}}) before {caller}()")
        step_batch(self._state, self.rules, b, self.autoreset_mode == AutoresetMode.NEXT_STEP, self.threads)
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

    def _info(self, solved: np.ndarray | None = None, caught: np.ndarray | None = None) -> dict:
        """The batched info of every world's current state, with Gymnasium's ``_key`` masks (every world reports
        every key); ``solved`` and ``caught`` default to the last step's.
        """
        s = self._state
        products = list(self.template.products)
        solved = self.last_solved if solved is None else solved
        caught = self.last_caught if caught is None else caught
        info = {"solved": solved, "caught": caught, "agent_pos": s["agent"].astype(np.int64),
                "lifetime_step": s["lifetime_step"].copy(), "completions": s["completions"].copy(),
                **{f"pickup_{NAMES[code]}": s["pickups"][:, code].copy() for code in self.template.counted},
                **{f"made_{NAMES[code]}": s["made"][:, code].copy() for code in products},
                "made": s["made"][:, products].sum(1)}  # beyond the single env's keys: every product, as logged
        return info | {f"_{key}": np.ones(self.num_envs, dtype=np.bool_) for key in info}

    def render(self):
        """A tuple with one RGB frame per world, or None without a render mode."""
        from gridtasks.render import render_world

        if not can_render(self.render_mode, self._seeded):
            return None
        return tuple(render_world(w, self.rules[0], self.template.channels) for w in self._state)


def _masked(info: dict, mask: np.ndarray) -> dict:
    """``info`` as ``SyncVectorEnv`` gathers it from the worlds in ``mask``: each value zero elsewhere, with its
    ``_key`` mask.
    """
    out = {}
    for key, value in info.items():
        if key.startswith("_"):  # the masks: this one's is ``mask``
            continue
        out[key] = np.where(mask.reshape(-1, *[1] * (value.ndim - 1)), value, 0).astype(value.dtype)
        out[f"_{key}"] = mask.copy()
    return out
