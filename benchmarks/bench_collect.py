"""Collection alone: the host-side loop of training (act, step the worlds, store, count visits), no updates.

    python benchmarks/bench_collect.py                 # K = 40 salad seeds, epsilon 0.1 (a forward every step)
    python benchmarks/bench_collect.py --ks 10 40 --steps 2000 --rounds 5

On a GPU host this loop, not the updates, bounds a packed run (the updates are CUDA graphs); on the CPU it
is a small share of training. Prints, per K, the median over rounds of the milliseconds per environment
step (all K worlds stepped once) with its min-max, and agent-steps per second; then the peak RSS. The
forward pass runs on the CPU here (one torch thread), so ``--no-forward`` also times the loop without it
(epsilon 1: every action random), which is what a GPU host adds to a graphed forward pass.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_gpu import BASE as GPU_BASE  # noqa: E402 (this script's folder is on the path)

from train.loop.trainer import Trainer  # noqa: E402

BASE = GPU_BASE.replace(reward="waypoint")
"""bench_gpu's salad trainer with the headline panel's reward."""


def per_step_ms(k: int, steps: int, rounds: int, epsilon: float) -> list[float]:
    """Milliseconds per environment step of ``rounds`` collections of ``steps`` steps at K seeds."""
    trainer = Trainer(BASE.replace(seeds=k, eps_start=epsilon, eps_end=epsilon))
    trainer.collect(steps)  # first calls, allocation
    times = []
    for _ in range(rounds):
        began = time.perf_counter()
        trainer.collect(steps)
        times.append(1e3 * (time.perf_counter() - began) / steps)
    trainer.close()
    return times


def main() -> None:
    """Time collection at each K and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ks", type=int, nargs="+", default=[40], help="seeds per process")
    parser.add_argument("--steps", type=int, default=2000, help="environment steps per timed round")
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds (the median is reported)")
    parser.add_argument("--no-forward", action="store_true", help="also time epsilon 1 (no forward pass)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    settings = [("epsilon 0.1", 0.1)] + ([("epsilon 1", 1.0)] if args.no_forward else [])
    print("ms per environment step (median [min-max] over rounds), agent-steps/s:")
    for k in args.ks:
        for name, eps in settings:
            times = per_step_ms(k, args.steps, args.rounds, eps)
            mid = statistics.median(times)
            print(f"  K = {k:>4}, {name:<11}: {mid:6.3f} ms [{min(times):.3f}-{max(times):.3f}], "
                  f"{k * 1e3 / mid:>9,.0f} agent-steps/s")
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
