"""The evaluation side of each task: its test MDP and the fixed validation layouts."""

from __future__ import annotations

import numpy as np

from ecology import NUM_VALIDATION_LAYOUTS, validation_seeds


def _env_class(task: str):
    from gridtasks.registration import TASKS

    if task not in TASKS:
        raise ValueError(f"unknown grid task {task!r}; choose one of {', '.join(TASKS)}")
    return TASKS[task]


def test_mdp_kwargs(task: str, **train_kwargs) -> dict:
    """Keyword arguments of the test MDP that belongs to a training env built with ``train_kwargs``."""
    return _env_class(task)(**train_kwargs).test_mdp_kwargs()


def make_test_env(task: str, **train_kwargs):
    """One test-MDP environment (static, unshaped, episodic, sparse) for a training configuration."""
    return _env_class(task)(**test_mdp_kwargs(task, **train_kwargs))


def make_validation_envs(task: str, n: int = NUM_VALIDATION_LAYOUTS, copies: int = 1, threads: int = 1,
                         **train_kwargs):
    """A vector env of ``copies × n`` test-MDP worlds reset to the fixed validation layouts.

    World ``k·n + i`` holds layout i (seed ``ecology.validation_seeds()[i]``), so several agents can be
    evaluated on the same layouts in one batch; ``threads`` as `GridTaskVectorEnv`'s. Returns (vector env,
    first observations).
    """
    from gridtasks.vector import GridTaskVectorEnv

    vec = GridTaskVectorEnv(_env_class(task), num_envs=n * copies, threads=threads,
                            **test_mdp_kwargs(task, **train_kwargs))
    obs, _ = vec.reset(seed=validation_seeds(n) * copies)
    return vec, obs


def validation_layouts(task: str, n: int = NUM_VALIDATION_LAYOUTS, **train_kwargs) -> dict[str, np.ndarray]:
    """The initial grids (n, N, N) and agent cells (n, 2) of the validation layouts, for inspection."""
    vec, _ = make_validation_envs(task, n, **train_kwargs)
    return {"grid": vec.worlds["grid"].copy(), "agent": vec.worlds["agent"].copy()}
