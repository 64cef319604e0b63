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
from train.runlog import Interrupted
from train.safeio import UnsafeFileError, load_json

DONE_FILE = "done.json"
"""Marker of a finished run (atomically written, with its step budget)."""


UNSTARTED_FILES = ("config.json",)
"""What a run stopped before its first checkpoint leaves (besides its lock and interrupted temporaries,
`train.fileio.is_temporary`); cleared before it starts again. Anything else is a result, never deleted
unless the job is restarted."""
RESULT_FILES = ("config.json", "metrics.csv", "visits.npy", "visits", "tensorboard", DONE_FILE)
"""What ``--restart`` clears (with the checkpoint) before a condition starts again."""


class FinishedWithoutCheckpoint(RuntimeError):
    """A condition holds results but no checkpoint to extend them from (the message says what to do)."""


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
    restart: bool = False
    """Clear the condition's results and checkpoint and train it from scratch (``ecorl run --restart``)."""

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
    """'done' (ran to its budget now), 'skipped' (already done), 'interrupted', 'failed' or 'kept' (results
    without a checkpoint, left as they are: `FinishedWithoutCheckpoint`)."""
    seconds: float = 0.0
    error: str = ""


def read_done(run_dir: str | Path) -> dict[str, Any] | None:
    """The done marker of a run directory, or None."""
    path = Path(run_dir) / DONE_FILE
    if not path.exists() and not path.is_symlink():
        return None
    done = load_json(path)
    return done if isinstance(done, dict) else {}


def job_is_done(job: Job) -> bool:
    """True when the job's directory holds a done marker that covers the job's budget and settings."""
    done = None if job.restart else read_done(job.run_dir)
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
        check_same_run(TrainConfig.from_dict(load_json(saved)), cfg, saved)
    run = RunDir(job.run_dir)
    if not run.metrics_path.exists() and run.has_checkpoint():  # deleted by hand: rebuild it from the checkpoint
        run.lock()
        try:
            run.restore_metrics()
        finally:
            run.unlock()
    return True


def _clear_unstarted(job: Job) -> None:
    """Remove what a run stopped before its first checkpoint left (its config.json and temporaries); with
    ``job.restart`` also its results. Results without a checkpoint are otherwise kept and reported
    (`FinishedWithoutCheckpoint`); files ecorl did not write are never touched.
    """
    from train.checkpoint import CHECKPOINT_NAME
    from train.rundir import LOCK_NAME

    run_dir = Path(job.run_dir)
    if not run_dir.exists():
        return
    clear = {*RESULT_FILES, CHECKPOINT_NAME} if job.restart else set(UNSTARTED_FILES)
    names = {p.name for p in run_dir.iterdir()} - {LOCK_NAME}
    unknown = sorted(n for n in names - clear if not is_temporary(n) and n not in RESULT_FILES)
    if unknown:
        raise RuntimeError(f"{run_dir} holds no checkpoint but other files ({', '.join(unknown)}); "
                           f"move them away or choose another --out")
    results = sorted(n for n in names - clear if n in RESULT_FILES)
    if results:
        raise FinishedWithoutCheckpoint(
            f"{job.name} holds results ({', '.join(results)}) but no {CHECKPOINT_NAME} to continue them from; "
            f"they are kept as they are. To train it again from scratch (deleting them), re-run with "
            f"--restart {job.condition}")
    for p in run_dir.iterdir():
        if p.name in clear or is_temporary(p.name):
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()


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
    except Interrupted:  # inside an evaluation, or a second signal: the last checkpoint stands
        return JobResult(job.name, "interrupted", time.perf_counter() - began)
    except FinishedWithoutCheckpoint as err:
        return JobResult(job.name, "kept", time.perf_counter() - began, str(err))
    except Exception as err:  # reported to the caller, which carries on with the other jobs
        from train.rundir import RunDirError

        input_error = isinstance(err, (RunDirError, UnsafeFileError, OSError))  # a file or a full disk, not a bug
        why = " ".join(str(err).split()) if input_error else traceback.format_exc()
        return JobResult(job.name, "failed", time.perf_counter() - began, why)


def _run_training(job: Job) -> bool:
    """Train (or resume) the job's run; write the done marker when it reached its budget."""
    from train.rundir import RunDir
    from train.trainer import Trainer

    run_dir = Path(job.run_dir)
    cfg = TrainConfig.from_dict(job.config)
    run = RunDir(run_dir)
    run.lock()  # one writer per run directory, held until the trainer closes: a concurrent sweep is refused
    try:
        resume = run.has_checkpoint() and not job.restart
        if not resume:
            _clear_unstarted(job)
    except BaseException:
        run.unlock()
        raise
    began = time.perf_counter()
    trainer = Trainer(cfg, run, resume=resume)
    try:
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
