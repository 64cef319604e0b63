"""`ecorl demo`: short random-policy videos of every task and a picture of them side by side."""

from __future__ import annotations

from pathlib import Path

import numpy as np

DEMO_KNOBS = {"dynamism": 0.1, "reset_free": True}
"""Dynamic, reset-free worlds: the setting the paper argues for."""


def demo_envs() -> dict:
    """Task name -> a render-ready environment, for every task (`train.tasks.TASKS`)."""
    import gymnasium as gym

    from train.tasks import TASKS

    return {name: gym.make(task.env_id, render_mode="rgb_array", **DEMO_KNOBS) for name, task in TASKS.items()}


def record_random_rollout(env, steps: int, seed: int) -> list[np.ndarray]:
    """Frames of a uniform random policy for ``steps`` steps."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    frames = [env.render()]
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        frames.append(env.render())
        if terminated or truncated:
            env.reset()
    return frames


def montage(frames: list[np.ndarray], height: int = 320) -> np.ndarray:
    """Frames resized to one height and placed side by side with a white gap."""
    import cv2

    tiles = []
    for f in frames:
        width = round(f.shape[1] * height / f.shape[0])
        tiles += [cv2.resize(f, (width, height), interpolation=cv2.INTER_AREA),
                  np.full((height, 8, 3), 255, np.uint8)]
    return np.concatenate(tiles[:-1], axis=1)


def run_demo(out: Path, steps: int = 150, seed: int = 0) -> list[Path]:
    """Write one H.264 MP4 per task and ``tasks.png`` into ``out``; return the written paths."""
    import cv2
    from tqdm import tqdm

    from train.experiments.video import write_h264
    from train.storage.fileio import atomic_write

    out.mkdir(parents=True, exist_ok=True)
    written, stills = [], []
    for name, env in tqdm(demo_envs().items(), desc="rendering demo videos", unit="task"):
        frames = record_random_rollout(env, steps, seed)
        write_h264(frames, out / f"{name}.mp4", fps=env.metadata.get("render_fps", 8))
        written.append(out / f"{name}.mp4")
        stills.append(frames[len(frames) // 2])
    ok, png = cv2.imencode(".png", montage(stills)[:, :, ::-1])
    if not ok:
        raise RuntimeError("OpenCV could not encode tasks.png")
    return [*written, atomic_write(out / "tasks.png", png.tobytes())]
