"""Throughput of the grid tasks under a uniform random policy: single env and batched engine.

    python benchmarks/bench_gridtasks.py            # all tasks, 1 core
    python benchmarks/bench_gridtasks.py --quick    # fewer steps (what `ecorl demo` prints)
    python benchmarks/bench_gridtasks.py --threads 2 --quick   # threads=2 against threads=1, as a ratio

Single env: ``gymnasium.make(id)`` with its default wrappers, one ``step`` call per step. Batched:
``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``, one call per N steps.
Steps/s are per core: the process is pinned to one CPU (``--cores``). Peak memory is the process's
maximum resident set size.

``--threads N`` times instead the batched engine on N threads (``threads=N``) against one thread at 64 and
1 024 worlds, alternating chunks of the two in one process (pinned to N cores) and printing the median
ratio with its min-max; absolute rates on a shared machine move between runs, the interleaved ratio less.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import gymnasium as gym
import numpy as np

import gridtasks

BATCH_SIZES = (1, 64, 1024, 4096)


def single_env_rate(env_id: str, steps: int) -> float:
    """Random-policy steps per second of one env through the Gymnasium API (resets included)."""
    env = gym.make(env_id, dynamism=0.1)
    env.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, 7, steps).tolist()
    env.step(0)  # warm the compiled kernels
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def batched_rate(env_id: str, num_envs: int, steps: int) -> float:
    """Random-policy world-steps per second of the batched engine (next-step autoreset included)."""
    vec = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", dynamism=0.1)
    vec.reset(seed=0)
    calls = max(steps // num_envs, 20)
    actions = np.random.default_rng(0).integers(0, 7, (calls, num_envs))
    vec.step(actions[0])
    start = time.perf_counter()
    for a in actions:
        vec.step(a)
    return calls * num_envs / (time.perf_counter() - start)


def thread_ratio(env_id: str, num_envs: int, threads: int, steps: int, rounds: int = 7) -> tuple[float, ...]:
    """World-steps/s on ``threads`` threads over one thread, in alternating chunks: (median, min, max)."""
    envs = [gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", dynamism=0.1,
                         threads=t) for t in (1, threads)]
    calls = max(steps // num_envs // rounds, 10)
    actions = np.random.default_rng(0).integers(0, 7, (calls, num_envs))
    for vec in envs:
        vec.reset(seed=0)
        vec.step(actions[0])  # compile (or load) the kernels
    ratios = []
    for _ in range(rounds):
        seconds = []
        for vec in envs:
            start = time.perf_counter()
            for a in actions:
                vec.step(a)
            seconds.append(time.perf_counter() - start)
        ratios.append(seconds[0] / seconds[1])
    return float(np.median(ratios)), min(ratios), max(ratios)


def run_threads(threads: int, steps: int, batch_sizes=(64, 1024)) -> None:
    """Print, per task and batch size, the speed-up of ``threads`` threads over one (median [min, max])."""
    print(f"threads={threads} / threads=1, batched world-steps/s, median [min, max] of 7 alternating chunks")
    print(f"{'env id':26s} " + " ".join(f"{f'x{b}':>22s}" for b in batch_sizes))
    for env_id in gridtasks.ENV_IDS.values():
        cells = [thread_ratio(env_id, b, threads, steps) for b in batch_sizes]
        print(f"{env_id:26s} " + " ".join(f"{m:8.2f} [{lo:4.2f}, {hi:4.2f}]" for m, lo, hi in cells))


def peak_rss_mib() -> float:
    """Peak resident memory of this process in MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run(steps: int, batched_steps: int, batch_sizes=BATCH_SIZES) -> list[dict]:
    """Measure every registered grid task and print one table row per task."""
    header = f"{'env id':26s} {'single':>10s} " + " ".join(f"{f'x{b}':>11s}" for b in batch_sizes)
    print(header + "   (steps/s per core)")
    rows = []
    for env_id in gridtasks.ENV_IDS.values():
        row = {"env": env_id, "single": single_env_rate(env_id, steps)}
        row.update({b: batched_rate(env_id, b, batched_steps) for b in batch_sizes})
        rows.append(row)
        print(f"{env_id:26s} {row['single']:10,.0f} " + " ".join(f"{row[b]:11,.0f}" for b in batch_sizes))
    print(f"peak memory (RSS): {peak_rss_mib():.0f} MiB")
    return rows


def main() -> None:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200_000, help="single-env steps per task")
    parser.add_argument("--batched-steps", type=int, default=4_000_000, help="world-steps per batch size")
    parser.add_argument("--quick", action="store_true", help="20k single / 400k batched steps")
    parser.add_argument("--cores", type=int, default=1, help="pin the process to this many cores")
    parser.add_argument("--threads", type=int, default=1,
                        help="time threads=N against threads=1 instead (pins to max(cores, N) cores)")
    args = parser.parse_args()
    args.cores = max(args.cores, args.threads)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, set(sorted(os.sched_getaffinity(0))[: args.cores]))
    if args.quick:
        args.steps, args.batched_steps = 20_000, 400_000
    print(f"{os.cpu_count()} CPUs visible, pinned to {args.cores}; numpy {np.__version__}, "
          f"gymnasium {gym.__version__}")
    if args.threads > 1:
        run_threads(args.threads, args.batched_steps)
    else:
        run(args.steps, args.batched_steps)


if __name__ == "__main__":
    main()
