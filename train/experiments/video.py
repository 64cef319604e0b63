"""Rollout videos: a trained policy (or a uniform random one) in a task's test MDP or training env.

The policy is one seed's network from a run directory, its ``checkpoint.npz``, or a policy file
(`train.storage.policy`); it acts epsilon-greedily (epsilon 0.05 by default).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from train.storage.fileio import atomic_path, atomic_write
from train.storage.policy import Policy, load_policy

H264_OPTIONS = ("-f", "mp4", "-threads", "1", "-movflags", "+faststart", "-map_metadata", "-1", "-fflags", "+bitexact",
                "-flags:v", "+bitexact", "-preset", "medium", "-crf", "20")
"""ffmpeg output options of every MP4 we write: one encoder thread and no metadata, so that the same frames
give the same bytes; faststart so that a browser plays it before the whole file is loaded."""


def write_h264(frames: Iterable[np.ndarray], path: str | Path, fps: float = 8.0) -> Path:
    """Write RGB uint8 frames (a sequence, or an iterable read one at a time) as an H.264 MP4 (yuv420p: it plays in
    every browser) at ``path``, atomically.

    Uses the ffmpeg binary that the ``imageio-ffmpeg`` package ships; odd frame sizes are padded by one black
    row or column (H.264 in yuv420p needs even sizes).
    """
    import imageio_ffmpeg

    frames = iter(frames)
    first = next(frames, None)
    if first is None:
        raise ValueError(f"no frames to write to {path}")
    frames = itertools.chain([first], frames)
    h, w = np.asarray(first).shape[:2]
    ph, pw = h + h % 2, w + w % 2
    with atomic_path(path) as tmp:
        writer = imageio_ffmpeg.write_frames(str(tmp), (pw, ph), fps=float(fps), codec="libx264",
                                             pix_fmt_out="yuv420p", macro_block_size=1, ffmpeg_log_level="error",
                                             output_params=list(H264_OPTIONS))
        writer.send(None)  # start ffmpeg
        try:
            for frame in frames:
                frame = np.asarray(frame, dtype=np.uint8)
                if frame.shape[:2] != (h, w):
                    raise ValueError(f"frame of size {frame.shape[:2]}, expected {(h, w)}")
                writer.send(np.ascontiguousarray(np.pad(frame, ((0, ph - h), (0, pw - w), (0, 0)))))
        finally:
            writer.close()
    return Path(path)

STRIP_FRAMES = 12
"""Most frames in a filmstrip (the paper's Fig. 11-12 show an episode as a row of frames)."""
STRIP_HEIGHT = 160
"""Height in pixels of each frame of a filmstrip."""


def write_filmstrip(frames: Sequence[np.ndarray], path: str | Path, count: int = STRIP_FRAMES) -> Path:
    """One episode's RGB frames as a PNG row of at most ``count`` of them, each labelled with its step: all
    frames of a short episode, else ``count`` evenly spaced from the first to the last.
    """
    import cv2

    if not len(frames):
        raise ValueError(f"no frames for the filmstrip {path}")
    steps = np.unique(np.linspace(0, len(frames) - 1, min(count, len(frames))).round().astype(int))
    tiles = []
    for step in steps:
        frame = np.asarray(frames[step], dtype=np.uint8)[:, :, :3]
        width = max(1, round(frame.shape[1] * STRIP_HEIGHT / frame.shape[0]))
        tile = cv2.resize(frame, (width, STRIP_HEIGHT), interpolation=cv2.INTER_NEAREST)
        tile = cv2.copyMakeBorder(tile, 20, 2, 2, 2, cv2.BORDER_CONSTANT, value=(255, 255, 255))
        cv2.putText(tile, f"t = {step}", (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        tiles.append(tile)
    ok, png = cv2.imencode(".png", np.ascontiguousarray(np.concatenate(tiles, axis=1)[:, :, ::-1]))
    if not ok:
        raise ValueError(f"could not encode the filmstrip {path}")
    return atomic_write(path, png.tobytes())


VIDEO_EPSILON = 0.05
"""Exploration of the filmed policy (a little noise keeps a greedy agent from freezing in a loop)."""

VIDEO_EPISODES = 3
"""Episodes filmed by default: one episode shows a single layout, a few show what the policy usually does."""

VIDEO_MAX_FRAMES = 1_000
"""No further episode starts once a film of whole episodes holds this many frames: a food-collector episode is
1 000 decisions (a 512 x 512 frame each, 1.8 MB of H.264), so it is filmed once; three grid episodes of at most
200 steps always fit, and two unsolved walled-salad ones (500 steps) end the film."""


def env_kwargs_for(task: str, policy: Policy | None, train_env: bool) -> dict[str, Any]:
    """Keyword arguments of the filmed environment: the test MDP, or the training env with ``train_env``."""
    from train.config import EnvConfig
    from train.tasks import get_task, probe

    if policy is not None:
        return dict(policy.cfg.env.env_make_kwargs) if train_env else policy.test_kwargs
    env_cfg = EnvConfig(task=task)
    return dict(env_cfg.env_make_kwargs) if train_env else dict(probe(get_task(task), env_cfg).test_kwargs)


@dataclass(frozen=True)
class Film:
    """A filmed rollout: its frames and how its episodes went."""

    frames: list[np.ndarray]
    """Rendered frames, the first reset included."""
    episodes: int
    """Episodes started in the film (the last may be cut off)."""
    solved: int
    """Episodes in which the task was solved (``info["solved"]``)."""
    total_return: float
    """Sum of the rewards over the film."""
    first_episode: int
    """Frames of the first episode (its reset frame to its last step)."""
    ended: int
    """Episodes that ended inside the film (``episodes - ended`` is the one cut off by a film of so many steps)."""
    steps: int
    """Environment steps filmed."""


def film_rollout(env, act: Callable[[np.ndarray], int], seed: int, steps: int | None = None,
                 episodes: int = 1, max_frames: int | None = None) -> Film:
    """Film ``act`` in ``env`` from a reset with ``seed``: exactly ``steps`` steps (a new episode after each
    end) or, without ``steps``, ``episodes`` whole episodes, fewer where the film already holds ``max_frames``
    frames when one ends (the first episode is always whole). The first frame is included.
    """
    obs, _ = env.reset(seed=seed)
    frames, started, ended, solved, solved_now, taken, total = [env.render()], 1, 0, 0, False, 0, 0.0
    first_episode = None
    while steps is None or taken < steps:
        obs, reward, terminated, truncated, info = env.step(act(obs))
        frames.append(env.render())
        taken += 1
        total += float(reward)
        solved_now |= bool(info.get("solved", False))
        if terminated or truncated:
            first_episode = first_episode or len(frames)
            solved, solved_now, ended = solved + solved_now, False, ended + 1
            enough = started == episodes or (max_frames is not None and len(frames) >= max_frames)
            if (steps is None and enough) or taken == steps:
                break
            obs, _ = env.reset()
            frames.append(env.render())
            started += 1
    return Film(frames, started, solved + solved_now, total, first_episode or len(frames), ended, taken)


@dataclass(frozen=True)
class Video:
    """A written video file and the rollout it shows."""

    path: Path
    """The MP4."""
    episodes: int
    """Episodes started in it."""
    solved: int
    """Episodes solved in it."""
    total_return: float
    """Sum of the rewards over the film."""
    metric: str
    """The task's evaluation metric, 'success' or 'return' (`train.tasks.Task.metric`)."""
    strip: Path | None = None
    """The filmstrip of the first episode, if one was asked for."""
    ended: int | None = None
    """Episodes that ended inside the film (None: all of them; fewer when a film of so many steps cut the last)."""
    steps: int = 0
    """Environment steps filmed."""

    def summary(self) -> str:
        """One line on how the filmed episodes went, in the task's metric; a film cut inside an episode says so
        rather than count the part as an episode.
        """
        if self.ended is not None and self.ended < self.episodes:
            whole = f"{self.ended} whole episode(s) and part of one more" if self.ended else "part of one episode"
            if self.metric == "return":
                return f"return {self.total_return:.1f} over the {self.steps} steps filmed ({whole})"
            return f"{self.solved} solve(s) in the {self.steps} steps filmed ({whole})"
        if self.metric == "return":
            return f"mean return {self.total_return / self.episodes:.1f} over the {self.episodes} episode(s) filmed"
        return f"solved {self.solved} of the {self.episodes} episode(s) filmed"


def record_video(task: str | None, out: str | Path, policy_path: str | Path | None = None, steps: int | None = None,
                 seed: int = 0, seed_index: int = 0, train_env: bool = False, epsilon: float = VIDEO_EPSILON,
                 episodes: int = VIDEO_EPISODES, strip: str | Path | None = None,
                 max_frames: int | None = VIDEO_MAX_FRAMES) -> Video:
    """Write an H.264 MP4 of one rollout; return its path and how many episodes it shows solved.

    ``policy_path`` (a run directory, checkpoint or policy file) selects the trained policy (of seed number
    ``seed_index`` of a run); without it a uniform random policy acts. The film is ``steps`` steps long, or
    without ``steps`` ``episodes`` whole episodes (each at most the horizon; fewer where the film holds
    ``max_frames`` frames when one ends; a reset-free env has one episode, so its film is one horizon long).
    ``seed`` seeds the first layout and the exploration draws. ``strip``: also write the first episode as a
    filmstrip PNG there (`write_filmstrip`).
    """
    import gymnasium as gym

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

    if steps is None and kwargs.get("reset_free"):
        steps = int(kwargs.get("horizon", 200))
    try:
        film = film_rollout(env, act, seed, steps, episodes, max_frames)
        fps = env.metadata.get("render_fps", 8)
    finally:
        env.close()
    write_h264(film.frames, out, fps=fps)
    if strip is not None:
        strip = write_filmstrip(film.frames[:film.first_episode], strip)
    return Video(Path(out), film.episodes, film.solved, film.total_return, get_task(task).metric, strip,
                 film.ended, film.steps)
