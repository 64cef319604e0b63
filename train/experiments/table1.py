"""Table 1 of the paper: what a uniform random policy experiences in static, dynamic and shaped worlds.

* first-reward hitting time: steps until a random policy first completes the task in the reset-free
  training env (one world per seed, all seeds stepped together by the batched engine);
* marginal entropy of the egocentric view (inventory excluded) over a random policy's lifetime, as
  dynamism grows.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

DYNAMISM_LEVELS = (0.0, 0.01, 0.05, 0.1, 0.5)
"""The paper's dynamism sweep of Table 1 (factory worker move probability)."""

_SALAD_CONDITIONS = {"static": {}, "dynamic": {"dynamism": 0.1}, "shaped": {"dynamism": 0.05, "shaping": 1.0}}
HITTING_CONDITIONS = {
    "salad": _SALAD_CONDITIONS,
    "walled-salad": _SALAD_CONDITIONS,
    "hunting": {"static": {}, "dynamic": {"dynamism": 0.2}, "shaped": {"shaping": 1.0}},
    "scavenging": {"static": {}, "dynamic": {"dynamism": 0.5}, "shaped": {"shaping": 1.0}},
    "factory": {"static": {}, "dynamic": {"dynamism": 0.2}, "shaped": {"shaping": 0.2}},
}
"""Per task, the training envs compared by the hitting-time table (all reset-free, sparse reward).

Salad's shaped env grows ingredients at p = 0.05 as in the paper's shaping runs (with p = 0 nothing spawns
before the first completion, so shaping could not act). The factory's cooperative-worker strength 0.2
matches the original code's approach probability (move 0.1-0.3 × close 0.5-0.8); at strength 1 workers
crowd the agent and the hitting time grows (reported in the README)."""


@dataclass(frozen=True)
class Summary:
    """Mean and standard deviation over seeds of one measured condition."""

    condition: str
    mean: float
    std: float
    seeds: int
    censored: int = 0
    """Seeds that never reached the event within the step budget (counted at the budget)."""

    def __str__(self) -> str:
        note = f" ({self.censored} censored)" if self.censored else ""
        return f"{self.condition:>24s}: {self.mean:9.1f} ± {self.std:7.1f}  (n={self.seeds}){note}"


def _vector_env(task: str, num: int, **knobs):
    import gymnasium as gym

    import gridtasks

    if task not in gridtasks.ENV_IDS:
        raise ValueError(f"unknown grid task {task!r}; choose one of {', '.join(gridtasks.ENV_IDS)}")
    return gym.make_vec(gridtasks.ENV_IDS[task], num_envs=num, vectorization_mode="vector_entry_point",
                        copy=False, reset_free=True, reward="sparse", **knobs)


def hitting_times(task: str, seeds: int = 25, max_steps: int = 50_000, seed: int = 0, **knobs) -> np.ndarray:
    """Steps until each seed's random policy first completes the task (``max_steps`` if it never did)."""
    vec = _vector_env(task, seeds, **knobs)
    vec.reset(seed=seed)
    rng = np.random.default_rng(seed)
    first = np.full(seeds, max_steps, dtype=np.int64)
    pending = np.ones(seeds, dtype=bool)
    for t in range(1, max_steps + 1):
        _, _, _, _, info = vec.step(rng.integers(0, 7, seeds))
        hit = pending & info["solved"]
        first[hit] = t
        pending &= ~hit
        if not pending.any():
            break
    return first


def view_entropies(task: str, seeds: int = 5, steps: int = 50_000, seed: int = 0, **knobs) -> np.ndarray:
    """Marginal entropy (nats) of each seed's egocentric views over ``steps`` random steps."""
    vec = _vector_env(task, seeds, **knobs)
    view_dim = vec.template.observation_split[0]
    obs, _ = vec.reset(seed=seed)
    rng = np.random.default_rng(seed)
    counts = [Counter() for _ in range(seeds)]
    for _ in range(steps):
        obs, *_ = vec.step(rng.integers(0, 7, seeds))
        packed = np.packbits(obs[:, :view_dim].astype(np.uint8), axis=1)
        for counter, row in zip(counts, packed):
            counter[row.tobytes()] += 1
    return np.array([_entropy(c) for c in counts])


def _entropy(counter: Counter) -> float:
    p = np.fromiter(counter.values(), dtype=np.float64)
    p /= p.sum()
    return float(-(p * np.log(p)).sum())


def summarise(condition: str, values: np.ndarray, budget: int | None = None) -> Summary:
    """Mean ± std over seeds (with the number of seeds censored at ``budget``)."""
    censored = int((values >= budget).sum()) if budget is not None else 0
    return Summary(condition, float(values.mean()), float(values.std(ddof=1) if len(values) > 1 else 0.0),
                   len(values), censored)


def hitting_time_table(task: str, seeds: int = 25, max_steps: int = 50_000, seed: int = 0) -> list[Summary]:
    """Table 1 left: hitting time in the static, dynamic and shaped reset-free training envs."""
    conditions = HITTING_CONDITIONS[task]
    return [summarise(f"{name} non-episodic", hitting_times(task, seeds, max_steps, seed, **knobs), max_steps)
            for name, knobs in conditions.items()]


def entropy_table(task: str, seeds: int = 5, steps: int = 50_000, seed: int = 0,
                  levels=DYNAMISM_LEVELS) -> list[Summary]:
    """Table 1 right: marginal view entropy as dynamism grows."""
    return [summarise(f"dynamism p={p:g}", view_entropies(task, seeds, steps, seed, dynamism=p)) for p in levels]
