"""Rollout videos: a trained policy (or a uniform random one) in a task's test MDP or training env.

The policy is one seed's network from a run directory, its ``checkpoint.pkl``, or a policy file
(`train.policy`); it acts epsilon-greedily (epsilon 0.05 by default).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from train.policy import Policy, load_policy

VIDEO_EPSILON = 0.05
"""Exploration of the filmed policy (a little noise keeps a greedy agent from freezing in a loop)."""


def env_kwargs_for(task: str, policy: Policy | None, train_env: bool) -> dict[str, Any]:
    """Keyword arguments of the filmed environment: the test MDP, or the training env with ``train_env``."""
    from train.config import EnvConfig
    from train.tasks import get_task, probe

    env_cfg = policy.cfg.env if policy is not None else EnvConfig(task=task)
    if train_env:
        return dict(env_cfg.env_make_kwargs)
    kwargs = dict(probe(get_task(task), env_cfg).test_kwargs)
    if policy is not None and policy.cfg.eval.eval_horizon:
        kwargs["horizon"] = policy.cfg.eval.eval_horizon
    return kwargs


def rollout_frames(env, act: Callable[[np.ndarray], int], steps: int, seed: int) -> list[np.ndarray]:
    """Frames of ``steps`` steps of ``act`` in ``env`` (a new episode after each end), first frame included."""
    obs, _ = env.reset(seed=seed)
    frames = [env.render()]
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(act(obs))
        frames.append(env.render())
        if terminated or truncated:
            obs, _ = env.reset()
            frames.append(env.render())
    return frames


def record_video(task: str | None, out: str | Path, policy_path: str | Path | None = None, steps: int | None = None,
                 seed: int = 0, seed_index: int = 0, train_env: bool = False,
                 epsilon: float = VIDEO_EPSILON) -> Path:
    """Write an MP4 of one rollout and return its path.

    ``policy_path`` (a run directory, checkpoint or policy file) selects the trained policy (of seed number
    ``seed_index`` of a run); without it a uniform random policy acts. ``steps`` defaults to the
    environment's horizon (one episode of the test MDP). ``seed`` seeds the layout and the exploration draws.
    """
    import gymnasium as gym

    from ecology import write_video
    from train.tasks import get_task

    policy = load_policy(policy_path, seed_index) if policy_path is not None else None
    if policy is not None:
        if task is not None and task != policy.task:
            raise ValueError(f"the policy at {policy_path} was trained on {policy.task!r}, not {task!r}")
        task = policy.task
    if task is None:
        raise ValueError("name a task or give a policy")
    kwargs = env_kwargs_for(task, policy, train_env)
    env = gym.make(get_task(task).env_id, render_mode="rgb_array", **kwargs)
    rng = np.random.default_rng(seed)
    n_actions = int(env.action_space.n)

    def act(obs: np.ndarray) -> int:
        if policy is None or rng.random() < epsilon:
            return int(rng.integers(n_actions))
        return policy.act(obs)

    n = steps if steps is not None else int(kwargs.get("horizon", 200))
    try:
        frames = rollout_frames(env, act, n, seed)
        fps = env.metadata.get("render_fps", 8)
    finally:
        env.close()
    return write_video(frames, out, fps=fps)
