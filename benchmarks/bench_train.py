"""Training throughput of ecorl's batched double DQN beside Stable-Baselines3's DQN, and replay memory.

Throughput: environment steps per second on salad (dynamism 0.1, episodic, horizon 200), each step paired
with one gradient step on a batch of 64, epsilon fixed at 0.1 (the steady state of training, where every
step needs a greedy action). Ours: epochs of 500 steps then 500 updates, 1 seed and 10 seeds in one
process. SB3: the same two-branch network (a features extractor for the view/inventory branches, net_arch
[16, 16] for the head), batch 64, train_freq 1, gradient_steps 1, buffer 5e5, learning_starts 200, Polyak
tau 0.001 after every update, gradient clip 5, lr 1e-4 (SB3's DQN target is the plain max, not double).
Memory: peak RSS of a fresh process holding a 10-seed trainer whose replay is filled with 500 000
transitions per seed, after some updates.

    python benchmarks/bench_train.py [--threads 1] [--repeats 3] [--steps 1500]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from train.agent.replay import STARTS  # noqa: E402
from train.config import TrainConfig  # noqa: E402
from train.trainer import Trainer  # noqa: E402

ENV_KWARGS = {"dynamism": 0.1, "reset_free": False, "horizon": 200}
EPSILON = 0.1


def bench_ours(seeds: int, steps: int, threads: int) -> float:
    """Aggregate environment steps per second (all seeds) of our trainer, one update per step."""
    cfg = TrainConfig().replace(task="salad", seeds=seeds, eps_start=EPSILON, eps_end=EPSILON, progress=False,
                                threads=threads, **ENV_KWARGS)
    trainer = Trainer(cfg)
    trainer.train_epoch()  # warm-up + one epoch, untimed
    epochs = max(1, steps // cfg.dqn.epoch_steps)
    began = time.perf_counter()
    for _ in range(epochs):
        trainer.train_epoch()
    elapsed = time.perf_counter() - began
    trainer.close()
    return seeds * epochs * cfg.dqn.epoch_steps / elapsed


def bench_sb3(steps: int, threads: int) -> float | None:
    """Environment steps per second of SB3's DQN configured like ours (None if SB3 is missing)."""
    torch.set_num_threads(threads)
    try:
        import stable_baselines3 as sb3
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
    except ImportError:
        return None
    import gymnasium as gym
    from torch import nn

    import gridtasks  # noqa: F401  (registers the ids)

    env = gym.make("gridtasks/Salad-v0", **ENV_KWARGS)
    view_dim, inventory_dim = env.unwrapped.observation_split

    class TwoBranch(BaseFeaturesExtractor):
        """The paper's view (64-64-32) and inventory (16-16-16) branches, concatenated."""

        def __init__(self, space):
            super().__init__(space, features_dim=48)
            self.view = nn.Sequential(nn.Linear(view_dim, 64), nn.ReLU(), nn.Linear(64, 64), nn.ReLU(),
                                      nn.Linear(64, 32))
            self.inventory = nn.Sequential(nn.Linear(inventory_dim, 16), nn.ReLU(), nn.Linear(16, 16),
                                           nn.ReLU(), nn.Linear(16, 16))

        def forward(self, obs):
            return torch.cat((self.view(obs[:, :view_dim]), self.inventory(obs[:, view_dim:])), dim=1)

    class Clock(BaseCallback):
        """Times the steps after learning starts."""

        def __init__(self, start: int):
            super().__init__()
            self.start, self.began = start, None

        def _on_step(self) -> bool:
            if self.num_timesteps == self.start:
                self.began = time.perf_counter()
            return True

    model = sb3.DQN("MlpPolicy", env, learning_rate=1e-4, buffer_size=500_000, learning_starts=200,
                    batch_size=64, tau=0.001, gamma=0.99, train_freq=1, gradient_steps=1,
                    target_update_interval=1, exploration_initial_eps=EPSILON, exploration_final_eps=EPSILON,
                    max_grad_norm=5.0, device="cpu", seed=0,
                    policy_kwargs={"features_extractor_class": TwoBranch, "net_arch": [16, 16]})
    warm = 700  # learning starts at 200; time from step 700 on
    clock = Clock(warm)
    model.learn(total_timesteps=warm + steps, callback=clock)
    return steps / (time.perf_counter() - clock.began)


def memory_child() -> None:
    """Fill a 10-seed trainer's replay with 500 000 transitions per seed, update, print peak RSS (MiB)."""
    cfg = TrainConfig().replace(task="salad", seeds=10, buffer_size=500_000, progress=False, **ENV_KWARGS)
    trainer = Trainer(cfg)
    trainer.collect(cfg.dqn.warmup_steps)
    replay = trainer.replay
    rng = np.random.default_rng(0)
    chunk = 50_000
    for start in range(0, replay.capacity, chunk):  # write every page, as a full buffer would
        replay.obs[:, start:start + chunk] = rng.integers(0, 256, (replay.num_agents, chunk, replay.obs.shape[2]),
                                                          dtype=np.uint8)  # random packed observations
        replay.action[:, start:start + chunk] = rng.integers(0, 7, (replay.num_agents, chunk))
        replay.reward[:, start:start + chunk] = 0.0
        replay.flags[:, start:start + chunk] = STARTS
    replay.size[:] = replay.capacity
    replay.ptr[:] = 0
    trainer.learn(500)
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{peak_mib:.0f} {replay.nbytes / 2**20:.0f}")


def measure_memory() -> tuple[float, float]:
    """Peak RSS (MiB) of `memory_child` in a fresh process, and the replay arrays' size (MiB)."""
    out = subprocess.run([sys.executable, __file__, "--memory-child"], capture_output=True, text=True,
                         check=True)
    peak, replay = out.stdout.split()[-2:]
    return float(peak), float(replay)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1, help="torch threads for every measurement")
    parser.add_argument("--repeats", type=int, default=3, help="measurements per setting (median reported)")
    parser.add_argument("--steps", type=int, default=1500, help="timed environment steps per seed")
    parser.add_argument("--memory-child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--skip-sb3", action="store_true", help="do not run Stable-Baselines3")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)  # each measurement pins it again (the trainer sets its own)
    if args.memory_child:
        memory_child()
        return
    print(f"torch {torch.__version__}, torch.set_num_threads({args.threads}), {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.2f}; median of {args.repeats}, {args.steps} timed steps per seed")
    results = {}
    for name, fn in (("ours, 1 seed", lambda: bench_ours(1, args.steps, args.threads)),
                     ("ours, 10 seeds", lambda: bench_ours(10, args.steps, args.threads)),
                     ("SB3 DQN, 1 seed", None if args.skip_sb3 else lambda: bench_sb3(args.steps, args.threads))):
        runs = [fn() for _ in range(args.repeats)] if fn is not None else [None]
        if None in runs:
            print(f"{name:>16}: not measured (stable-baselines3 not installed or --skip-sb3)")
            continue
        results[name] = statistics.median(runs)
        print(f"{name:>16}: {results[name]:8.0f} env steps/s (aggregate)   runs: "
              + ", ".join(f"{r:.0f}" for r in runs), flush=True)
    sb3 = results.get("SB3 DQN, 1 seed")
    if sb3:
        print(f"speed-up vs SB3: 1 seed x{results['ours, 1 seed'] / sb3:.1f} (target >= 2), "
              f"10 seeds x{results['ours, 10 seeds'] / sb3:.1f} (target >= 10)")
    peak, replay = measure_memory()
    print(f"memory: 10 seeds x 500 000 transitions: replay arrays {replay:.0f} MiB, peak RSS {peak:.0f} MiB "
          f"(target < 1024 MiB); load average now {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
