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
from train.loop.runlog import Interrupted
from train.storage.fileio import atomic_text, is_temporary
from train.storage.rundir import FILM_FILES, RUN_POLICIES_DIR
from train.storage.safeio import UnsafeFileError, load_json

DONE_FILE = "done.json"
"""Marker of a finished run (atomically written, with its step budget)."""


UNSTARTED_FILES = ("config.json", "progress.json")
"""What a run stopped before its first checkpoint leaves (besides its lock and interrupted temporaries,
`train.storage.fileio.is_temporary`); cleared before it starts again. Anything else is a result, never deleted
unless the job is restarted."""
RESULT_FILES = ("config.json", "metrics.csv", "visits.npy", "visits", "tensorboard", "progress.json",
                RUN_POLICIES_DIR, DONE_FILE, *FILM_FILES)
"""What ``--restart`` clears (with the checkpoint) before a condition starts again (the report's film of the run
too: it would show the run deleted)."""


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
class Pack:
    """Several training jobs of one task trained by one packed trainer (`train.loop.packing`)."""

    jobs: tuple[Job, ...]

    @property
    def name(self) -> str:
        """experiment/task/[condition, ...]; task/[experiment/condition, ...] for a pack across experiments."""
        first = self.jobs[0]
        if all(j.experiment == first.experiment for j in self.jobs):
            return f"{first.experiment}/{first.task}/[{', '.join(j.condition for j in self.jobs)}]"
        return f"{first.task}/[{', '.join(f'{j.experiment}/{j.condition}' for j in self.jobs)}]"

    @property
    def cost(self) -> float:
        """Relative cost of the whole pack."""
        return sum(j.cost for j in self.jobs)


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


def job_is_done_safely(job: Job) -> bool:
    """`job_is_done`, False where the job's folder holds a run of other settings: the mismatch surfaces when the
    job runs (as a failure with its message) or in a dry run's plan (a clash line), not while planning.
    """
    try:
        return job_is_done(job)
    except Exception:
        return False


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
    from train.storage.rundir import RunDir, check_same_run

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


def foreign_files(run_dir: Path) -> list[str]:
    """The files in a run directory that ecorl did not write (it never deletes them, so a run cannot start
    there afresh), sorted; empty where there is no directory.
    """
    from train.storage.checkpoint import CHECKPOINT_NAME
    from train.storage.rundir import LOCK_NAME

    if not run_dir.is_dir():
        return []
    known = {*RESULT_FILES, *UNSTARTED_FILES, CHECKPOINT_NAME, LOCK_NAME}
    return sorted(p.name for p in run_dir.iterdir() if p.name not in known and not is_temporary(p.name))


def foreign_files_message(run_dir: Path, names: list[str]) -> str:
    """Why a run cannot start afresh in ``run_dir``, which holds ``names`` (`foreign_files`), and what to do."""
    return (f"{run_dir} holds files ecorl did not write ({', '.join(names)}), which it never deletes; move them "
            f"away or choose another --out")


def _clear_unstarted(job: Job) -> None:
    """Remove what a run stopped before its first checkpoint left (its config.json and temporaries); with
    ``job.restart`` also its results. Results without a checkpoint are otherwise kept and reported
    (`FinishedWithoutCheckpoint`); files ecorl did not write are never touched.
    """
    from train.storage.checkpoint import CHECKPOINT_NAME
    from train.storage.rundir import LOCK_NAME, RunDirError

    run_dir = Path(job.run_dir)
    if not run_dir.exists():
        return
    clear = {*RESULT_FILES, CHECKPOINT_NAME} if job.restart else set(UNSTARTED_FILES)
    names = {p.name for p in run_dir.iterdir()} - {LOCK_NAME}
    if unknown := foreign_files(run_dir):
        raise RunDirError(foreign_files_message(run_dir, unknown))
    results = sorted(n for n in names - clear if n in RESULT_FILES)
    if results:
        raise FinishedWithoutCheckpoint(
            f"{job.name} holds results ({', '.join(results)}) but no {CHECKPOINT_NAME} to continue them from; "
            f"they are kept as they are. To train it again from scratch (deleting them), re-run with "
            f"--restart {job.condition}")
    clear_run_files(run_dir, clear)


def clear_run_files(run_dir: Path, names: set[str] | tuple[str, ...]) -> None:
    """Delete the entries of ``run_dir`` named in ``names`` and ecorl's temporaries there (a link itself, never
    what it points to); nothing else.
    """
    for p in run_dir.iterdir():
        if p.name in names or is_temporary(p.name):
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
    except (Exception, Interrupted) as err:  # reported to the caller, which carries on with the other jobs
        return _error_result(job, err, began)


def _error_result(job: Job, err: BaseException, began: float) -> JobResult:
    """What an exception means for a job: interrupted (the last checkpoint stands), kept (results without a
    checkpoint), or failed (one line for bad input or a full disk, the traceback for a bug).
    """
    from train.storage.rundir import RunDirError

    seconds = time.perf_counter() - began
    if isinstance(err, Interrupted):  # inside an evaluation, or a second signal
        return JobResult(job.name, "interrupted", seconds)
    if isinstance(err, FinishedWithoutCheckpoint):
        return JobResult(job.name, "kept", seconds, str(err))
    input_error = isinstance(err, (RunDirError, UnsafeFileError, OSError))  # a file or a full disk, not a bug
    why = " ".join(str(err).split()) if input_error else traceback.format_exc()
    return JobResult(job.name, "failed", seconds, why)


def _open_run(job: Job):
    """Lock the job's run directory (one writer per run: a concurrent sweep is refused) and say whether it
    resumes; a run killed before its first checkpoint is cleared. Returns (RunDir, resume).
    """
    from train.storage.rundir import RunDir

    run = RunDir(job.run_dir)
    run.lock()
    try:
        resume = run.has_checkpoint() and not job.restart
        if not resume:
            _clear_unstarted(job)
    except BaseException:
        run.unlock()
        raise
    return run, resume


def _train(jobs: list[Job], opened: list) -> bool:
    """Train ``jobs`` (one trainer; packed when several) from their opened run directories; write each done
    marker when the runs reach their budget. Returns False when a signal stopped them (with checkpoints).
    """
    from train.loop.runlog import PROGRESS_FILE, heartbeat_to
    from train.loop.trainer import Trainer
    from train.storage.policy import export_run_policies

    began = time.perf_counter()
    cfgs = [TrainConfig.from_dict(j.config) for j in jobs]
    runs, resume = [o[0] for o in opened], [o[1] for o in opened]
    trainer = Trainer(cfgs[0], runs[0], resume[0]) if len(jobs) == 1 else Trainer.packed(cfgs, runs, resume)
    try:
        with heartbeat_to(*(Path(j.run_dir) / PROGRESS_FILE for j in jobs)):  # the sweep shows progress from it
            trainer.run()
        finished = trainer.epoch >= trainer.cfg.num_epochs
        for index, job in enumerate(jobs if finished else []):  # while the worlds are still open
            export_run_policies(job.run_dir, trainer.state_dict(index))
    finally:
        trainer.close()
    if not finished:
        return False  # stopped by a signal, with a checkpoint
    for job, part in zip(jobs, trainer.parts):
        marker = {"total_steps": part.cfg.total_steps, "seeds": part.cfg.run.seeds,
                  "seconds": round(time.perf_counter() - began, 1), "finished": time.strftime("%Y-%m-%dT%H:%M:%S")}
        if len(jobs) > 1:
            marker["packed_with"] = [j.condition for j in jobs if j is not job]
        atomic_text(Path(job.run_dir) / DONE_FILE, json.dumps(marker, indent=2) + "\n")
    return True


def _run_training(job: Job) -> bool:
    """Train (or resume) the job's run; write the done marker when it reached its budget."""
    return _train([job], [_open_run(job)])


def execute_pack(pack: Pack) -> list[JobResult]:
    """Run a pack's jobs not yet done in packed trainers, one per step at which they stand (usually one).

    Each condition gets its own result, as from `execute`: one that cannot open (kept results, a bad
    checkpoint) does not stop the others; an error while training is every trained condition's. Exceptions
    are returned, not raised.
    """
    began = time.perf_counter()
    results, todo = [], []
    for job in pack.jobs:
        try:
            done = job_is_done(job)
        except Exception as err:  # e.g. a settings mismatch: this condition fails, the others run
            results.append(_error_result(job, err, began))
            continue
        if done:
            results.append(JobResult(job.name, "skipped"))
        else:
            todo.append(job)
    for group in _by_step(todo):
        members, opened = [], []
        try:
            for job in group:
                try:
                    opened.append(_open_run(job))
                    members.append(job)
                except Exception as err:
                    results.append(_error_result(job, err, began))
            if members:
                finished = _train(members, opened)
                results += [JobResult(j.name, "done" if finished else "interrupted", time.perf_counter() - began)
                            for j in members]
        except (Exception, Interrupted) as err:
            for run, _ in opened:
                run.unlock()
            results += [_error_result(j, err, began) for j in members]
    return results


def _by_step(jobs: list[Job]) -> list[list[Job]]:
    """Jobs grouped by the step their checkpoint stands at (0 for a fresh run): one packed trainer each."""
    from train.storage.rundir import RunDir

    groups: dict[int, list[Job]] = {}
    for job in jobs:
        try:
            run = RunDir(job.run_dir)
            step = run.saved_config()[1] if run.has_checkpoint() else 0
        except Exception:  # an unreadable checkpoint: the job alone meets the error when it opens
            step = -1 - len(groups)
        groups.setdefault(step, []).append(job)
    return list(groups.values())


def execute_unit(unit: Job | Pack) -> list[JobResult]:
    """`execute` of a job, or `execute_pack` of a pack: the results of every condition it holds."""
    return execute_pack(unit) if isinstance(unit, Pack) else [execute(unit)]


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
