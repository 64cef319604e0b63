"""Several experiments as one sweep: ``ecorl run A B ...`` or ``ecorl run --all``.

Each experiment keeps its own results directory, experiment.json and run directories, as if run alone. Two things
change when they run together: a configuration that several experiments name (a sweep's p 0 is the headline's
static non-episodic run) is trained once and the finished run directory copied to the others, and the conditions
of one task can share a pack across experiments (``--pack``, the default on a GPU), since packing groups whatever
jobs it is given (`train.experiments.sweep.pack_jobs`).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from pathlib import Path

from train.config import TrainConfig
from train.config.checks import unknown_choice
from train.experiments.experiment import Experiment
from train.experiments.jobs import Job, job_is_done, job_is_done_safely
from train.experiments.sweep import plan
from train.storage.fileio import atomic_dir, is_temporary
from train.storage.rundir import LOCK_NAME, RunDir

__all__ = ["fill_copies", "finished_twins", "plan_many", "split_copies"]


def plan_many(experiments: Sequence[Experiment], budget: str, out: str | Path, tasks: Sequence[str] | None = None,
              conditions: Sequence[str] | None = None, seeds: int | None = None, steps: int | None = None,
              device: str | None = None) -> list[Job]:
    """The jobs of every experiment, each restricted to the ``tasks`` and ``conditions`` it has (an experiment with
    none of them is left out); ValueError when nothing is left.
    """
    _check_named(experiments, tasks, conditions)
    jobs: list[Job] = []
    for exp in experiments:
        for task in (t for t in exp.tasks if not tasks or t in tasks):
            names = [c.name for c in exp.conditions[task] if not conditions or c.name in conditions]
            if names:
                jobs += plan(exp, budget, out, [task], seeds, steps, names, (), device)
    if not jobs:
        raise ValueError(f"no experiment of {', '.join(e.name for e in experiments)} has the tasks or conditions "
                         f"asked for; see 'ecorl run --list' and 'ecorl run NAME --dry-run'")
    return jobs


def _check_named(experiments: Sequence[Experiment], tasks: Sequence[str] | None,
                 conditions: Sequence[str] | None) -> None:
    """ValueError (naming the nearest valid name) for a task or condition that none of the ``experiments`` has."""
    known_tasks = list(dict.fromkeys(t for exp in experiments for t in exp.tasks))
    unknown = [t for t in tasks or () if t not in known_tasks]
    if unknown:
        raise unknown_choice("task", unknown, known_tasks)
    known = list(dict.fromkeys(c.name for exp in experiments for t in exp.tasks if not tasks or t in tasks
                               for c in exp.conditions[t]))
    unknown = [c for c in conditions or () if c not in known]
    if unknown:
        raise unknown_choice("condition", unknown, known)


def _identity(job: Job) -> str:
    return json.dumps(TrainConfig.from_dict(job.config).identity(), sort_keys=True)


def split_copies(jobs: Sequence[Job]) -> tuple[list[Job], list[tuple[Job, Job]]]:
    """(the jobs to train, (copy, original) pairs): a job whose settings equal an earlier job's, runtime settings
    aside, is that job's copy and is not trained again.
    """
    first: dict[str, Job] = {}
    train, copies = [], []
    for job in jobs:
        if job.is_measurement:
            train.append(job)
            continue
        key = _identity(job)
        if key in first:
            copies.append((job, first[key]))
        else:
            first[key] = job
            train.append(job)
    return train, copies


def _not_copied(name: str) -> bool:
    return name.startswith("checkpoint.") or name == LOCK_NAME or is_temporary(name)


def fill_copy(copy: Job, original: Job) -> str:
    """Give ``copy`` the finished run directory of ``original`` (all but its checkpoint and lock, with the copy's own
    config.json), built in a hidden folder beside it and renamed into place; one line saying what happened.
    """
    if job_is_done(copy):
        return f"{copy.name}: already there"
    if not job_is_done(original):
        return f"{copy.name}: not filled in, {original.name} has not finished"
    dest = Path(copy.run_dir)
    if dest.exists() and any(dest.iterdir()):
        return (f"{copy.name}: not filled in from {original.name}, its folder holds files already (train it with "
                f"'ecorl run {copy.experiment} --condition {copy.condition}', or empty it)")
    with atomic_dir(dest, "copying") as staging:
        shutil.copytree(original.run_dir, staging, ignore=lambda _, names: [n for n in names if _not_copied(n)])
        RunDir(staging).write_config(TrainConfig.from_dict(copy.config))
    return f"{copy.name}: the same run as {original.name}, copied"


def fill_copies(copies: Sequence[tuple[Job, Job]]) -> list[str]:
    """`fill_copy` for each pair; what happened to each."""
    return [fill_copy(copy, original) for copy, original in copies]


def finished_twins(jobs: Sequence[Job], others: Sequence[Experiment], budget: str, out: str | Path,
                   seeds: int | None = None, steps: int | None = None) -> tuple[list[Job], list[tuple[Job, Job]]]:
    """(the jobs to train, (copy, original) pairs): a job not yet done whose settings equal a finished run of one of
    ``others`` in ``out`` (the same budget and overrides) is copied from it instead of trained again, unless its own
    folder already holds files (a run of its own, resumed as usual).
    """
    finished: dict[str, Job] = {}
    for exp in others:
        try:
            planned = plan_many([exp], budget, out, seeds=seeds, steps=steps)
        except ValueError:  # an experiment these overrides do not fit has no runs to share
            continue
        for job in planned:
            if not job.is_measurement and job_is_done_safely(job):
                finished.setdefault(_identity(job), job)
    train, copies = [], []
    for job in jobs:
        twin = None if job.is_measurement or job.restart or job_is_done_safely(job) else finished.get(_identity(job))
        folder = Path(job.run_dir)
        if twin is not None and not (folder.exists() and any(folder.iterdir())):
            copies.append((job, twin))
        else:
            train.append(job)
    return train, copies
