"""What an experiment is: conditions (config overrides) per task, and the budgets they run at.

The paper's experiments themselves are data in `train.experiments.catalog`, which re-exports these classes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from train.config.checks import unknown_choice

BUDGETS = ("smoke", "quick", "paper")
"""Budget names, cheapest first."""


@dataclass(frozen=True)
class Condition:
    """One training condition of a task: a directory name, a legend label and its config overrides."""

    name: str
    """Directory name (no spaces), e.g. 'dynamic-reset-free'."""
    label: str
    """Legend label in plots and tables."""
    overrides: Mapping[str, Any] = field(default_factory=dict)
    """Flat `TrainConfig.replace` overrides (env knobs, reward, rnd, env_kwargs ...)."""
    measure: str | None = None
    """For measurement experiments: 'hitting-time' or 'entropy' (no training)."""


@dataclass(frozen=True)
class Budget:
    """Seeds, steps and evaluation of every condition of an experiment."""

    seeds: int
    """Seeds per condition (trained together in one process)."""
    steps: int | Mapping[str, int]
    """Environment steps per seed: one number, or one per task."""
    eval_every: int
    """Evaluate every this many steps (a multiple of 500)."""
    eval_rollouts: int | None = None
    """Validation rollouts per seed (None: the task's 100 layouts; food collector 10 episodes)."""
    overrides: Mapping[str, Any] = field(default_factory=dict)
    """Extra flat overrides for every task (e.g. checkpoint_every)."""
    task_overrides: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    """Extra flat overrides for one task only."""

    def steps_for(self, task: str) -> int:
        """Steps per seed for ``task``."""
        return int(self.steps[task] if isinstance(self.steps, Mapping) else self.steps)


@dataclass(frozen=True)
class Experiment:
    """A figure or table of the paper as runs: conditions per task, three budgets."""

    name: str
    paper: str
    """Where in the paper, e.g. 'Fig. 4'."""
    title: str
    description: str
    conditions: Mapping[str, tuple[Condition, ...]]
    """Task -> its conditions (tasks in the paper's panel order)."""
    paper_steps: Mapping[str, int]
    """Task -> steps per seed of the paper budget."""
    paper_seeds: int
    budgets: Mapping[str, Budget]
    """'smoke' and 'quick' budgets ('paper' is derived from paper_steps and paper_seeds)."""
    heatmaps: bool = False
    """Plot visitation heat-maps at four points of training."""
    videos: bool = False
    """The report renders a rollout video of each condition's final policy."""
    milestones: tuple[int, ...] = ()
    """Steps at which the report tabulates every condition (mean, CI, seeds learned) besides the last one."""
    panel_per_setting: bool = False
    """The report's curves give each task's non-episodic and episodic conditions a panel each (the paper's
    Fig. 8 has one per setting), instead of one panel per task."""

    @property
    def tasks(self) -> tuple[str, ...]:
        """The experiment's tasks, in panel order."""
        return tuple(self.conditions)

    @property
    def is_measurement(self) -> bool:
        """True for the Table 1 measurements (random policy, no training)."""
        return any(c.measure for conds in self.conditions.values() for c in conds)

    def budget(self, name: str) -> Budget:
        """The budget called ``name`` (one of `BUDGETS`)."""
        if name == "paper":
            return Budget(self.paper_seeds, dict(self.paper_steps), eval_every=5_000)
        if name not in self.budgets:
            raise unknown_choice("budget", name, BUDGETS)
        return self.budgets[name]

    def select_tasks(self, tasks: list[str] | tuple[str, ...] | None) -> tuple[str, ...]:
        """The requested subset of tasks (all when None), validated, in panel order."""
        if not tasks:
            return self.tasks
        unknown = [t for t in tasks if t not in self.conditions]
        if unknown:
            raise unknown_choice(f"{self.name} task", unknown, self.tasks)
        return tuple(t for t in self.tasks if t in tasks)

    def select_conditions(self, task: str, names: Sequence[str] | None) -> list[Condition]:
        """The task's conditions named in ``names`` (all when None), validated, in panel order."""
        if not names:
            return list(self.conditions[task])
        known = [c.name for c in self.conditions[task]]
        unknown = [n for n in names if n not in known]
        if unknown:
            raise unknown_choice(f"{self.name}/{task} condition", unknown, known)
        return [c for c in self.conditions[task] if c.name in names]

    def describe(self) -> dict[str, Any]:
        """A JSON-friendly summary (written next to the runs, read back by the report)."""
        return {
            "name": self.name, "paper": self.paper, "title": self.title, "description": self.description,
            "heatmaps": self.heatmaps, "videos": self.videos, "measurement": self.is_measurement,
            "milestones": list(self.milestones), "panel_per_setting": self.panel_per_setting,
            "tasks": {task: [{"name": c.name, "label": c.label, "overrides": dict(c.overrides),
                              "measure": c.measure} for c in conds]
                      for task, conds in self.conditions.items()},
        }
