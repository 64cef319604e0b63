"""One job of a sweep: a trainer run (or a Table 1 measurement) in its own directory, run to its budget.

`execute` skips a job whose ``done.json`` covers its budget, resumes one that left a checkpoint, and starts the
others afresh (clearing what a run killed before its first checkpoint left behind). It runs in any process
(a local worker or a Ray task) and returns what happened instead of raising.
"""

from __future__ import annotations

import json
import shutil
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from train.config import TrainConfig
from train.experiments import table1
from train.fileio import atomic_text, is_temporary

DONE_FILE = "done.json"
"""Marker of a finished run (atomically written, with its step budget)."""


TRAINER_FILES = ("config.json", "metrics.csv", "visits.npy", "visits", "progress.json")
"""What a run that never reached its first checkpoint may have left (besides its lock and interrupted
temporaries, `train.fileio.is_temporary`); cleared before it starts again."""


@dataclass(frozen=True)
class Job:
    """One condition of one task: a trainer run (or a Table 1 measurement) in its own directory."""

    experiment: str
    task: str
    condition: str
    run_dir: str
    config: dict[str, Any]
    """`TrainConfig.to_dict()`, or for a measurement {'measure', 'task', 'seeds', 'steps'}."""
    cost: float
    """Relative cost (seed-steps), to start the longest jobs first."""

    @property
    def name(self) -> str:
        """experiment/task/condition."""
        return f"{self.experiment}/{self.task}/{self.condition}"

    @property
    def is_measurement(self) -> bool:
        """True for a Table 1 measurement job."""
        return "measure" in self.config


@dataclass(frozen=True)
class JobResult:
    """What happened to a job."""

    job: str
    status: str
    """'done' (ran to its budget now), 'skipped' (already done), 'interrupted' or 'failed'."""
    seconds: float = 0.0
    error: str = ""


def read_done(run_dir: str | Path) -> dict[str, Any] | None:
    """The done marker of a run directory, or None."""
    path = Path(run_dir) / DONE_FILE
    return json.loads(path.read_text()) if path.exists() else None


def job_is_done(job: Job) -> bool:
    """True when the job's directory holds a done marker that covers the job's budget and settings."""
    done = read_done(job.run_dir)
    if done is None:
        return False
    if job.is_measurement:
        return done.get("config") == job.config
    cfg = TrainConfig.from_dict(job.config)
    if done.get("total_steps", -1) < cfg.total_steps:
        return False  # a longer budget was asked for: the run is resumed from its checkpoint
    from train.rundir import RunDir, check_same_run

    saved = Path(job.run_dir) / "config.json"
    if saved.exists():
        check_same_run(TrainConfig.from_dict(json.loads(saved.read_text())), cfg, saved)
    run = RunDir(job.run_dir)
    if not run.metrics_path.exists() and run.has_checkpoint():  # deleted by hand: rebuild it from the checkpoint
        run.lock()
        try:
            run.restore_metrics()
        finally:
            run.unlock()
    return True


def _clear_unstarted(run_dir: Path) -> None:
    """Remove what a run killed before its first checkpoint left behind (refuse to touch anything else)."""
    from train.rundir import LOCK_NAME

    if not run_dir.exists():
        return
    keep = {*TRAINER_FILES, DONE_FILE}
    unknown = [p.name for p in run_dir.iterdir()
               if p.name not in keep and p.name != LOCK_NAME and not is_temporary(p.name)]
    if unknown:
        raise RuntimeError(f"{run_dir} holds no checkpoint but other files ({', '.join(sorted(unknown))}); "
                           f"move them away or choose another --out")
    for p in run_dir.iterdir():
        if p.name != LOCK_NAME:
            shutil.rmtree(p) if p.is_dir() else p.unlink()


def execute(job: Job) -> JobResult:
    """Run one job to its budget: skip it if done, resume it from its checkpoint, or start it afresh.

    Safe to call in any process (local worker or Ray task). Exceptions are returned, not raised.
    """
    began = time.perf_counter()
    try:
        if job_is_done(job):
            return JobResult(job.name, "skipped")
        finished = _run_measurement(job) if job.is_measurement else _run_training(job)
        return JobResult(job.name, "done" if finished else "interrupted", time.perf_counter() - began)
    except Exception as err:  # reported to the caller, which carries on with the other jobs
        from train.rundir import RunDirError

        why = " ".join(str(err).split()) if isinstance(err, RunDirError) else traceback.format_exc()
        return JobResult(job.name, "failed", time.perf_counter() - began, why)


def _run_training(job: Job) -> bool:
    """Train (or resume) the job's run; write the done marker when it reached its budget."""
    from train.rundir import RunDir
    from train.runlog import PROGRESS_FILE, heartbeat_to
    from train.trainer import Trainer

    run_dir = Path(job.run_dir)
    cfg = TrainConfig.from_dict(job.config)
    run = RunDir(run_dir)
    run.lock()  # one writer per run directory, held until the trainer closes: a concurrent sweep is refused
    try:
        resume = run.has_checkpoint()
        if not resume:
            _clear_unstarted(run_dir)
    except BaseException:
        run.unlock()
        raise
    began = time.perf_counter()
    trainer = Trainer(cfg, run, resume=resume)
    try:
        with heartbeat_to(run_dir / PROGRESS_FILE):  # the sweep shows each run's progress from it
            trainer.run()
    finally:
        trainer.close()
    if trainer.epoch < trainer.cfg.num_epochs:
        return False  # stopped by a signal, with a checkpoint
    marker = {"total_steps": trainer.cfg.total_steps, "seeds": trainer.cfg.run.seeds,
              "seconds": round(time.perf_counter() - began, 1), "finished": time.strftime("%Y-%m-%dT%H:%M:%S")}
    atomic_text(run_dir / DONE_FILE, json.dumps(marker, indent=2) + "\n")
    return True


def _run_measurement(job: Job) -> bool:
    """Run a Table 1 measurement and write table.csv, table.md and the done marker."""
    cfg = job.config
    run_dir = Path(job.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    began = time.perf_counter()
    rows = table1.measure_rows(cfg["measure"], cfg["task"], cfg["seeds"], cfg["steps"])
    title = f"{cfg['measure']} ({cfg['task']}, {cfg['seeds']} seeds, {cfg['steps']} steps)"
    table1.write_table(cfg["measure"], rows, run_dir / "table", title)
    marker = {"config": cfg, "seconds": round(time.perf_counter() - began, 1),
              "finished": time.strftime("%Y-%m-%dT%H:%M:%S")}
    atomic_text(run_dir / DONE_FILE, json.dumps(marker, indent=2) + "\n")
    return True
