"""Training throughput of ecorl's batched double DQN against Stable-Baselines3's DQN, as ratios per core.

Both learn on salad (dynamism 0.1, episodic, horizon 200) with one gradient step on a batch of 64 per
environment step, a 500 000-transition replay per seed, epsilon fixed at 0.1 (the steady state of training,
where most steps need a greedy action) and one torch thread, in this one process. ecorl trains K seeds
together (K = 1, 10, 40 by default): each chunk is one epoch of ``n`` steps in every world, then ``n``
updates per seed. SB3 trains one seed with the same two-branch network (a features extractor for the
view 64-64-32 and inventory 16-16-16 branches, net_arch [16, 16] for the head), train_freq 1,
gradient_steps 1, learning_starts 200, Polyak tau 0.001 after every update, gradient clip 5, lr 1e-4 (its
target is the plain max, not double). Absolute rates move 5-25 % between runs on a shared machine, so the
chunks alternate -- SB3, K = 1, SB3, K = 10, SB3, K = 40, SB3, and again -- and each ecorl chunk is
compared with the mean of the SB3 chunks on either side of it. Reported per K: the median of those ratios
of environment steps per second per core (ecorl's aggregate over its K seeds against SB3's), their min-max,
the absolute rates, and the replay memory; then the peak RSS of a fresh process holding a K = 40 trainer
with full replays. (ecorl's trainer flushes denormals to zero for the whole process, SB3's updates included.)

    python benchmarks/bench_train.py                 # ~3-5 minutes
    python benchmarks/bench_train.py --rounds 15 --scale 3   # longer, tighter
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
from train.loop.trainer import Trainer  # noqa: E402

ENV_KWARGS = {"dynamism": 0.1, "reset_free": False, "horizon": 200}
EPSILON = 0.1
BUFFER = 500_000
SB3_CHUNK = 400
"""SB3 environment steps per chunk (times --scale)."""
OURS_CHUNK = {1: 800, 10: 160, 40: 60}
"""ecorl environment steps per seed per chunk (times --scale); other K get 2400 // K (at least 20)."""


def ours_trainer(seeds: int, chunk: int) -> Trainer:
    """A K-seed trainer whose epochs are ``chunk`` steps and ``chunk`` updates, warmed up by one epoch."""
    cfg = TrainConfig().replace(task="salad", seeds=seeds, eps_start=EPSILON, eps_end=EPSILON, progress=False,
                                threads=1, buffer_size=BUFFER, epoch_steps=chunk, updates_per_epoch=chunk,
                                eval_every=chunk, **ENV_KWARGS)
    trainer = Trainer(cfg)
    trainer.train_epoch()  # the warm-up, the first updates (and any compilation), untimed
    return trainer


def time_ours(trainer: Trainer) -> float:
    """Aggregate environment steps per second (every seed) of one epoch."""
    began = time.perf_counter()
    trainer.train_epoch()
    return trainer.num_agents * trainer.cfg.dqn.epoch_steps / (time.perf_counter() - began)


def sb3_model():
    """SB3's DQN configured like ecorl, with learning already started (None if SB3 is not installed)."""
    try:
        import stable_baselines3 as sb3
        from stable_baselines3.common.logger import Logger
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

    model = sb3.DQN("MlpPolicy", env, learning_rate=1e-4, buffer_size=BUFFER, learning_starts=200,
                    batch_size=64, tau=0.001, gamma=0.99, train_freq=1, gradient_steps=1,
                    target_update_interval=1, exploration_initial_eps=EPSILON, exploration_final_eps=EPSILON,
                    max_grad_norm=5.0, device="cpu", seed=0,
                    policy_kwargs={"features_extractor_class": TwoBranch, "net_arch": [16, 16]})
    model.set_logger(Logger(folder=None, output_formats=[]))  # else every learn() makes a /tmp/SB3-<time> folder
    model.learn(total_timesteps=700)  # learning starts at step 200: 500 updates of warm-up, untimed
    return model


def time_sb3(model, steps: int) -> float:
    """Environment steps per second of SB3 continuing to learn for ``steps`` steps."""
    began = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    return steps / (time.perf_counter() - began)


def sb3_replay_mib(model) -> float:
    """Size of SB3's replay arrays (MiB), as allocated."""
    buf = model.replay_buffer
    arrays = (buf.observations, buf.next_observations, buf.actions, buf.rewards, buf.dones, buf.timeouts)
    return sum(a.nbytes for a in arrays if a is not None) / 2**20


def memory_child(seeds: int) -> None:
    """Fill a K-seed trainer's replay with 500 000 transitions per seed, update, print peak RSS (MiB)."""
    cfg = TrainConfig().replace(task="salad", seeds=seeds, buffer_size=BUFFER, progress=False, threads=1,
                                updates_per_epoch=20, **ENV_KWARGS)
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
    trainer.learn()  # one epoch's 20 updates
    status = Path("/proc/self/status")  # VmHWM: this process's own peak (ru_maxrss can carry the parent's)
    hwm = [line.split()[1] for line in status.read_text().splitlines() if line.startswith("VmHWM")] \
        if status.exists() else []
    peak_mib = int(hwm[0]) / 1024 if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{peak_mib:.0f} {replay.nbytes / 2**20:.0f}")


def measure_memory(seeds: int) -> tuple[float, float]:
    """Peak RSS (MiB) of `memory_child` in a fresh process, and the replay arrays' size (MiB)."""
    out = subprocess.run([sys.executable, __file__, "--memory-child", str(seeds)], capture_output=True,
                         text=True, check=True)
    peak, replay = out.stdout.split()[-2:]
    return float(peak), float(replay)


def alternate(trainers: dict[int, Trainer], model, rounds: int, sb3_steps: int) -> dict[int, list]:
    """Per K, the (ecorl rate, SB3 rate) of each round. SB3's chunks run between ecorl's, and each ecorl
    chunk is paired with the mean rate of the SB3 chunks just before and just after it.
    """
    pairs: dict[int, list] = {k: [] for k in trainers}
    before = time_sb3(model, sb3_steps)
    for r in range(rounds):
        for k, trainer in trainers.items():
            ours = time_ours(trainer)
            after = time_sb3(model, sb3_steps)
            pairs[k].append((ours, (before + after) / 2))
            before = after
        print(f"  round {r + 1}/{rounds}: " + ", ".join(f"K={k} x{p[-1][0] / p[-1][1]:.1f}"
                                                       for k, p in pairs.items()), flush=True)
    return pairs


def report(pairs: dict[int, list], trainers: dict[int, Trainer], sb3_mib: float) -> None:
    """Print the median ratio (min-max) and the absolute rates per K."""
    print(f"{'K':>3} {'ratio median':>12} {'min-max':>11} {'ecorl steps/s':>14} {'per seed':>9} "
          f"{'SB3 steps/s':>12} {'ecorl replay':>13}")
    for k, rounds in pairs.items():
        ratios = [ours / sb3 for ours, sb3 in rounds]
        ours = statistics.median(r[0] for r in rounds)
        sb3 = statistics.median(r[1] for r in rounds)
        replay = trainers[k].replay.nbytes / 2**20
        print(f"{k:>3} {statistics.median(ratios):>11.1f}x {min(ratios):>5.1f}-{max(ratios):<5.1f} "
              f"{ours:>14.0f} {ours / k:>9.0f} {sb3:>12.0f} {replay:>9.0f} MiB")
    if 40 in pairs:
        ratio = statistics.median(ours / sb3 for ours, sb3 in pairs[40])
        verdict = 'met' if ratio >= 16 else 'not met'
        print(f"issue 17's acceptance, K = 40 >= 16 x SB3 per core: x{ratio:.1f}, {verdict}")
    print(f"SB3's replay arrays: {sb3_mib:.0f} MiB per seed (float32 observations and next observations)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1,10,40", help="comma-separated K of ecorl trainers")
    parser.add_argument("--rounds", type=int, default=5, help="alternations of every chunk (median reported)")
    parser.add_argument("--scale", type=float, default=1.0, help="multiply every chunk's steps")
    parser.add_argument("--memory-seeds", type=int, default=40, help="K of the full-replay memory check; 0: skip")
    parser.add_argument("--memory-child", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.memory_child:
        memory_child(args.memory_child)
        return
    model = sb3_model()
    if model is None:
        raise SystemExit("stable-baselines3 is not installed: pip install stable-baselines3")
    seeds = [int(k) for k in args.seeds.split(",")]
    trainers = {k: ours_trainer(k, max(1, round(args.scale * OURS_CHUNK.get(k, max(20, 2400 // k)))))
                for k in seeds}
    torch.set_num_threads(1)
    print(f"torch {torch.__version__}, 1 thread, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}; "
          f"{args.rounds} rounds; chunks: SB3 {round(args.scale * SB3_CHUNK)} steps, ecorl "
          + ", ".join(f"K={k} {t.cfg.dqn.epoch_steps} steps/seed" for k, t in trainers.items()), flush=True)
    pairs = alternate(trainers, model, args.rounds, round(args.scale * SB3_CHUNK))
    report(pairs, trainers, sb3_replay_mib(model))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**10
    print(f"peak RSS of this process (every trainer and SB3, replays mostly untouched): {peak:.0f} MiB; "
          f"load average now {os.getloadavg()[0]:.2f}")
    for trainer in trainers.values():
        trainer.close()
    if args.memory_seeds:
        peak, replay = measure_memory(args.memory_seeds)
        print(f"memory: {args.memory_seeds} seeds x {BUFFER} transitions: replay arrays {replay:.0f} MiB, "
              f"peak RSS {peak:.0f} MiB ({peak / args.memory_seeds:.0f} MiB per seed)")


if __name__ == "__main__":
    main()
