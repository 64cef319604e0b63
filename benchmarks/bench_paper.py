"""How long the whole paper takes on this machine: every experiment's training runs at the paper's budget,
packed per task, timed for a few epochs and projected.

    python benchmarks/bench_paper.py --device cpu --max-k 20          # a few minutes on 2 cores
    python benchmarks/bench_paper.py --device cuda                    # on a GPU: every pack at its full K
    python benchmarks/bench_paper.py --census                         # only count what the paper trains

The census: what ``ecorl run --all --budget paper`` trains, every condition of every named experiment, each
distinct configuration once (copies such as a sweep's p 0 and the headline's static run are the same config),
grouped into the packs one process can train (`train.loop.packing.group_packable`: conditions of a task that differ
only in per-row settings). For each pack the benchmark builds the packed trainer (with a 20 000-slot replay, so
any K fits; replay size does not change the work per step), trains ``--epochs`` epochs after an untimed one and
times one evaluation at the paper's protocol. Its projection: epochs x epoch time + evaluations x evaluation
time. With ``--max-k`` a pack larger than that is timed at that many seeds and scaled linearly in K, which is
how the CPU's cost grows (a GPU's grows more slowly: time it at full K). Packs run one after another in the
projection; absolute rates move between machines and runs.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from train.config import TrainConfig  # noqa: E402
from train.experiments.catalog import EXPERIMENTS  # noqa: E402
from train.experiments.multi import plan_many, split_copies  # noqa: E402
from train.loop.packing import group_packable  # noqa: E402
from train.loop.trainer import Trainer  # noqa: E402

BENCH_REPLAY = 20_000
"""Replay slots per seed while timing (the paper's 500 000 x K hundreds would not fit a host's memory)."""


@dataclass
class PaperPack:
    """Conditions of one task that one process trains together at the paper's budget."""

    task: str
    names: list[str]
    cfgs: list[TrainConfig]

    @property
    def k(self) -> int:
        """Seeds trained together."""
        return sum(c.run.seeds for c in self.cfgs)

    @property
    def steps(self) -> int:
        """Environment steps per seed (shared by a pack)."""
        return self.cfgs[0].total_steps

    @property
    def agent_steps(self) -> int:
        """Seeds x steps."""
        return self.k * self.steps

    @property
    def evaluations(self) -> int:
        """Evaluations at the pack's protocol."""
        return self.steps // self.cfgs[0].eval.eval_every


def census(device: str) -> list[PaperPack]:
    """What ``ecorl run --all --budget paper`` trains (each configuration once), grouped into packs per task."""
    with tempfile.TemporaryDirectory() as out:
        experiments = [e for e in EXPERIMENTS.values() if not e.is_measurement]
        train, _ = split_copies(plan_many(experiments, "paper", out, device=device))
    by_task: dict[str, list[tuple[str, TrainConfig]]] = {}
    for job in train:
        by_task.setdefault(job.task, []).append((job.name, TrainConfig.from_dict(job.config)))
    packs = []
    for task, entries in by_task.items():
        for group in group_packable([cfg for _, cfg in entries]):
            packs.append(PaperPack(task, [entries[i][0] for i in group], [entries[i][1] for i in group]))
    return sorted(packs, key=lambda p: (p.task, -p.agent_steps))


def _timed_cfgs(pack: PaperPack, max_k: int | None) -> list[TrainConfig]:
    """The pack's configs with a small replay, cut to at most ``max_k`` seeds in all (each keeps one at least)."""
    cfgs, left = [], max_k if max_k else pack.k
    for cfg in pack.cfgs:
        if left <= 0:
            break
        seeds = min(cfg.run.seeds, left)
        cfgs.append(cfg.replace(seeds=seeds, buffer_size=BENCH_REPLAY, progress=False, threads=1))
        left -= seeds
    return cfgs


def time_pack(pack: PaperPack, epochs: int, max_k: int | None, seconds: float = 0.0) -> tuple[float, float, int]:
    """(seconds per epoch, seconds per evaluation, seeds timed) of the pack's trainer, timed over ``epochs``
    epochs or, if longer, as many as fill ``seconds``.
    """
    cfgs = _timed_cfgs(pack, max_k)
    trainer = Trainer.packed(cfgs, [None] * len(cfgs), [False] * len(cfgs))
    device = cfgs[0].run.device
    trainer.train_epoch()  # untimed: warm-up, first kernels, graph capture
    _sync(device)
    began, done = time.perf_counter(), 0
    while done < epochs or time.perf_counter() - began < seconds:
        trainer.train_epoch()
        _sync(device)
        done += 1
    epoch = (time.perf_counter() - began) / done
    began = time.perf_counter()
    trainer.evaluate()
    _sync(device)
    evaluation = time.perf_counter() - began
    k = trainer.num_agents
    trainer.close()
    return epoch, evaluation, k


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:.2f} h" if seconds >= 3600 else f"{seconds / 60:.1f} min"


def main(argv: list[str] | None = None) -> None:
    """The census, then each pack timed and projected; a total."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu",
                        help="cpu, cuda or cuda:N (default: cuda where there is one)")
    parser.add_argument("--epochs", type=int, default=2, help="timed epochs per pack, after an untimed one")
    parser.add_argument("--seconds", type=float, default=0.0, help="time each pack over at least this many "
                        "seconds of epochs (so that packs timed side by side overlap)")
    parser.add_argument("--max-k", type=int, default=None, help="time at most this many seeds per pack and scale "
                        "linearly in K (the CPU's cost; default: every pack at its full K)")
    parser.add_argument("--tasks", nargs="+", default=None, help="only these tasks' packs")
    parser.add_argument("--census", action="store_true", help="only count the paper's runs; time nothing")
    parser.add_argument("--pack", type=int, nargs="+", default=None, metavar="I",
                        help="only these packs, by their row in the census (from 0), say to time packs side by side")
    args = parser.parse_args(argv)
    packs = [p for p in census(args.device) if args.tasks is None or p.task in args.tasks]
    if args.pack is not None:
        if max(args.pack) >= len(packs) or min(args.pack) < 0:
            parser.error(f"--pack: rows 0 to {len(packs) - 1} here; see --census")
        packs = [packs[i] for i in args.pack]
    total = sum(p.agent_steps for p in packs)
    print(f"the paper at its budget: {sum(len(p.names) for p in packs)} distinct conditions in {len(packs)} packs, "
          f"{total / 1e6:,.0f} M agent-steps ({args.device}, torch {torch.__version__})")
    print("| task | conditions | K | steps | M agent-steps | K timed | agent-steps/s | s per evaluation | projected |")
    print("|---|---|---|---|---|---|---|---|---|")
    projected = 0.0
    for pack in packs:
        row = f"| {pack.task} | {len(pack.names)} | {pack.k} | {pack.steps:,} | {pack.agent_steps / 1e6:,.1f} |"
        if args.census:
            print(row + " | | | |")
            continue
        epoch, evaluation, timed = time_pack(pack, args.epochs, args.max_k, args.seconds)
        scale = pack.k / timed
        epoch_steps = pack.cfgs[0].dqn.epoch_steps
        seconds = scale * (pack.steps / epoch_steps * epoch + pack.evaluations * evaluation)
        projected += seconds
        print(f"{row} {timed} | {timed * epoch_steps / epoch:,.0f} | {evaluation:.2f} | {_hours(seconds)} |",
              flush=True)
    if not args.census:
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"the whole paper, one pack after another on this {args.device}: {_hours(projected)} "
              f"({total / projected:,.0f} agent-steps/s overall); peak RSS {peak:.0f} MiB")


if __name__ == "__main__":
    main()
