"""Rollout videos: a trained policy (or a uniform random one) in a task's test MDP or training env.

The policy is read from a run directory (or its ``checkpoint.pkl``) through the trainer itself
(`train.trainer.Trainer` resumed from the checkpoint), so a video shows exactly the network the run
evaluated. One seed of the run is chosen; it acts epsilon-greedily (epsilon 0.05 by default).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

VIDEO_EPSILON = 0.05
"""Exploration of the filmed policy (a little noise keeps a greedy agent from freezing in a loop)."""


@dataclass
class LoadedPolicy:
    """One seed's Q-network from a run, with the run's resolved config and environment facts."""

    cfg: Any
    """The run's `TrainConfig`."""
    trainer: Any
    """The resumed `Trainer` (its agent holds every seed's network)."""
    seed_index: int
    """Which of the run's seeds acts."""

    @property
    def seed(self) -> int:
        """The chosen agent's training seed."""
        return self.cfg.run.seed_list[self.seed_index]

    def greedy(self, obs: np.ndarray) -> int:
        """The chosen seed's greedy action for one observation."""
        import torch

        k = self.trainer.num_agents
        batch = torch.from_numpy(np.asarray(obs, dtype=np.float32)).view(1, 1, -1).expand(k, 1, -1)
        with torch.no_grad():
            return int(self.trainer.agent.greedy(batch.contiguous())[self.seed_index, 0])

    def close(self) -> None:
        """Release the trainer's environments."""
        self.trainer.close()


def resolve_run_dir(path: str | Path) -> Path:
    """The run directory of a run directory or of a checkpoint file inside one."""
    path = Path(path)
    run_dir = path.parent if path.is_file() else path
    if not (run_dir / "checkpoint.pkl").exists() or not (run_dir / "config.json").exists():
        raise FileNotFoundError(f"{path} is not a run directory with config.json and checkpoint.pkl "
                                f"(nor a checkpoint.pkl inside one)")
    return run_dir


def load_policy(path: str | Path, seed_index: int = 0) -> LoadedPolicy:
    """Load the network of seed number ``seed_index`` of the run at ``path`` (run dir or checkpoint)."""
    from train.config import TrainConfig
    from train.trainer import Trainer

    run_dir = resolve_run_dir(path)
    cfg = TrainConfig.from_dict(json.loads((run_dir / "config.json").read_text()))
    cfg = cfg.replace(progress=False, threads=1)
    if not 0 <= seed_index < cfg.run.seeds:
        raise ValueError(f"{run_dir} trained {cfg.run.seeds} seed(s); --agent must be in [0, {cfg.run.seeds})")
    trainer = Trainer(cfg, run_dir, resume=True)
    return LoadedPolicy(trainer.cfg, trainer, seed_index)


def env_kwargs_for(task: str, policy: LoadedPolicy | None, train_env: bool) -> dict[str, Any]:
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

    ``policy_path`` (a run directory or checkpoint) selects the trained policy of seed number ``seed_index``;
    without it a uniform random policy acts. ``steps`` defaults to the environment's horizon (one
    episode of the test MDP). ``seed`` seeds the layout and the exploration draws.
    """
    import gymnasium as gym

    from ecology import write_video
    from train.tasks import get_task

    policy = load_policy(policy_path, seed_index) if policy_path is not None else None
    try:
        if policy is not None:
            if task is not None and task != policy.cfg.env.task:
                raise ValueError(f"the run at {policy_path} trained task {policy.cfg.env.task!r}, not {task!r}")
            task = policy.cfg.env.task
        if task is None:
            raise ValueError("name a task or give a policy")
        spec = get_task(task)
        kwargs = env_kwargs_for(task, policy, train_env)
        env = gym.make(spec.env_id, render_mode="rgb_array", **kwargs)
        rng = np.random.default_rng(seed)
        n_actions = int(env.action_space.n)

        def act(obs: np.ndarray) -> int:
            if policy is None or rng.random() < epsilon:
                return int(rng.integers(n_actions))
            return policy.greedy(obs)

        n = steps if steps is not None else int(kwargs.get("horizon", 200))
        try:
            frames = rollout_frames(env, act, n, seed)
            fps = env.metadata.get("render_fps", 8)
        finally:
            env.close()
        return write_video(frames, out, fps=fps)
    finally:
        if policy is not None:
            policy.close()
