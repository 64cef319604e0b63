"""The batched engine's plumbing: argument checks, world seeds, step buffers, and the thread count of a call."""

from __future__ import annotations

from contextlib import contextmanager
from typing import Any

import numba
import numpy as np

from gridtasks import engine


def world_key(np_random: np.random.Generator) -> np.uint64:
    """Seed of a world's own random stream, drawn from the environment's seeded generator."""
    return np_random.integers(np.iinfo(np.uint64).max, dtype=np.uint64, endpoint=True)


def check_positive_int(name: str, value: Any, minimum: int = 1) -> None:
    """Raise a clear error unless ``value`` is an integer >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def check_flag(name: str, value: Any) -> None:
    """Raise a clear error unless ``value`` is True or False (a string such as 'no' would read as True)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")


def check_probability(name: str, value: Any) -> None:
    """Raise a clear error unless ``value`` is a number in [0, 1]."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not 0 <= value <= 1:
        raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> None:
    """Raise a clear error unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"unknown {name} {value!r}; choose one of {', '.join(choices)}")


def check_actions(actions, num_envs: int) -> np.ndarray:
    """Validate a batch of actions: shape (num_envs,), integers in [0, 7)."""
    a = np.asarray(actions)
    if a.shape != (num_envs,) or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"actions must be an integer array of shape ({num_envs},), got {a.dtype} {a.shape}")
    if a.size and (a.min() < 0 or a.max() >= engine.NUM_ACTIONS):
        raise ValueError(f"actions must lie in [0, {engine.NUM_ACTIONS - 1}], got values from {a.min()} "
                         f"to {a.max()}")
    return a


def check_threads(threads: Any) -> int:
    """The number of threads a vector env steps its worlds on: an integer from 1 to numba's pool size."""
    check_positive_int("threads", threads)
    pool = numba.config.NUMBA_NUM_THREADS
    if threads > pool:
        raise ValueError(f"threads={threads} exceeds numba's thread pool of {pool}; ask at most {pool} or set "
                         f"the environment variable NUMBA_NUM_THREADS before starting Python")
    return int(threads)


@contextmanager
def numba_threads(threads: int):
    """Run numba's parallel loops of the calling thread on ``threads`` threads, then restore the count."""
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


class StepBuffers:
    """Preallocated inputs and outputs of the step kernel for ``b`` worlds."""

    def __init__(self, b: int, obs_dim: int):
        self.actions = np.zeros(b, dtype=np.int64)
        self.obs = np.zeros((b, obs_dim), dtype=np.float32)
        self.rewards = np.zeros(b, dtype=np.float64)
        self.terminated = np.zeros(b, dtype=np.bool_)
        self.truncated = np.zeros(b, dtype=np.bool_)
        self.solved = np.zeros(b, dtype=np.bool_)
        self.caught = np.zeros(b, dtype=np.bool_)


def step_batch(state: np.ndarray, rules: np.ndarray, b: StepBuffers, autoreset: bool, threads: int = 1) -> None:
    """Step every world of ``state`` with ``b.actions`` into ``b`` (on ``threads`` threads; 1: the sequential
    loop). The result is the same whatever the number of threads.
    """
    args = (state, rules, b.actions, b.obs, b.rewards, b.terminated, b.truncated, b.solved, b.caught, autoreset)
    if threads == 1:
        engine.step_worlds(*args)
        return
    with numba_threads(threads):
        engine.step_worlds_threaded(*args)


def reset_batch(state: np.ndarray, rules: np.ndarray, mask: np.ndarray, obs: np.ndarray, threads: int = 1) -> None:
    """Reset the worlds of ``state`` that ``mask`` selects, writing their observations into ``obs``."""
    if threads == 1:
        engine.reset_worlds(state, rules, mask, obs)
        return
    with numba_threads(threads):
        engine.reset_worlds_threaded(state, rules, mask, obs)
