r"""The released learner and ecorl's, trained on one and the same stream of experience: whose values blow up?

With a uniform behaviour policy (epsilon 1 throughout) the experience does not depend on the learner, so both
learners can be fed the very same transitions in the same order, the way each code's lifetime loop feeds its
replay: 200 steps first, then per epoch 500 new transitions and 500 gradient steps on batches of 64 drawn
uniformly from everything stored so far. What differs is only the learner: the released double-DQN trainer
(rlkit's ``DoubleDQNTrainer``) with the released network (``gen_network`` of the variant the Fig. 4 hunting script
imports, the sizes its runs logged in ``variant.json``), against ecorl's `train.agent.dqn.DoubleDQN` with the
released settings (inventory read 8 times). The experience is ecorl's hunting (deer moving at 0.2, non-episodic,
waypoint reward), as in the ``hunting-behaviour`` experiment's ``eps-1`` arm, where ecorl's largest |Q| grew to a
median of 1 700 over 10 seeds by 500 000 steps. For the released network each observation is re-encoded into
the released layout (8 object channels, inventory one-hot over 8 types repeated 8 times, zeros when empty, 8
pick-up counts that its network ignores).

Every 5 000 steps each learner's Q-values are read on a fixed probe set (every 250th observation of the stream)
and its largest |Q| (every action) written to ``OUT/LEARNER-seedS.csv`` with the TD loss (ecorl: the mean of
the last epoch; released: its trainer's own statistic, the epoch's first batch).

    python tools/original/learner_swap.py stream --steps 600000 --out runs/swap             # ecorl's venv
    python tools/original/learner_swap.py ecorl --seeds 3 --out runs/swap                   # ecorl's venv
    python tools/original/learner_swap.py ecorl --seeds 3 --inventory-repeat 1 --out runs/swap   # as shipped
    ../released-venv/bin/python tools/original/learner_swap.py released --checkout ../ecologicalrl \
        --seed 0 --out runs/swap                                                              # the release's venv
    python tools/original/learner_swap.py table --out runs/swap          # the learners side by side, as markdown
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
WARMUP, EPOCH, BATCH = 200, 500, 64
"""The released lifetime loop's (and ecorl's) steps before training, steps and updates per epoch, batch size."""
PROBE_EVERY, REPORT_EVERY = 250, 5_000
RELEASED_VARIANT = ROOT / "docs/results/original/hunting-fig4/dynamic-reset-free-waypoint-first/seed0/variant.json"
ECORL_TO_RELEASED_CHANNEL = {0: 0, 1: 1, 2: 6, 3: 5, 4: 2}
"""ecorl's hunting view channels (empty, wall, axe, deer, food) as the released type indices (empty 0, wall 1,
food 2, wood 3, metal 4, deer 5, axe 6, monster 7)."""
VIEW_CELLS, ECORL_CHANNELS, RELEASED_CHANNELS = 25, 5, 8


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=["stream", "ecorl", "released", "table"])
    parser.add_argument("--out", type=Path, required=True, help="folder of the stream and the learners' csv files")
    parser.add_argument("--steps", type=int, default=600_000, help="stream: environment steps to record")
    parser.add_argument("--seed", type=int, default=0, help="stream: the world's seed; released: the learner's")
    parser.add_argument("--seeds", type=int, default=3, help="ecorl: learners trained together (seeds 0..N-1)")
    parser.add_argument("--inventory-repeat", type=int, default=8, help="ecorl: inventory copies the network reads "
                        "(8 as the released network; the shipped runs read 1)")
    parser.add_argument("--checkout", type=Path, help="released: the jcoreyes/ecologicalrl checkout")
    return parser.parse_args(argv)


def record_stream(steps: int, seed: int, out: Path) -> None:
    """Record ``steps`` uniform-random steps of one ecorl hunting world (dynamic 0.2, non-episodic, waypoint)."""
    import gymnasium as gym

    import gridtasks  # noqa: F401  (registers the environments)

    env = gym.make("gridtasks/Hunting-v0", dynamism=0.2, reset_free=True, reward="waypoint")
    rng = np.random.default_rng(seed)
    obs = np.empty((steps + 1, env.observation_space.shape[0]), np.uint8)
    actions = rng.integers(0, env.action_space.n, steps)
    rewards = np.empty(steps, np.float32)
    obs[0] = env.reset(seed=seed)[0]
    for t in range(steps):
        ob, rewards[t], terminated, truncated, _ = env.step(int(actions[t]))
        assert not (terminated or truncated), "a non-episodic world ended"
        obs[t + 1] = ob
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "stream.npz", obs=obs, actions=actions, rewards=rewards)
    print(f"{steps} steps recorded: reward {rewards.sum():.0f} in all, {int((rewards >= 100).sum())} food picked up")


def load_stream(out: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(observations (T + 1, D), actions (T,), rewards (T,), probe observations)."""
    data = np.load(out / "stream.npz")
    obs = data["obs"]
    return obs, data["actions"], data["rewards"], obs[::PROBE_EVERY]


def schedule(steps: int):
    """Yield the transitions stored (the step reached) at the end of each epoch's collection."""
    stored = WARMUP
    while stored + EPOCH <= steps:
        stored += EPOCH
        yield stored


class Log:
    """One csv per learner and seed: step, largest and mean Q on the probes, TD loss, seconds."""

    def __init__(self, path: Path) -> None:
        self.file = path.open("w", newline="")
        self.writer = csv.writer(self.file)
        self.writer.writerow(["step", "max_abs_q", "mean_q", "td_loss", "seconds"])
        self.began = time.time()

    def row(self, step: int, q: np.ndarray, loss: float) -> None:
        """Write one row: Q-values ``q`` of the probes (N, actions) at ``step``, and the TD ``loss``."""
        self.writer.writerow([step, f"{np.abs(q).max():.6g}", f"{q.mean():.6g}", f"{loss:.6g}",
                              round(time.time() - self.began)])
        self.file.flush()


def train_ecorl(seeds: int, inventory_repeat: int, out: Path) -> None:
    """Train ecorl's DoubleDQN (the released settings, the inventory read ``inventory_repeat`` times),
    ``seeds`` learners at once.
    """
    import torch

    sys.path.insert(0, str(ROOT))
    from train.agent.dqn import DoubleDQN
    from train.agent.network import QNetwork
    from train.config import DQNConfig

    torch.set_num_threads(1)
    obs, actions, rewards, probes = load_stream(out)
    cfg = DQNConfig(inventory_repeat=inventory_repeat)
    view_dim = ECORL_CHANNELS * VIEW_CELLS
    net = QNetwork.from_config(view_dim, obs.shape[1], 7, cfg)
    agent = DoubleDQN(net, cfg, [np.random.default_rng([s, 1]) for s in range(seeds)])
    samplers = [np.random.default_rng([s, 2]) for s in range(seeds)]
    name = "ecorl" if inventory_repeat == 8 else f"ecorl-inv{inventory_repeat}"
    logs = [Log(out / f"{name}-seed{s}.csv") for s in range(seeds)]
    probe_t = torch.from_numpy(probes.astype(np.float32)).expand(seeds, -1, -1).contiguous()
    print(f"ecorl: {cfg}")
    for stored in schedule(len(actions)):
        losses = []
        for _ in range(EPOCH):
            idx = np.stack([r.integers(0, stored, BATCH) for r in samplers])  # (K, B)
            pairs = np.concatenate([obs[idx], obs[idx + 1]], axis=1).astype(np.float32)
            losses.append(agent.update(torch.from_numpy(pairs), torch.from_numpy(actions[idx]),
                                       torch.from_numpy(rewards[idx]), torch.zeros(idx.shape)))
        if (stored - WARMUP) % REPORT_EVERY == 0:
            with torch.no_grad():
                q = agent.q_values(probe_t).numpy()
            loss = torch.stack(losses).mean(0).numpy()
            for s, log in enumerate(logs):
                log.row(stored, q[s], float(loss[s]))
            print(f"{name} {stored}: max |Q| {[f'{np.abs(q[s]).max():.3g}' for s in range(seeds)]}", flush=True)


def released_obs(obs: np.ndarray) -> np.ndarray:
    """Re-encode ecorl hunting observations (N, 130) in the released layout (N, 272), as float32."""
    n = len(obs)
    view = obs[:, :ECORL_CHANNELS * VIEW_CELLS].reshape(n, ECORL_CHANNELS, VIEW_CELLS)
    inventory = obs[:, ECORL_CHANNELS * VIEW_CELLS:]
    image = np.zeros((n, RELEASED_CHANNELS, VIEW_CELLS), np.float32)
    shelf = np.zeros((n, RELEASED_CHANNELS), np.float32)
    for ours, theirs in ECORL_TO_RELEASED_CHANNEL.items():
        image[:, theirs] = view[:, ours]
        if ours:  # the released shelf is all zeros when nothing is carried
            shelf[:, theirs] = inventory[:, ours]
    pickups = np.zeros((n, 8), np.float32)  # read by no layer of the released network
    return np.concatenate([image.reshape(n, -1), np.repeat(shelf, 8, axis=1), pickups], axis=1)


def train_released(checkout: Path, seed: int, out: Path) -> None:
    """The released DoubleDQNTrainer and network, one seed."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import shims

    shims.install(checkout.resolve())
    import rlkit.torch.pytorch_util as ptu
    import torch
    from rlkit.torch.dqn.double_dqn import DoubleDQNTrainer
    from torch import nn
    from variants.dqn_lifetime.dqn_medium8_mlp_task_partial_variant import gen_network

    algo = json.loads(RELEASED_VARIANT.read_text())["algo_kwargs"]
    torch.set_num_threads(1)
    ptu.set_gpu_mode(False)
    np.random.seed(seed)
    torch.manual_seed(seed)
    qf, target_qf = (gen_network(algo, 7, algo["layer_size"]) for _ in range(2))
    trainer = DoubleDQNTrainer(qf=qf, target_qf=target_qf, qf_criterion=nn.MSELoss(), **algo["trainer_kwargs"])
    obs, actions, rewards, probes = load_stream(out)
    one_hot = np.eye(7, dtype=np.float32)
    probe_t = torch.from_numpy(released_obs(probes))
    log = Log(out / f"released-seed{seed}.csv")
    print(f"released: trainer {algo['trainer_kwargs']}, soft target tau {trainer.soft_target_tau}")
    for stored in schedule(len(actions)):
        trainer.end_epoch(0)  # as the released loop: its statistics (the TD loss) of each epoch's first batch
        for _ in range(EPOCH):
            idx = np.random.randint(0, stored, BATCH)  # as the released EnvReplayBuffer.random_batch
            batch = {"observations": released_obs(obs[idx]), "next_observations": released_obs(obs[idx + 1]),
                     "actions": one_hot[actions[idx]], "rewards": rewards[idx, None],
                     "terminals": np.zeros((BATCH, 1), np.float32)}
            trainer.train_from_torch({k: torch.from_numpy(v) for k, v in batch.items()})
        if (stored - WARMUP) % REPORT_EVERY == 0:
            with torch.no_grad():
                q = qf(probe_t).numpy()
            log.row(stored, q, float(trainer.eval_statistics["QF Loss"]))
            print(f"released seed {seed} {stored}: max |Q| {np.abs(q).max():.3g}", flush=True)


TABLE_STEPS = (5_200, 25_200, 50_200, 75_200, 95_200, 150_200, 200_200, 235_200, 300_200, 400_200, 495_200)
"""Steps of the side-by-side table."""


def print_table(out: Path) -> None:
    """A markdown table of every learner's largest |Q| on the probes at `TABLE_STEPS`: per learner, the median
    over its seeds [min, max] and the number of seeds written there.
    """
    learners: dict[str, list[dict[int, float]]] = {}
    for path in sorted(out.glob("*-seed*.csv")):
        with path.open() as fh:
            rows = {int(r["step"]): float(r["max_abs_q"]) for r in csv.DictReader(fh)}
        learners.setdefault(path.stem.rsplit("-seed", 1)[0], []).append(rows)
    print("| step | " + " | ".join(learners) + " |")
    print("|---|" + "---|" * len(learners))
    for step in TABLE_STEPS:
        cells = []
        for seeds in learners.values():
            values = [rows[step] for rows in seeds if step in rows]
            cells.append(f"{np.median(values):.3g} [{min(values):.3g}, {max(values):.3g}] (n={len(values)})"
                         if values else "—")
        print(f"| {step:,} | " + " | ".join(cells) + " |")


def main(argv: list[str] | None = None) -> None:
    """Record the stream, or train one code's learner on it."""
    args = parse_args(argv)
    if args.what == "stream":
        record_stream(args.steps, args.seed, args.out)
    elif args.what == "table":
        print_table(args.out)
    elif args.what == "ecorl":
        train_ecorl(args.seeds, args.inventory_repeat, args.out)
    else:
        if args.checkout is None:
            sys.exit("learner_swap.py released: --checkout PATH (the jcoreyes/ecologicalrl checkout) is needed")
        train_released(args.checkout, args.seed, args.out)


if __name__ == "__main__":
    main()
