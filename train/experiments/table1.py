"""Table 1 of the paper: what a uniform random policy experiences in static, dynamic and shaped worlds.

* first-reward hitting time: steps until a random policy first completes the task in the reset-free
  training env (one world per seed, all seeds stepped together by the batched engine);
* marginal entropy of the egocentric view (inventory excluded) over a random policy's lifetime, as
  dynamism grows.

Both are computed by `ecology.measure` on the recorded rollouts. Each task's static, dynamic and shaped
worlds come from the experiments' own tables (`train.experiments.catalog`), so Table 1 measures the worlds
the agents train in. A measurement writes ``table.csv`` (`TABLE_FIELDS`, read back by the report) and
``table.md``; `format_value` is the one way a row's value is shown.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ecology import hitting_time, marginal_entropy, parse_schedule
from train.config.checks import unknown_choice
from train.experiments.choices import DYNAMIC_P, GRID_TASKS, SHAPING_BASE, SHAPING_SCHEDULE
from train.storage.fileio import atomic_text

MEASUREMENTS = ("hitting-time", "entropy")
"""The two measurements of Table 1."""
DYNAMISM_LEVELS = (0.0, 0.01, 0.05, 0.1, 0.5)
"""The paper's dynamism sweep of Table 1 (factory worker move probability)."""
TABLE_FIELDS = ("condition", "mean", "std", "seeds", "censored")
"""Columns of a measurement's table.csv, one row per condition."""


def hitting_conditions(task: str) -> dict[str, dict[str, Any]]:
    """The reset-free, sparse-reward training envs the hitting-time table compares: knobs by condition.

    Dynamic is the task's dynamic p of the experiments. Shaped is the world the shaping experiments train in
    (`SHAPING_BASE`: salad's ingredients growing at p = 0.05, hunting's hard deer fleeing at 0.2) at the start
    of the task's shaping schedule (the factory's cooperative workers at strength 0.2, the original code's
    approach probability; at strength 1 workers crowd the agent and the hitting time grows).
    """
    base = dict(SHAPING_BASE[task])
    shaped = {**base.pop("env_kwargs", {}), **base, "shaping": parse_schedule(SHAPING_SCHEDULE[task])(0)}
    return {"static": {}, "dynamic": {"dynamism": DYNAMIC_P[task]}, "shaped": shaped}


def _vector_env(task: str, num: int, **knobs):
    """``num`` reset-free, sparse-reward worlds of a grid task in one batched env."""
    import gymnasium as gym

    from train.tasks import TASKS

    if task not in GRID_TASKS:
        raise unknown_choice("grid task", task, GRID_TASKS)
    return gym.make_vec(TASKS[task].env_id, num_envs=num, vectorization_mode="vector_entry_point",
                        copy=False, reset_free=True, reward="sparse", **knobs)


def hitting_times(task: str, seeds: int = 25, max_steps: int = 50_000, seed: int = 0, **knobs) -> np.ndarray:
    """Steps until each seed's random policy first completes the task (``max_steps`` if it never did)."""
    vec = _vector_env(task, seeds, **knobs)
    vec.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = int(vec.single_action_space.n)
    solved, pending = [], np.ones(seeds, dtype=bool)
    for _ in range(max_steps):
        _, _, _, _, info = vec.step(rng.integers(0, actions, seeds))
        solved.append(info["solved"])
        pending &= ~info["solved"]
        if not pending.any():
            break
    times = [hitting_time(events) for events in np.array(solved).T]
    return np.array([max_steps if t is None else t for t in times], dtype=np.int64)


def view_entropies(task: str, seeds: int = 5, steps: int = 50_000, seed: int = 0, **knobs) -> np.ndarray:
    """Marginal entropy (nats) of each seed's egocentric views over ``steps`` random steps."""
    vec = _vector_env(task, seeds, **knobs)
    view_dim = vec.template.observation_split[0]
    vec.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = int(vec.single_action_space.n)
    views = np.empty((steps, seeds, -(-view_dim // 8)), dtype=np.uint8)  # bit-packed, one row per step
    for t in range(steps):
        obs, *_ = vec.step(rng.integers(0, actions, seeds))
        views[t] = np.packbits(obs[:, :view_dim].astype(np.uint8), axis=1)
    return np.array([marginal_entropy(views[:, k]) for k in range(seeds)])


def summarise(condition: str, values: np.ndarray, budget: int | None = None) -> dict[str, Any]:
    """A table row: mean ± std over seeds, and the seeds censored at ``budget`` (never reached the event)."""
    censored = int((values >= budget).sum()) if budget is not None else 0
    std = float(values.std(ddof=1) if len(values) > 1 else 0.0)
    return {"condition": condition, "mean": float(values.mean()), "std": std, "seeds": len(values),
            "censored": censored}


def measure_rows(kind: str, task: str, seeds: int, steps: int, seed: int = 0) -> list[dict[str, Any]]:
    """One Table 1 measurement of a grid task: a row per condition (`TABLE_FIELDS`)."""
    if kind == "hitting-time":
        return [summarise(f"{name} non-episodic", hitting_times(task, seeds, steps, seed, **knobs), steps)
                for name, knobs in hitting_conditions(task).items()]
    if kind == "entropy":
        return [summarise(f"dynamism p={p:g}", view_entropies(task, seeds, steps, seed, dynamism=p))
                for p in DYNAMISM_LEVELS]
    raise unknown_choice("measurement", kind, MEASUREMENTS)


def format_value(kind: str, row: dict[str, Any]) -> str:
    """A row's value as every table shows it: 'mean ± std', whole steps or nats to 0.01, censored seeds."""
    digits = 0 if kind == "hitting-time" else 2
    censored = f" ({row['censored']} censored)" if row["censored"] else ""
    return f"{row['mean']:.{digits}f} ± {row['std']:.{digits}f}{censored}"


def write_table(kind: str, rows: Sequence[dict[str, Any]], stem: Path, title: str) -> tuple[Path, Path]:
    """Write ``stem``.csv (`TABLE_FIELDS`) and ``stem``.md (the shown values); return both paths."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=TABLE_FIELDS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    csv_path, md_path = stem.with_suffix(".csv"), stem.with_suffix(".md")
    stem.parent.mkdir(parents=True, exist_ok=True)
    atomic_text(csv_path, buf.getvalue())
    lines = [f"### {title}", "", "| condition | mean ± std | seeds |", "|---|---|---|"]
    lines += [f"| {r['condition']} | {format_value(kind, r)} | {r['seeds']} |" for r in rows]
    atomic_text(md_path, "\n".join(lines) + "\n")
    return csv_path, md_path
