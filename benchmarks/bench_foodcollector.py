"""Decisions per second of the food collector under a uniform random policy, and its memory.

One decision = 5 physics steps + sphere motion and contacts + 7 ray casts + the observation, through
``gymnasium.make`` (its default wrappers included). Pin to one core for numbers comparable to the target
(3 000 decisions/s on one core)::

    OMP_NUM_THREADS=1 taskset -c 0 python benchmarks/bench_foodcollector.py --decisions 50000

``--calls`` times the arena's two ways into Chipmunk (`foodcollector.chipmunk`), alternating in this process:
its direct calls (the default) against pymunk's public API, round after round, and prints their ratio.
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc

import gymnasium
import numpy as np

import foodcollector
from foodcollector import chipmunk

CONDITIONS = {
    "static": {"dynamism": 0.0},
    "dynamic (p=1)": {"dynamism": 1.0},
    "dynamic + shaped, reset-free": {"dynamism": 0.5, "shaping": 1.0, "reset_free": True},
}
TRACE_DECISIONS = 2_000  # tracemalloc slows Python down; it runs on a short separate rollout


def rollout(env, actions: np.ndarray) -> float:
    """Step through ``actions`` (resetting when an episode ends); return the seconds taken."""
    start = time.perf_counter()
    for a in actions.tolist():
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return time.perf_counter() - start


def bench(knobs: dict, decisions: int, seed: int) -> dict:
    """Decisions/s and the peak Python allocation of one env under a random policy."""
    env = gymnasium.make(foodcollector.ENV_ID, **knobs)
    env.reset(seed=seed)
    actions = np.random.default_rng(seed).integers(0, 27, size=decisions)
    rollout(env, actions[: min(500, decisions)])  # warm-up
    seconds = rollout(env, actions)
    tracemalloc.start()
    rollout(env, actions[:TRACE_DECISIONS])
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"decisions_per_s": decisions / seconds, "us_per_decision": 1e6 * seconds / decisions,
            "traced_peak_kib": peak / 1024}


def compare_calls(decisions: int, rounds: int, seed: int) -> None:
    """Decisions/s of `chipmunk.ChipmunkCalls` and `chipmunk.PublicCalls`, alternating, on the dynamic
    reset-free condition; prints each round and the ratio of the medians.
    """
    knobs = CONDITIONS["dynamic + shaped, reset-free"]
    rates: dict[str, list[float]] = {"direct": [], "public": []}
    previous = chipmunk.CALLS
    try:
        for r in range(rounds):
            for name, calls in (("direct", chipmunk.ChipmunkCalls), ("public", chipmunk.PublicCalls)):
                chipmunk.CALLS = calls
                rates[name].append(bench(knobs, decisions, seed + r)["decisions_per_s"])
    finally:
        chipmunk.CALLS = previous
    for name, values in rates.items():
        print(f"  {name:6s} calls: {' '.join(f'{v:6.0f}' for v in values)} decisions/s")
    print(f"  direct / public (medians): {np.median(rates['direct']) / np.median(rates['public']):.2f}x")


def main() -> None:
    """Run every condition and print one line each, then the process's peak resident memory."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decisions", type=int, default=20_000, help="decisions timed per condition")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--calls", action="store_true",
                        help="compare the arena's direct Chipmunk calls with pymunk's public API instead")
    parser.add_argument("--rounds", type=int, default=5, help="rounds of --calls (the median is compared)")
    args = parser.parse_args()
    if args.calls:
        if chipmunk.CALLS is not chipmunk.ChipmunkCalls:
            raise SystemExit("this pymunk does not expose Chipmunk's bindings: the arena uses the public API")
        print(f"food collector, the arena's calls into Chipmunk, {args.decisions} decisions x {args.rounds} rounds")
        compare_calls(args.decisions, args.rounds, args.seed)
        return
    print(f"food collector, {args.decisions} random decisions per condition (1 decision = 5 physics steps)")
    for name, knobs in CONDITIONS.items():
        r = bench(knobs, args.decisions, args.seed)
        print(f"  {name:30s} {r['decisions_per_s']:8.0f} decisions/s  {r['us_per_decision']:6.1f} µs/decision"
              f"  tracemalloc peak {r['traced_peak_kib']:6.1f} KiB")
    maxrss_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux reports KiB
    print(f"  peak resident memory of the process (ru_maxrss): {maxrss_mib:.1f} MiB")


if __name__ == "__main__":
    main()
