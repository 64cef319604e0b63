r"""A uniform random policy in a released script's own environment: the dynamics' fingerprint, for the original side.

``python -m gridtasks.random_policy`` counts what a random policy completes in ecorl's worlds; this counts the same
in the released environment class, built with the environment settings of one sweep point of a released script
(``--set`` picks it, as in ``run_released.py``), non-episodic: the solves per world over ``--steps`` steps (95 %
interval over worlds), the first solve's step, and for scavenging the steps on which a predator caught the agent,
and of those the steps caught by a predator that appeared on the agent's own cell (ecorl's never do).
World ``s`` seeds Python's ``random`` and NumPy's global generator with ``s`` (the release draws resource growth
and predator moves from them) and the environment with ``s``::

    python tools/original/random_policy.py --checkout ../ecologicalrl --script scavenging-shaping \
        --set monster_eps=0.25 monster_eps_decay=0 place_schedule=None make_rtype=sparse time_horizon=0
"""

from __future__ import annotations

import argparse
import random
import runpy
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import shims  # noqa: E402
from run_released import SCRIPTS, add_point_arguments, parse_settings, pick  # noqa: E402


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_point_arguments(parser)
    parser.add_argument("--seeds", type=int, default=32, help="worlds (default 32, as gridtasks.random_policy)")
    parser.add_argument("--steps", type=int, default=20_000, help="steps per world (default 20 000)")
    return parser.parse_args(argv)


def script_point(checkout: Path, script: str, settings: dict) -> tuple[type, dict]:
    """(the script's environment class, the chosen sweep point's env_kwargs): the script runs as __main__ with
    rlkit's ``run_experiment`` collecting its sweep; the class is the one environment class it calls.
    """
    import rlkit.launchers.launcher_util as launcher
    from rlkit.envs.gym_minigrid.gym_minigrid.envs.getfood_base import FoodEnvBase

    calls: list[tuple] = []
    launcher.run_experiment = lambda function, variant=None, **kwargs: calls.append((function, variant, kwargs))
    path = checkout / SCRIPTS.get(script, script)
    names, source = runpy.run_path(str(path), run_name="__main__"), path.read_text()
    classes = {v for v in names.values()
               if isinstance(v, type) and issubclass(v, FoodEnvBase) and f"{v.__name__}(" in source}
    if len(classes) != 1:
        raise SystemExit(f"{script} builds {len(classes)} environment classes, not one")
    _, variant, _ = pick(calls, settings)
    return classes.pop(), dict(variant["env_kwargs"])


def one_world(env_class: type, kwargs: dict, seed: int, steps: int) -> tuple[int, int, int, int]:
    """(solves, the first solve's step or steps + 1, steps caught by a predator, of those the steps caught by one
    born on the agent's cell) of one non-episodic world.
    """
    random.seed(seed)
    np.random.seed(seed)
    env = env_class(**{**kwargs, "time_horizon": 0, "end_on_task_completion": False})
    env.reset(seed=seed)
    solves, first, caught, caught_by_born_on_agent = 0, steps + 1, 0, 0
    for t in range(1, steps + 1):
        _, reward, _, info = env.step(random.randrange(env.action_space.n))
        solved = bool(info.get("solved"))
        if solved:
            solves += 1
            first = min(first, t)
        caught += (reward - 100 * solved) <= -100  # the sparse task pays 100; a catch costs monster_penalty
        monsters = getattr(env, "monsters", [])
        for m in monsters:
            if m.life == 0:  # placed this step, not moved yet
                m.born_on_agent = bool(np.array_equal(m.cur_pos, env.agent_pos))
        caught_by_born_on_agent += any(getattr(m, "born_on_agent", False) and np.array_equal(m.cur_pos, env.agent_pos)
                                       for m in monsters)
    return solves, first, caught, caught_by_born_on_agent


def main(argv: list[str] | None = None) -> None:
    """Print one table row of the worlds' statistics."""
    args = parse_args(argv)
    shims.install(args.checkout)
    settings = parse_settings(args.set)
    env_class, kwargs = script_point(shims.check_checkout(args.checkout), args.script, settings)
    if kwargs.get("make_rtype") != "sparse":
        raise SystemExit("pick a sparse-reward sweep point (--set make_rtype=sparse): solves are read off its reward")
    results = np.array([one_world(env_class, kwargs, s, args.steps) for s in range(args.seeds)], dtype=float)
    solves, first, caught, by_born_on_agent = results.T
    print("| script point | solves per world (± 95 % CI) | first solve, mean / median step | steps caught per world | "
          "of those by predators born on the agent's cell |")
    print("|---|---|---|---|---|")
    print(f"| {args.script} {' '.join(args.set)} | {solves.mean():.2f} ± {half_width(solves):.2f} | "
          f"{first.mean():.0f} / {np.median(first):.0f} | {caught.mean():.0f} ± {half_width(caught):.0f} | "
          f"{by_born_on_agent.mean():.0f} ± {half_width(by_born_on_agent):.0f} |")


def half_width(values: np.ndarray) -> float:
    """Half the width of the normal 95 % interval of the mean over worlds."""
    return float(1.96 * values.std(ddof=1) / np.sqrt(len(values)))


if __name__ == "__main__":
    main()
