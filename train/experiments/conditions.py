"""The building blocks of the experiments in `train.experiments.catalog` and `train.experiments.released`: the
smoke and quick budgets and the condition sets of the paper's figures (Fig. 4's four, Fig. 5's shaping arms, the
dynamism sweeps).
"""

from __future__ import annotations

from collections.abc import Mapping

from train.experiments.choices import DYNAMIC_P, SHAPING_BASE, SHAPING_SCHEDULE, SPARSE_EQUIVALENT
from train.experiments.experiment import Budget, Condition

__all__ = ["FLAT_LADDER", "SMOKE", "dynamism_conditions", "quick", "shaping_conditions", "sweep_conditions",
           "walls_conditions", "with_reward"]

FLAT_LADDER = {"reward_ladder": "flat"}
"""Factory's +1-per-stage, +100-per-delivery rewards: what its subgoal-mode arms trained with before the released
ladder became factory's default (their shipped runs), kept so that those arms re-run as shipped."""


SMOKE = Budget(seeds=2, steps=1_000, eval_every=500, eval_rollouts=10, overrides={"updates_per_epoch": 100},
               task_overrides={"foodcollector": {"eval_rollouts": 2, "eval_horizon": 100}})
"""Seconds per condition, for tests: 100 updates per epoch, two evaluations on 10 layouts (food collector:
2 short episodes)."""


def quick(seeds: int, steps: int | Mapping[str, int], eval_every: int = 10_000) -> Budget:
    """A laptop budget: the food collector evaluates 5 episodes instead of 10."""
    return Budget(seeds=seeds, steps=steps, eval_every=eval_every,
                  task_overrides={"foodcollector": {"eval_rollouts": 5}})


def dynamism_conditions(task: str, p: float | None = None) -> tuple[Condition, ...]:
    """{static, dynamic} x {episodic, reset-free} (Fig. 4), dynamic at ``p`` (the task's `DYNAMIC_P` by default)."""
    p = DYNAMIC_P[task] if p is None else p
    out = []
    for dyn_name, dyn in (("static", 0.0), ("dynamic", p)):
        for mode, reset_free in (("episodic", False), ("reset-free", True)):
            label = f"{dyn_name}{f' p={p:g}' if dyn else ''}, {'non-episodic' if reset_free else 'episodic'}"
            out.append(Condition(f"{dyn_name}-{mode}", label, {"dynamism": dyn, "reset_free": reset_free}))
    return tuple(out)


def with_reward(conditions: tuple[Condition, ...], reward: str, note: str, extra: Mapping | None = None
                ) -> tuple[Condition, ...]:
    """The same conditions trained with another reward mode (names unchanged, labels annotated), and ``extra``
    overrides.
    """
    return tuple(Condition(c.name, f"{c.label}, {note}", {**c.overrides, "reward": reward, **(extra or {})})
                 for c in conditions)


def shaping_conditions(task: str, reset_free: bool = True, suffix: str = "") -> tuple[Condition, ...]:
    """Env shaping + sparse / + subgoal, distance and one-time reward shaping, no shaping (Fig. 5, 8), less the
    arms whose reward is the sparse one on ``task`` (`SPARSE_EQUIVALENT`).
    """
    base = {**SHAPING_BASE[task], "reset_free": reset_free}
    schedule = SHAPING_SCHEDULE[task]
    table = [("env-shaping-sparse", "env shaping, sparse reward", {"shaping": schedule, "reward": "sparse"}),
             ("env-shaping-subgoal", "env shaping, subgoal reward", {"shaping": schedule, "reward": "subgoal"}),
             ("distance-reward", "distance reward shaping", {"reward": "distance"}),
             ("one-time-reward", "one-time reward shaping", {"reward": "one_time"}),
             ("no-shaping", "no shaping, sparse reward", {"reward": "sparse"})]
    if task == "foodcollector":  # no subgoals, hence no reward shaping (Fig. 5 caption)
        table = [row for row in table if row[0] in ("env-shaping-sparse", "no-shaping")]
    same = SPARSE_EQUIVALENT.get(task, frozenset())  # these arms would repeat the sparse arm of their shaping
    table = [row for row in table if row[2]["reward"] not in same]
    if task == "factory":  # its reward-shaped arms as shipped; 'factory-released' trains the released ladder
        table = [(name, f"{label}, flat ladder", {**knobs, "env_kwargs": FLAT_LADDER})
                 if knobs["reward"] in ("distance", "one_time") else (name, label, knobs)
                 for name, label, knobs in table]
    mode = ", non-episodic" if reset_free else ", episodic"
    return tuple(Condition(name + suffix, label + (mode if suffix else ""), {**base, **knobs})
                 for name, label, knobs in table)


def walls_conditions() -> tuple[Condition, ...]:
    """The walled salad's shaping arms, non-episodic then episodic (Figs. 8-10)."""
    return (shaping_conditions("walled-salad", True, "-reset-free")
            + shaping_conditions("walled-salad", False, "-episodic"))


def sweep_conditions(task: str, levels: tuple[float, ...]) -> tuple[Condition, ...]:
    """Non-episodic training at each dynamism level (Fig. 6 left and middle)."""
    return tuple(Condition(f"p{p:g}", f"p = {p:g}", {"dynamism": p, "reset_free": True}) for p in levels)
