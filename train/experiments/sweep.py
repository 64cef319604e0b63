"""Running an experiment: plan its jobs, run them in local processes or on Ray, resume, skip what is done.

Layout of a results directory::

    OUT/<experiment>/experiment.json          what was run (conditions, budget), read by the report
    OUT/<experiment>/<task>/<condition>/      one trainer run directory (train.rundir), all seeds
        done.json                             written atomically when the run has reached its budget
    OUT/measure/<task>/<measurement>/         table.csv, table.md, done.json (Table 1, no training)

A job is one condition of one task with all its seeds, trained in one process (`execute`). Re-running the
same command skips jobs whose ``done.json`` covers the requested steps, resumes jobs that left a checkpoint,
and starts the others afresh, so an interrupted sweep (even by SIGKILL) finishes with no run lost or
repeated: the trainer's checkpoints are atomic and a resumed run continues exactly where the checkpoint
stood.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from train.checkpoint import CHECKPOINT_NAME
from train.config import TrainConfig
from train.experiments import table1
from train.experiments.catalog import Experiment, job_config
from train.fileio import atomic_text, die_with_parent, is_temporary

DONE_FILE = "done.json"
"""Marker of a finished run (atomically written, with its step budget)."""
EXPERIMENT_FILE = "experiment.json"
"""Description of an experiment directory, written by `run_experiment`."""
TRAINER_FILES = ("config.json", "metrics.csv", "visits.npy", "visits")
"""What a run that never reached its first checkpoint may have left (besides its lock and interrupted
temporaries, `train.fileio.is_temporary`); cleared before it starts again."""
EXPERIMENT_LOCK = ".experiment.lock"
"""Lock file serialising updates of experiment.json by concurrent ``ecorl run`` processes."""


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


# ---- planning ------------------------------------------------------------------------------------------


def plan(experiment: Experiment, budget_name: str, out: str | Path, tasks: Sequence[str] | None = None,
         seeds: int | None = None, steps: int | None = None) -> list[Job]:
    """The jobs of ``experiment`` at a budget (optionally a task subset, or other seeds/steps)."""
    budget = experiment.budget(budget_name)
    if seeds is not None or steps is not None:
        budget = replace(budget, seeds=seeds or budget.seeds, steps=steps or budget.steps)
    root = Path(out).resolve() / experiment.name
    jobs = []
    for task in experiment.select_tasks(tasks):
        for cond in experiment.conditions[task]:
            run_dir = str(root / task / cond.name)
            n_steps = budget.steps_for(task)
            if cond.measure:
                config = {"measure": cond.measure, "task": task, "seeds": budget.seeds, "steps": n_steps}
                jobs.append(Job(experiment.name, task, cond.name, run_dir, config, budget.seeds * n_steps / 20))
            else:
                cfg = job_config(experiment, task, cond, budget)
                jobs.append(Job(experiment.name, task, cond.name, run_dir, cfg.to_dict(),
                                cfg.run.seeds * cfg.total_steps * (10 if task == "foodcollector" else 1)))
    return jobs


def write_experiment_file(experiment: Experiment, budget_name: str, jobs: Sequence[Job], out: str | Path) -> Path:
    """Record what this experiment directory holds, merged (under a lock) with earlier or concurrent runs of
    other task subsets."""
    from train.fileio import FileLock, LockedError

    path = Path(out).resolve() / experiment.name / EXPERIMENT_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = FileLock(path.parent / EXPERIMENT_LOCK, f"{path}", "try again in a moment")
    deadline = time.monotonic() + 30.0
    while True:  # writers hold this lock for milliseconds: wait for it
        try:
            lock.acquire()
            break
        except LockedError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)
    try:
        old = _read_json(path)
        info = experiment.describe()
        info["budget"] = budget_name
        info["tasks_run"] = sorted((set(old.get("tasks_run", [])) & set(experiment.tasks)) | {j.task for j in jobs},
                                   key=lambda t: list(experiment.tasks).index(t))
        atomic_text(path, json.dumps(info, indent=2) + "\n")
    finally:
        lock.release()
    return path


def _read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path`` ({} if missing or unreadable)."""
    try:
        data = json.loads(path.read_text())
    except (FileNotFoundError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


# ---- one job -------------------------------------------------------------------------------------------


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


# ---- executors -----------------------------------------------------------------------------------------


_STOP = None
"""In a local worker process: the sweep's stop event (set when the user interrupts the sweep)."""
_PARENT: int | None = None
"""In a local worker process: the pid of the sweep that started it."""


def _init_worker(stop, parent: int) -> None:
    """Worker initializer: Ctrl-C reaches the trainer's own handler (a clean stop), not the pool loop; the
    worker gets SIGTERM (a clean stop too) when the sweep's process dies, and then takes no further job."""
    global _STOP, _PARENT
    _STOP, _PARENT = stop, parent
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(signal.SIGTERM)
    if _parent_gone():  # it died before the request took effect
        os._exit(1)


def _parent_gone() -> bool:
    """True in a worker whose sweep process has died (the worker was re-parented)."""
    return _PARENT is not None and os.getppid() != _PARENT


_INTERRUPTED = False
"""In a local worker process: a job of this worker was stopped by a signal, so it takes no further job."""


def _execute_unless_stopped(job: Job) -> JobResult:
    """`execute`, unless the sweep was interrupted before this job started; a worker whose sweep died
    exits instead of taking (or reporting) a job.

    A worker whose job a signal stopped takes no further job either: the kernel's parent-death signal can
    arrive when the sweep's first thread dies, while its other threads (same pid) still live.
    """
    global _INTERRUPTED
    if _parent_gone():
        os._exit(0)
    if _INTERRUPTED or (_STOP is not None and _STOP.is_set()):
        return JobResult(job.name, "interrupted")
    result = execute(job)
    _INTERRUPTED = _INTERRUPTED or result.status == "interrupted"
    if _parent_gone():
        os._exit(0)
    return result


class _Terminated(KeyboardInterrupt):
    """SIGTERM to the sweep, handled like Ctrl-C."""


@contextmanager
def _sigterm_interrupts():
    """Inside the block (main thread only), SIGTERM raises `_Terminated`."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise _Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run_local(jobs: Sequence[Job], workers: int, on_result: Callable[[JobResult], None]) -> list[JobResult]:
    """Run ``jobs`` in up to ``workers`` local processes (one job per process at a time)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    results: list[JobResult] = []
    if not jobs:
        return results
    ctx = multiprocessing.get_context("spawn")  # no forked torch/OpenMP state in the workers
    stop = ctx.Event()
    pool = ProcessPoolExecutor(max_workers=max(1, min(workers, len(jobs))), mp_context=ctx,
                               initializer=_init_worker, initargs=(stop, os.getpid()))
    try:
        with _sigterm_interrupts():
            _collect(pool, jobs, results, on_result)
    except KeyboardInterrupt as err:
        stop.set()  # queued jobs do not start; running trainers stop at their epoch end
        if isinstance(err, _Terminated):  # Ctrl-C reached the workers too; SIGTERM only this process
            for proc in list((pool._processes or {}).values()):
                proc.terminate()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return results


def _collect(pool, jobs: Sequence[Job], results: list[JobResult], on_result: Callable[[JobResult], None]) -> None:
    """Submit ``jobs`` to ``pool`` and gather their results as they finish."""
    from concurrent.futures import FIRST_COMPLETED, wait

    pending = {pool.submit(_execute_unless_stopped, job): job for job in jobs}
    while pending:
        finished, _ = wait(pending, return_when=FIRST_COMPLETED)
        for fut in finished:
            job = pending.pop(fut)
            try:
                result = fut.result()
            except Exception as err:  # a worker died (e.g. killed): report it, keep going
                result = JobResult(job.name, "failed", error=f"worker process failed: {err!r}")
            results.append(result)
            on_result(result)


def _import_ray():
    """Import Ray, or explain how to get it."""
    try:
        import ray
    except ImportError:
        raise RuntimeError("the Ray executor needs Ray: pip install 'ecorl[ray]' (or pip install 'ray>=2.9'), "
                           "or use --executor local") from None
    return ray


def run_ray(jobs: Sequence[Job], address: str | None, on_result: Callable[[JobResult], None]) -> list[JobResult]:
    """Run ``jobs`` as Ray tasks (one CPU each) on the cluster at ``address`` (None: start a local one).

    Every node must see the results directory at the same path (a shared file system), since each task
    writes its run directory itself.
    """
    ray = _import_ray()
    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False, include_dashboard=False)
    remote = ray.remote(num_cpus=1, max_retries=0)(execute)
    pending = {remote.remote(job): job for job in jobs}
    results: list[JobResult] = []
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            job = pending.pop(ready[0])
            try:
                result = ray.get(ready[0])
            except Exception as err:  # the task's worker died
                result = JobResult(job.name, "failed", error=f"Ray task failed: {err!r}")
            results.append(result)
            on_result(result)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref)
        raise
    return results


# ---- the whole sweep -----------------------------------------------------------------------------------


def run_jobs(jobs: Sequence[Job], executor: str = "local", workers: int | None = None,
             address: str | None = None, progress: bool = True) -> list[JobResult]:
    """Run every job not yet done (longest first), with a progress bar over conditions."""
    from tqdm import tqdm

    done_before = [j for j in jobs if _safe_is_done(j)]
    todo = sorted((j for j in jobs if j not in done_before), key=lambda j: -j.cost)
    bar = tqdm(total=len(jobs), initial=len(done_before), unit="run", desc="conditions", disable=not progress,
               dynamic_ncols=True)
    results = [JobResult(j.name, "skipped") for j in done_before]

    def on_result(result: JobResult) -> None:
        bar.update(1)
        if result.status == "failed":
            bar.write(f"FAILED {result.job}: {result.error}", file=sys.stderr)
        elif result.status == "done":
            bar.write(f"finished {result.job} in {result.seconds:.0f} s", file=sys.stderr)

    if executor not in ("local", "ray"):
        bar.close()
        raise ValueError(f"unknown executor {executor!r}; choose local or ray")
    try:
        if not todo:
            pass
        elif executor == "local":
            results += run_local(todo, workers or os.cpu_count() or 1, on_result)
        else:
            results += run_ray(todo, address, on_result)
    finally:
        bar.close()
    return results


def _safe_is_done(job: Job) -> bool:
    """`job_is_done`, letting a settings mismatch surface when the job runs (as a failure with its message)."""
    try:
        return job_is_done(job)
    except Exception:
        return False


def summarize(results: Iterable[JobResult]) -> dict[str, int]:
    """Count results by status."""
    counts: dict[str, int] = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    return counts


def print_plan(jobs: Sequence[Job], file=None) -> None:
    """One line per job: its directory, seeds, steps and whether it is done."""
    file = file or sys.stdout
    for job in jobs:
        cfg = job.config
        if job.is_measurement:
            what = f"{cfg['measure']}: {cfg['seeds']} seeds x {cfg['steps']} steps"
        else:
            c = TrainConfig.from_dict(cfg)
            what = (f"{c.run.seeds} seeds x {c.total_steps} steps, eval every {c.eval.eval_every}, "
                    f"p={c.env.dynamism:g}, shaping={c.env.shaping}, "
                    f"{'reset-free' if c.env.reset_free else 'episodic'}, "
                    f"reward={c.env.reward}{', rnd' if c.rnd.rnd else ''}")
        state = "done" if _safe_is_done(job) else ("resume" if (Path(job.run_dir) / CHECKPOINT_NAME).exists()
                                                    else "new")
        print(f"[{state:>6s}] {job.name}: {what}", file=file)


def job_to_dict(job: Job) -> dict[str, Any]:
    """A JSON-friendly job."""
    return asdict(job)
