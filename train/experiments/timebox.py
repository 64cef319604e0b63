"""Size an experiment's runs to a time budget, from this machine's speed measured in the first seconds.

`measure_speed` trains one job's configuration for a few epochs (a fully random epoch and a mostly greedy one,
which costs a forward pass per step, and one evaluation), in as many processes at once as will train side by side
(`measure_speed_together`); `fit_steps` turns that into the
steps per seed every job can take so that all of them, run ``workers`` at a time, end within the budget.
The estimate is conservative: it counts each job's start-up, every evaluation and a margin for checkpoints.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from train.config import TrainConfig

MARGIN = 1.1
"""Factor on the predicted training time when sizing runs (checkpoints, a busier machine later on); the
prediction printed is the estimate itself."""

MIN_EVALUATIONS = 2
"""A sized run takes at least this many evaluation intervals (a curve needs points)."""


@dataclass(frozen=True)
class Speed:
    """What one job costs on this machine, measured."""

    startup_s: float
    """Seconds from a new worker to the first trained epoch (environment compilation; the imports where the
    worker's process had not done them: workers fork from a server that has, `worker_context`)."""
    random_epoch_s: float
    """Seconds per epoch while every action is random (exploration epsilon 1)."""
    greedy_epoch_s: float
    """Seconds per epoch at the final exploration epsilon (a forward pass per step)."""
    evaluation_s: float
    """Seconds per evaluation."""

    def describe(self, cfg: TrainConfig) -> str:
        """One line: steps/s per seed early and late in training, and the evaluation's cost."""
        k, n = cfg.run.seeds, cfg.dqn.epoch_steps
        return (f"{n / self.random_epoch_s:.0f} steps/s per seed exploring, {n / self.greedy_epoch_s:.0f} acting "
                f"greedily ({k} seeds in one process), {self.evaluation_s:.1f} s per evaluation")

    def run_seconds(self, cfg: TrainConfig, margin: float = MARGIN) -> float:
        """Predicted seconds of one job of ``cfg`` (start-up, every epoch at its epsilon, every evaluation),
        the training's part times ``margin``.
        """
        dqn, k = cfg.dqn, cfg.run.seeds
        greedy_weight = 1.0 - dqn.eps_end ** k  # an epoch calls the network unless every seed explores
        total = self.startup_s
        for epoch in range(cfg.num_epochs):
            step = dqn.warmup_steps + epoch * dqn.epoch_steps
            share = (1.0 - dqn.epsilon(step) ** k) / greedy_weight if greedy_weight > 0 else 1.0
            total += self.random_epoch_s + (self.greedy_epoch_s - self.random_epoch_s) * share
        evaluations = cfg.num_epochs // cfg.eval_epochs + 1
        return total * margin + evaluations * self.evaluation_s

    def seconds_left(self, cfg: TrainConfig, done: int, margin: float = MARGIN) -> float:
        """Predicted seconds to take a job of ``cfg`` from step ``done`` (a resumed run) to its end."""
        if done <= 0:
            return self.run_seconds(cfg, margin)
        trained = self.run_seconds(cfg.replace(steps=done), margin) - self.startup_s * margin
        return max(self.run_seconds(cfg, margin) - trained, self.startup_s * margin)


def _timed_epochs(cfg: TrainConfig, epochs: int, evaluate: bool = False) -> tuple[float, float, float]:
    """(seconds to the end of the first epoch, seconds per later epoch, seconds of one evaluation)."""
    from train.loop.trainer import Trainer

    began = time.perf_counter()
    trainer = Trainer(cfg)
    try:
        trainer.train_epoch()
        first = time.perf_counter()
        for _ in range(epochs):
            trainer.train_epoch()
        later = time.perf_counter()
        if evaluate:
            trainer.evaluate()
        done = time.perf_counter()
    finally:
        trainer.close()
    return first - began, (later - first) / epochs, done - later


def measure_speed(config: dict[str, Any], epochs: int = 2) -> Speed:
    """Train the job configuration ``config`` (`TrainConfig.to_dict`) briefly here and time it."""
    cfg = TrainConfig.from_dict(config).replace(progress=False, steps=10_000)
    start = time.perf_counter()
    first, random_epoch, _ = _timed_epochs(cfg.replace(eps_start=1.0, eps_end=1.0), epochs)
    startup = time.perf_counter() - start - random_epoch * epochs  # imports and compilation included
    _, greedy_epoch, evaluation = _timed_epochs(cfg.replace(eps_start=cfg.dqn.eps_end), epochs, evaluate=True)
    return Speed(max(startup, first), random_epoch, max(greedy_epoch, random_epoch), evaluation)


def measure_speed_together(config: dict[str, Any], copies: int) -> Speed:
    """`measure_speed` in ``copies`` fresh processes at once, as the sized runs will share the machine; the
    slowest copy's times (each field its largest). On a machine whose cores share a physical core or a cache,
    runs side by side are slower than one alone: measuring one alone forecast a two-run demo 47 % short.
    """
    if copies <= 1:
        return measure_speed(config)
    from train.experiments.executors import worker_context

    with worker_context().Pool(copies) as pool:
        speeds = pool.map(measure_speed, [config] * copies)
    return Speed(*(max(getattr(s, f.name) for s in speeds) for f in fields(Speed)))


def fit_steps(speed: Speed, config: dict[str, Any], jobs: int, workers: int, seconds: float, done: int = 0) -> int:
    """The most steps per seed (a multiple of the evaluation interval, at most the configuration's own) that
    ``jobs`` runs of ``config``, ``workers`` at a time, finish in ``seconds``, where they resume at step ``done``;
    at least `MIN_EVALUATIONS` intervals and ``done``, even where that is more than the time or the
    configuration's own steps allow.
    """
    cfg = TrainConfig.from_dict(config)
    waves = math.ceil(jobs / max(1, min(workers, jobs)))
    every = cfg.eval.eval_every
    low = max(MIN_EVALUATIONS, math.ceil(done / every))
    high = max(low, cfg.run.steps // every)
    while low < high:  # the largest multiple whose predicted time fits
        mid = (low + high + 1) // 2
        if waves * speed.seconds_left(cfg.replace(steps=mid * every), done) <= seconds:
            low = mid
        else:
            high = mid - 1
    return low * every


def sized(config: dict[str, Any], steps: int) -> dict[str, Any]:
    """``config`` with ``steps`` per seed (and its checkpoint interval scaled as the catalog does)."""
    cfg = TrainConfig.from_dict(config)
    every = max(cfg.eval.eval_every, min(50_000, math.ceil(steps / 10)))
    return cfg.replace(steps=steps, checkpoint_every=every).to_dict()


def resize_jobs(jobs: list, steps: int) -> list:
    """The jobs with ``steps`` per seed."""
    return [replace(job, config=sized(job.config, steps)) for job in jobs]


REPORT_RESERVE_S = 75.0
"""Seconds kept at the end of a time budget for the report (figures, videos)."""


def timebox(jobs: list, seconds_left: float, workers: int, say, asked_seconds: float | None = None) -> list:
    """Measure this machine on the first job and size every job to end ``seconds_left`` from now, less the
    report's reserve; ``say`` prints a line. Jobs already longer than that keep their own steps when done.
    ``asked_seconds``: the whole time the user gave (default ``seconds_left``), for the advice when even the
    shortest runs do not fit.
    """
    if not jobs or any(j.is_measurement for j in jobs):
        return jobs
    began = time.perf_counter()
    say("measuring this machine's training speed (a few seconds) ...")
    speed = measure_speed_together(jobs[0].config, min(workers, len(jobs)))
    cfg = TrainConfig.from_dict(jobs[0].config)
    left = seconds_left - (time.perf_counter() - began) - REPORT_RESERVE_S
    done = min(_done_step(job) for job in jobs)
    if done:
        say(f"resuming: the runs stand at step {done:,} or later, and go on from there")
    steps = fit_steps(speed, jobs[0].config, len(jobs), workers, left, done)
    waves = math.ceil(len(jobs) / max(1, min(workers, len(jobs))))
    predicted = waves * speed.seconds_left(cfg.replace(steps=steps), done, margin=1.0)
    say(f"speed: {speed.describe(cfg)}; {len(jobs)} runs, {min(workers, len(jobs))} at a time, in "
        f"{max(left, 0) / 60:.1f} min: {steps:,} steps per seed (predicted {predicted / 60:.1f} min, sized with a "
        f"{MARGIN - 1:.0%} margin; the budget's own: {cfg.run.steps:,})")
    if predicted > left:
        asked = seconds_left if asked_seconds is None else asked_seconds
        say(f"warning: even the shortest runs ({MIN_EVALUATIONS} evaluation intervals, {steps:,} steps per seed) "
            f"take about {predicted / 60:.1f} min here, more than the {max(left, 0) / 60:.1f} min left after "
            f"measuring and the report's {REPORT_RESERVE_S:.0f} s: this will end late (give --minutes "
            f"{math.ceil((asked + predicted - left) / 60) + 1} or more, or fewer --condition/--seeds)")
    return resize_jobs(jobs, steps)


def _duration(seconds: float) -> str:
    """'3 h 05 min', '12 min', or '40 s'."""
    if seconds < 60:
        return f"{seconds:.0f} s"
    hours, minutes = divmod(round(seconds / 60), 60)
    return f"{hours} h {minutes:02d} min" if hours else f"{minutes} min"


def makespan(seconds: list[float], workers: int) -> float:
    """Wall time of runs of ``seconds`` each, ``workers`` at a time, longest first (as `run_jobs` starts them)."""
    lanes = [0.0] * max(1, workers)
    for s in sorted(seconds, reverse=True):
        lanes[lanes.index(min(lanes))] += s
    return max(lanes)


def run_kind(job) -> tuple[tuple[str, str], ...]:
    """What sets a run's speed, as (name, value) pairs: its task, seeds per process, minibatch, updates and the
    evaluation's settings where they differ from the defaults (one measurement per kind).
    """
    cfg, default = TrainConfig.from_dict(job.config), TrainConfig().eval
    evaluation = [f"{f.name}={getattr(cfg.eval, f.name)}" for f in fields(cfg.eval)
                  if getattr(cfg.eval, f.name) != getattr(default, f.name)]
    return (("task", cfg.env.task), ("seeds", f"{cfg.run.seeds} seeds"), ("batch", f"batch {cfg.dqn.batch_size}"),
            ("updates", f"{cfg.dqn.updates_per_epoch} updates per epoch"), ("eval", " ".join(evaluation)))


def kind_labels(kinds: list[tuple[tuple[str, str], ...]]) -> list[str]:
    """A name per kind: its task and seeds, and what else tells it from the other kinds of that task."""
    labels = []
    for kind in kinds:
        same_task = [k for k in kinds if k[0] == kind[0]]
        parts = [value for i, (name, value) in enumerate(kind)
                 if name in ("task", "seeds") or (value and len({k[i][1] for k in same_task}) > 1)]
        labels.append(", ".join(parts))
    return labels


def _done_step(job) -> int:
    """The step a job's run stands at (its heartbeat's, where it ran before; 0 for a fresh one)."""
    from train.loop.runlog import PROGRESS_FILE, read_heartbeat

    beat = read_heartbeat(Path(job.run_dir) / PROGRESS_FILE)
    return 0 if beat is None else int(beat["step"])


def _left(job, total_steps: int) -> float:
    """The share of a job's ``total_steps`` still to train (its heartbeat's step, where it ran before)."""
    return max(0.0, 1.0 - _done_step(job) / total_steps)


def estimate(jobs: list, workers: int, say, measure=measure_speed_together) -> float:
    """Measure this machine on one run of each kind among the training ``jobs`` (`run_kind`) and predict the wall
    time of them all, ``workers`` at a time (resumed ones for their steps left); ``say`` prints a line per kind
    and the total. Returns the predicted seconds.
    """
    kinds: dict[tuple[tuple[str, str], ...], list] = {}
    for job in jobs:
        if not job.is_measurement:
            kinds.setdefault(run_kind(job), []).append(job)
    if not kinds:
        say("estimate: nothing to train")
        return 0.0
    say(f"measuring this machine's speed on each kind of run ({len(kinds)}; a few seconds each) ...")
    seconds = []
    for label, group in zip(kind_labels(list(kinds)), kinds.values()):
        configs = [TrainConfig.from_dict(j.config) for j in group]
        speed = measure(group[0].config, min(workers, len(group)))
        each = [speed.run_seconds(c, margin=1.0) * _left(j, c.total_steps) for j, c in zip(group, configs)]
        seconds += each
        say(f"  {label}: {speed.describe(configs[0])}; {len(group)} run(s), {_duration(sum(each))} in all")
    total = makespan(seconds, workers)
    say(f"estimate: {len(seconds)} run(s), {min(workers, len(seconds))} at a time: about {_duration(total)} on this "
        f"machine, more rather than less (checkpoints, late greedy epochs and other work add to it; --jobs N sets "
        f"how many run at a time)")
    return total
