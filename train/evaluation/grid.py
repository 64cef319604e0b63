"""A policy's success across evaluation settings: epsilons x horizons x layout sets, split by the first view.

The paper's protocol is one point of this grid (epsilon 0.1, the test horizon, the 100 validation layouts).
The grid asks where a policy fails: on layouts where nothing it needs is in its first 5x5 view it has to
search, and a memoryless policy that cannot search loops until exploration noise breaks the loop (issue 18).

Layout sets: ``validation`` (the fixed validation layouts, `ecology.validation_seeds`) and ``fresh`` (test-MDP
layouts from seeds `FRESH_SEED_BASE` + i, disjoint from the validation and training seeds). Each rollout's
split is whether an object needed from an empty hand (salad: a lettuce or a carrot) is in the first view.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ecology import validation_seeds
from gridtasks.codes import Code
from train.storage.policy import Policy
from train.tasks import get_task, make_vector_env

FRESH_SEED_BASE = 2_000_000_000
"""Seed of the first fresh layout (validation layouts start at 1 000 000 000, training worlds at 0)."""

NEEDED_FIRST = {"salad": (Code.LETTUCE, Code.CARROT), "walled-salad": (Code.LETTUCE, Code.CARROT)}
"""Objects an empty-handed agent needs first, per task (the tasks the first-view split supports)."""

SPLITS = ("all", "needed item in first view", "nothing needed in first view")
"""The rows of each (layouts, horizon, epsilon) cell."""

GRID_COLUMNS = ("layouts", "horizon", "epsilon", "split", "rollouts", "success", "low", "high")
"""Columns of the grid's rows (and of its CSV); low/high bound the 95 % Wilson interval of the success."""


def fresh_seeds(n: int) -> list[int]:
    """The seeds of the first ``n`` fresh layouts."""
    return [FRESH_SEED_BASE + i for i in range(n)]


def needed_in_first_view(task: str, test_kwargs: dict[str, Any], seeds: Sequence[int]) -> np.ndarray:
    """(N,) whether the first observation of each layout (the test MDP reset with ``seeds[i]``) shows an object
    of `NEEDED_FIRST` in the agent's view.
    """
    if task not in NEEDED_FIRST:
        raise ValueError(f"the first-view split knows the needs of {', '.join(NEEDED_FIRST)} only, not {task!r}; "
                         f"evaluate without it (split=False)")
    env = make_vector_env(get_task(task).env_id, len(seeds), test_kwargs)
    try:
        obs, _ = env.reset(seed=[int(s) for s in seeds])
        channels = list(env.template.channels)
    finally:
        env.close()
    cells = 25  # the 5 x 5 view, channel-major (index channel * 25 + row * 5 + col)
    view = np.asarray(obs)[:, : len(channels) * cells].reshape(len(seeds), len(channels), cells)
    wanted = [channels.index(code) for code in NEEDED_FIRST[task]]
    return view[:, wanted].any(axis=(1, 2))


def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval (95 % by default) of a binomial proportion; (nan, nan) for n = 0."""
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def layout_sets(validation: int, fresh: int) -> dict[str, list[int]]:
    """The named layout sets of the grid (a set of size 0 is left out)."""
    sets = {"validation": validation_seeds(validation), "fresh": fresh_seeds(fresh)}
    return {name: seeds for name, seeds in sets.items() if seeds}


def split_rows(base: dict[str, Any], solved: np.ndarray, in_view: np.ndarray | None) -> list[dict[str, Any]]:
    """One row per split (only 'all' without ``in_view``): rollouts, success and its interval."""
    masks = {"all": np.ones_like(solved, dtype=bool)}
    if in_view is not None:
        masks |= {SPLITS[1]: in_view, SPLITS[2]: ~in_view}
    rows = []
    for split, mask in masks.items():
        n, k = int(mask.sum()), int(solved[mask].sum())
        low, high = wilson(k, n)
        rows.append({**base, "split": split, "rollouts": n, "success": k / n if n else math.nan,
                     "low": low, "high": high})
    return rows


def evaluate_grid(policy: Policy, epsilons: Sequence[float], horizons: Sequence[int], validation: int = 100,
                  fresh: int = 0, split: bool = True, dynamism: float | None = None) -> list[dict[str, Any]]:
    """Success of ``policy`` at every (layout set, horizon, epsilon), split by the first view if ``split`` and
    the task defines one (`NEEDED_FIRST`), in the test MDP with ``dynamism`` if given.
    """
    split = split and policy.task in NEEDED_FIRST
    rows = []
    for name, seeds in layout_sets(validation, fresh).items():
        in_view = needed_in_first_view(policy.task, policy.test_kwargs, seeds) if split else None
        for horizon in horizons:
            for eps in epsilons:
                result = policy.evaluate(len(seeds), eps, horizon=horizon, layout_seeds=seeds, dynamism=dynamism)
                base = {"layouts": name, "horizon": int(horizon), "epsilon": float(eps)}
                rows += split_rows(base, result.solved[0], in_view)
    return rows


def format_grid(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The grid as aligned text lines: success in % with its 95 % interval."""
    head = f"{'layouts':<11}{'horizon':>8}{'epsilon':>8}  {'split':<29}{'rollouts':>9}  success [95% CI]"
    lines = [head, "-" * len(head)]
    for r in rows:
        ci = "—" if r["rollouts"] == 0 else (f"{100 * r['success']:5.1f} % [{100 * r['low']:.1f}, "
                                             f"{100 * r['high']:.1f}]")
        lines.append(f"{r['layouts']:<11}{r['horizon']:>8}{r['epsilon']:>8g}  {r['split']:<29}{r['rollouts']:>9}  {ci}")
    return lines
