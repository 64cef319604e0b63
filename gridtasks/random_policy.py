"""What a uniform random policy experiences in the reset-free grid tasks: the dynamics' fingerprint.

How often a random policy completes a task, how soon it first does, and how many resources lie on the grid
are fixed by the rules alone (where, when and for how long objects appear), so they compare rule sets
without any learning: ours against the original code's (docs/fidelity.md quotes them), or one option
against another. Every world is reset-free with the sparse reward; all seeds step together in one batched
call.

    python -m gridtasks.random_policy                      # the standard settings, 32 seeds × 20 000 steps
    python -m gridtasks.random_policy --param spawn_on_agent=False --param count_carried=True
"""

from __future__ import annotations

import argparse
import ast
import difflib
from dataclasses import dataclass
from typing import NoReturn

import numpy as np
from tqdm import tqdm

from gridtasks.codes import GROUP, Code
from gridtasks.registration import TASKS
from gridtasks.vector import GridTaskVectorEnv

SETTINGS: dict[str, tuple[str, dict]] = {
    "salad p=0": ("salad", {"dynamism": 0.0}),
    "salad p=0.05": ("salad", {"dynamism": 0.05}),
    "salad p=0.1": ("salad", {"dynamism": 0.1}),
    "salad p=0.5": ("salad", {"dynamism": 0.5}),
    # the released Fig. 5 salad's environment shaping, place_schedule (40 000, 20 000): a window 2 cells wide for the
    # first 20 000 steps, 3 for the next 20 000, ...
    "salad p=0.05 window": ("salad", {"dynamism": 0.05, "shaping": "linear:1:0:280000"}),
    "hunting move=0": ("hunting", {"dynamism": 0.0}),
    "hunting move=0.2": ("hunting", {"dynamism": 0.2}),
    "factory move=0.2": ("factory", {"dynamism": 0.2}),
    # cooperative workers at the released factory shaping sweep's point fac_move_prob 0.3 x close 0.8: a step
    # toward the agent with probability 0.24, a random one with 0.06 (p = 0.06 / 0.76 of the other steps)
    "factory coop=0.24": ("factory", {"dynamism": 0.06 / 0.76, "shaping": 0.24}),
    "factory coop=0.2 static": ("factory", {"shaping": 0.2}),  # the start of the shaping experiments' schedule
    "factory coop=1": ("factory", {"shaping": 1.0}),
    "hunting hard deer=0.2": ("hunting", {"deer_kind": "hard", "deer_speed": 0.2}),  # the shaping experiments' deer
    "scavenging p=0.25": ("scavenging", {"dynamism": 0.25}),
    # the released Fig. 5 hunting and scavenging environment shaping (the windows of `hunting-released` and
    # `scavenging-released`): place_schedule (60 000, 20 000) on 8x8 and (60 000, 30 000) on 10x10
    "hunting p=0.1 window": ("hunting", {"dynamism": 0.1, "shaping": "linear:0.928571428571:0:260000",
                                         "shaping_mechanism": "nearby"}),
    "scavenging p=0.25 window": ("scavenging", {"dynamism": 0.25, "food_growth": 0.2, "shaping": "linear:1:0:540000"}),
}
"""The settings the fidelity table reports: name -> (task, knobs)."""

RESOURCES: dict[str, tuple[Code, ...]] = {
    "salad": (Code.LETTUCE, Code.CARROT),
    "walled-salad": (Code.LETTUCE, Code.CARROT),
    "hunting": (Code.AXE, Code.DEER),
    "scavenging": (Code.FOOD,),
    "factory": (Code.METAL, Code.WOOD, Code.AXE),
}
"""Per task, the groups whose mean count on the grid is reported (deer counts every deer kind)."""


@dataclass(frozen=True)
class RandomPolicyStats:
    """One setting's statistics over seeds (one reset-free world per seed)."""

    name: str
    seeds: int
    steps: int
    solves: np.ndarray
    """Task completions per seed over ``steps`` steps."""
    first_solve: np.ndarray
    """Step of each seed's first completion (1-based); ``steps + 1`` where it never came."""
    counts: dict[str, float]
    """Mean number on the grid per resource group, over steps and seeds."""
    caught: np.ndarray
    """Steps per seed on which a predator caught the agent (all zero where the task has none)."""

    @property
    def solves_mean(self) -> float:
        """Mean completions per seed."""
        return float(self.solves.mean())

    @property
    def solves_ci(self) -> float:
        """Half-width of the normal 95 % confidence interval of ``solves_mean``."""
        return self._ci(self.solves)

    @staticmethod
    def _ci(values: np.ndarray) -> float:
        """Half-width of the normal 95 % confidence interval of the mean of ``values`` (one per seed)."""
        return float(1.96 * values.std(ddof=1) / np.sqrt(len(values))) if len(values) > 1 else float("nan")

    @property
    def never_solved(self) -> int:
        """Seeds that never completed the task."""
        return int((self.first_solve > self.steps).sum())

    def row(self) -> str:
        """One markdown table row: name, solves [CI], first-solve mean / median, never-solved, counts, caught."""
        first = self.first_solve.astype(np.float64)
        counts = ", ".join(f"{k} {v:.2f}" for k, v in self.counts.items())
        caught = f"{self.caught.mean():.0f} ± {self._ci(self.caught):.0f}" if self.caught.any() else "—"
        return (f"| {self.name} | {self.solves_mean:.2f} ± {self.solves_ci:.2f} | {first.mean():.0f} / "
                f"{np.median(first):.0f} | {self.never_solved} | {counts} | {caught} |")


HEADER = ("| setting | solves per seed (± 95 % CI) | first solve, mean / median step | seeds never solved | "
          "mean count on the grid | steps caught by a predator per seed (± 95 % CI) |\n|---|---|---|---|---|---|")


def measure(task: str, knobs: dict, seeds: int = 32, steps: int = 20_000, seed: int = 0, name: str = "",
            progress: bool = False) -> RandomPolicyStats:
    """Run ``seeds`` reset-free worlds of ``task`` (knobs and task parameters in ``knobs``) under a uniform
    random policy for ``steps`` steps; world i is seeded ``seed + i``, the actions by ``seed``.
    """
    if task not in TASKS:
        raise ValueError(f"unknown grid task {task!r}; choose one of {', '.join(TASKS)}")
    env = GridTaskVectorEnv(TASKS[task], seeds, copy=False, reset_free=True, reward="sparse", **knobs)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    groups = RESOURCES[task]
    solves = np.zeros(seeds, dtype=np.int64)
    caught = np.zeros(seeds, dtype=np.int64)
    first = np.full(seeds, steps + 1, dtype=np.int64)
    totals = np.zeros(len(groups), dtype=np.float64)
    for t in tqdm(range(1, steps + 1), desc=name or task, disable=not progress, leave=False):
        _, _, _, _, info = env.step(rng.integers(0, 7, seeds))
        solved = info["solved"]
        solves += solved
        caught += info["caught"]
        first[solved & (first > steps)] = t
        on_grid = GROUP[env.worlds["grid"]]
        for k, g in enumerate(groups):
            totals[k] += np.count_nonzero(on_grid == g)
    counts = {Code(g).name.lower(): totals[k] / (steps * seeds) for k, g in enumerate(groups)}
    return RandomPolicyStats(name or task, seeds, steps, solves, first, counts, caught)


def parse_params(pairs: list[str]) -> dict:
    """``['spawn_on_agent=False', 'max_material=6']`` -> ``{'spawn_on_agent': False, 'max_material': 6}``."""
    params = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise SystemExit(f"error: --param expects NAME=VALUE, got {pair!r}")
        try:
            params[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            params[key] = value
    return params


class _OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (what is wrong and how to mend it), without the usage dump."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def _count(text: str) -> int:
    """A whole number, also written ``2e4`` (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not value.is_integer():
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}")
    return int(value)


def _setting(text: str) -> str:
    """One of `SETTINGS` (an argparse type), the nearest named where ``text`` is none."""
    if text in SETTINGS:
        return text
    near = difflib.get_close_matches(text, SETTINGS, n=1, cutoff=0.5)
    near = near or [name for name in SETTINGS if name.startswith(text)][:1]
    hint = f"did you mean {near[0]!r}? " if near else ""
    raise argparse.ArgumentTypeError(f"unknown setting {text!r}; {hint}(choose among {', '.join(map(repr, SETTINGS))}; "
                                     f"quote a name with a space)")


def main(argv: list[str] | None = None) -> None:
    """Print the random-policy table for the standard settings (or those named with ``--setting``)."""
    parser = _OneLineParser(prog="python -m gridtasks.random_policy", description=__doc__.split("\n")[0],
                            allow_abbrev=False)
    parser.add_argument("--seeds", type=_count, default=32, help="worlds per setting, at least 2 (default 32)")
    parser.add_argument("--steps", type=_count, default=20_000, help="steps per world (default 20 000)")
    parser.add_argument("--setting", action="append", type=_setting, metavar="NAME",
                        help=f"only these settings, one a flag: {', '.join(map(repr, SETTINGS))}")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a task parameter for every setting that has it, e.g. spawn_on_agent=False")
    args = parser.parse_args(argv)
    if args.seeds < 2:
        parser.error(f"--seeds must be at least 2 (the table's intervals are over worlds), got {args.seeds}")
    if args.steps < 1:
        parser.error(f"--steps must be at least 1, got {args.steps}")
    params = parse_params(args.param)
    names = args.setting or list(SETTINGS)
    known = {field for name in names for field in TASKS[SETTINGS[name][0]].Config.__dataclass_fields__}
    if unknown := sorted(set(params) - known):
        parser.error(f"--param {', '.join(unknown)}: no selected setting's task has such a parameter "
                     f"(they have: {', '.join(sorted(known))})")
    settings = {}
    for name in names:  # every setting's configuration checked before the first is measured
        task, knobs = SETTINGS[name]
        fields = TASKS[task].Config.__dataclass_fields__
        settings[name] = task, {**knobs, **{k: v for k, v in params.items() if k in fields}}
        try:
            GridTaskVectorEnv(TASKS[task], 1, reset_free=True, reward="sparse", **settings[name][1]).close()
        except (ValueError, TypeError) as err:
            parser.error(f"setting {name!r} with --param {' '.join(args.param)}: {err}")
    print(HEADER)
    for name, (task, knobs) in settings.items():
        stats = measure(task, knobs, args.seeds, args.steps, name=name, progress=True)
        print(stats.row(), flush=True)


if __name__ == "__main__":
    main()
