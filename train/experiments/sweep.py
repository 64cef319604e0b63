"""Running an experiment: plan its jobs, run them in local processes or on Ray, resume, skip what is done.

Layout of a results directory::

    OUT/<experiment>/experiment.json          what was run (conditions, budget), read by the report
    OUT/<experiment>/<task>/<condition>/      one trainer run directory (train.storage.rundir), all seeds
        policies/best.npz, median.npz         its best and median seed by the last validation score
        done.json                             written atomically when the run has reached its budget
    OUT/measure/<task>/<measurement>/         table.csv, table.md, done.json (Table 1, no training)

A job is one condition of one task with all its seeds, trained in one process (`train.experiments.jobs`;
the processes are `train.experiments.executors`). Re-running the
same command skips jobs whose ``done.json`` covers the requested steps, resumes jobs that left a checkpoint,
and starts the others afresh, so an interrupted sweep (even by SIGKILL) finishes with no run lost or
repeated: the trainer's checkpoints are atomic and a resumed run continues exactly where the checkpoint
stood.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Iterable, Sequence
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from train.config import TrainConfig
from train.experiments.catalog import Experiment, job_config
from train.experiments.executors import run_local, run_ray, usable_cpus
from train.experiments.jobs import Job, JobResult, Pack, job_is_done_safely
from train.storage.checkpoint import CHECKPOINT_NAME
from train.storage.fileio import atomic_text
from train.storage.rundir import EXPERIMENT_FILE
from train.storage.safeio import load_json, no_link_below, real_dir

EXPERIMENT_LOCK = ".experiment.lock"
"""Lock file serialising updates of experiment.json by concurrent ``ecorl run`` processes."""


def plan(experiment: Experiment, budget_name: str, out: str | Path, tasks: Sequence[str] | None = None,
         seeds: int | None = None, steps: int | None = None, conditions: Sequence[str] | None = None,
         restart: Sequence[str] = (), device: str | None = None, first_seed: int = 0) -> list[Job]:
    """The jobs of ``experiment`` at a budget (optionally a task or condition subset, other seeds/steps, seeds
    from ``first_seed`` on (a part of each condition's seeds, `train.experiments.merge`), or another device: a runtime
    setting, so runs move between devices freely); conditions named in ``restart`` are cleared and trained
    from scratch.
    """
    budget = experiment.budget(budget_name)
    if first_seed and experiment.is_measurement:
        raise ValueError(f"--first-seed picks the seeds of training runs; {experiment.name!r} measures a random "
                         f"policy over its own seeds (drop --first-seed)")
    if seeds is not None or steps is not None:
        budget = replace(budget, seeds=seeds or budget.seeds, steps=steps or budget.steps)
    root = Path(out).resolve() / experiment.name
    jobs = []
    for task in experiment.select_tasks(tasks):
        for cond in experiment.select_conditions(task, conditions):
            run_dir = root / task / cond.name
            for inside in (run_dir, run_dir / "policies", run_dir / "visits"):  # refused now, not after training
                no_link_below(root.parent, inside)  # a linked folder would send the run's files elsewhere
            run_dir = str(run_dir)
            n_steps = budget.steps_for(task)
            if cond.measure:
                config = {"measure": cond.measure, "task": task, "seeds": budget.seeds, "steps": n_steps}
                jobs.append(Job(experiment.name, task, cond.name, run_dir, config, budget.seeds * n_steps / 20))
            else:
                cfg = job_config(task, cond, budget)
                cfg = cfg.replace(device=device) if device else cfg
                cfg = cfg.replace(first_seed=first_seed) if first_seed else cfg
                try:
                    cfg.check_trains()
                except ValueError:  # its message names ecorl train's --warmup-steps, which ecorl run has not
                    raise ValueError(f"{task}/{cond.name} would train nothing: its {cfg.dqn.warmup_steps}-step "
                                     f"warm-up takes all {cfg.run.steps} steps; give --steps above "
                                     f"{cfg.dqn.warmup_steps}") from None
                jobs.append(Job(experiment.name, task, cond.name, run_dir, cfg.to_dict(),
                                cfg.run.seeds * cfg.total_steps * (10 if task == "foodcollector" else 1)))
    unknown = sorted(set(restart) - {job.condition for job in jobs})
    if unknown:
        raise ValueError(f"--restart names {unknown[0]!r}, which is not a condition of this run; choose among "
                         f"{', '.join(sorted({job.condition for job in jobs}))}")
    return [replace(job, restart=True) if job.condition in restart else job for job in jobs]


def write_experiment_file(experiment: Experiment, budget_name: str, jobs: Sequence[Job], out: str | Path) -> Path:
    """Record what this experiment directory holds, merged (under a lock) with earlier or concurrent runs of
    other task subsets.
    """
    from train.storage.fileio import FileLock, LockedError

    path = Path(out).resolve() / experiment.name / EXPERIMENT_FILE
    real_dir(path.parent)
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
        data = load_json(path)
    except (FileNotFoundError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def pack_jobs(jobs: Sequence[Job], workers: int = 1) -> list[Job | Pack]:
    """The training jobs grouped into packs of conditions that one trainer can train together
    (`train.loop.packing`), each group split into up to ``workers`` packs of about equal size so that every
    worker process gets one (a pack of one stays a job); measurements stay single.
    """
    from train.loop.packing import group_packable

    training = [j for j in jobs if not j.is_measurement]
    units: list[Job | Pack] = [j for j in jobs if j.is_measurement]
    for group in group_packable([TrainConfig.from_dict(j.config) for j in training]):
        parts = min(max(workers, 1), len(group))
        for chunk in (group[i::parts] for i in range(parts)):
            members = tuple(training[i] for i in chunk)
            units.append(members[0] if len(members) == 1 else Pack(members))
    return units


PROGRESS_EVERY_S = 20.0
"""Seconds between two progress reports of the running jobs."""


def _duration(seconds: float | None) -> str:
    """'4 min 05 s' (or '?')."""
    if seconds is None:
        return "?"
    minutes, secs = divmod(int(round(seconds)), 60)
    return f"{minutes} min {secs:02d} s" if minutes else f"{secs} s"


def heartbeat(job: Job, began: float) -> dict | None:
    """The job's last heartbeat, if it wrote one since ``began`` (wall-clock seconds)."""
    from train.loop.runlog import PROGRESS_FILE, read_heartbeat

    beat = read_heartbeat(Path(job.run_dir) / PROGRESS_FILE)
    return None if beat is None or beat.get("time", 0) < began - 1 else beat


def progress_line(job: Job, began: float) -> str:
    """One line on a job: steps done of its total, steps/s, ETA and the last evaluation (from its heartbeat)."""
    beat = heartbeat(job, began)
    name = f"{job.task}/{job.condition}"
    if beat is None:
        return f"  {name}: starting (imports, environment, first epoch)"
    step, total = int(beat["step"]), int(beat.get("total") or 1)
    bar = "#" * round(20 * step / total) + "." * (20 - round(20 * step / total))
    latest = ", ".join(f"last {k} {v}" for k, v in beat.get("latest", {}).items() if k != "sps")
    return (f"  {name}: [{bar}] {step:,}/{total:,} steps ({step / total:.0%}), {beat.get('steps_per_s', 0):.0f} "
            f"steps/s per seed, ETA {_duration(beat.get('eta_s'))}" + (f", {latest}" if latest else ""))


class ProgressMonitor:
    """A thread that prints, every `PROGRESS_EVERY_S`, one line per running job (from their heartbeats,
    which the worker processes write). With ``workers`` (a job per process), jobs that have not begun while
    that many others beat are waiting for a process, and share one line.
    """

    def __init__(self, jobs: Sequence[Job], write, every: float = PROGRESS_EVERY_S,
                 workers: int | None = None) -> None:
        import threading

        self.jobs, self.write, self.every, self.workers = list(jobs), write, every, workers
        self.finished: set[str] = set()
        self.began, self.wall = time.monotonic(), time.time()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        while not self.stop.wait(self.every):
            report = self.report()
            if report:
                self.write(report)

    def report(self) -> str:
        """The lines on the unfinished jobs ('' when none is left)."""
        left = [j for j in self.jobs if j.name not in self.finished]
        if not left:
            return ""
        beating = [j for j in left if heartbeat(j, self.wall) is not None]
        waiting = [j for j in left if j not in beating] if self.workers and len(beating) >= self.workers else []
        running = [j for j in left if j not in waiting]
        lines = [progress_line(j, self.wall) for j in running]
        if waiting:
            lines.append(f"  {len(waiting)} waiting for a free process: "
                         + ", ".join(f"{j.task}/{j.condition}" for j in waiting))
        return (f"[{_duration(time.monotonic() - self.began)}] {len(running)} run(s) in progress"
                + (f", {len(waiting)} waiting" if waiting else "") + ":\n" + "\n".join(lines))

    def __enter__(self) -> ProgressMonitor:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join()


def run_jobs(jobs: Sequence[Job], executor: str = "local", workers: int | None = None,
             address: str | None = None, progress: bool = True, pack: int = 0) -> list[JobResult]:
    """Run every job not yet done (longest first), with a progress bar over conditions and, every
    `PROGRESS_EVERY_S`, a line per running job; ``pack`` > 0: the conditions of a task that can share a
    trainer train packed, in up to ``pack`` processes (`pack_jobs`).
    """
    from tqdm import tqdm

    done_before = [j for j in jobs if job_is_done_safely(j)]
    todo = [j for j in jobs if j not in done_before]
    monitored = todo
    todo = sorted(pack_jobs(todo, pack) if pack else todo, key=lambda j: -j.cost)
    bar = tqdm(total=len(jobs), initial=len(done_before), unit="run", desc="conditions", disable=not progress,
               dynamic_ncols=True)
    results = [JobResult(j.name, "skipped") for j in done_before]

    workers = workers or usable_cpus()
    monitor = ProgressMonitor(monitored, lambda text: bar.write(text, file=sys.stderr),
                              workers=workers if executor == "local" and not pack else None)

    def on_result(result: JobResult) -> None:
        monitor.finished.add(result.job)
        bar.update(1)
        if result.status == "failed":
            bar.write(f"FAILED {result.job}: {result.error}", file=sys.stderr)
        elif result.status == "kept":
            bar.write(f"KEPT {result.job}: {result.error}", file=sys.stderr)
        elif result.status == "done":
            bar.write(f"finished {result.job} in {result.seconds:.0f} s", file=sys.stderr)

    if executor not in ("local", "ray"):
        bar.close()
        raise ValueError(f"unknown executor {executor!r}; choose local or ray")
    try:
        if not todo:
            pass
        elif executor == "local":
            with monitor if progress else _nothing():
                results += run_local(todo, workers, on_result)
        else:
            with monitor if progress else _nothing():
                results += run_ray(todo, address, on_result)
    finally:
        bar.close()
    return results


@contextmanager
def _nothing():
    """A context that does nothing."""
    yield


def summarize(results: Iterable[JobResult]) -> dict[str, int]:
    """Count results by status."""
    counts: dict[str, int] = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    return counts


PLAN_EXTRAS = (("env", "horizon"), ("env", "env_kwargs"), ("dqn", "lr"), ("dqn", "eps_end"),
               ("dqn", "inventory_repeat"), ("dqn", "completion_terminal"), ("dqn", "timeouts_terminal"),
               ("eval", "eval_dynamism"), ("eval", "eval_horizon"), ("eval", "eval_env_kwargs"))
"""Settings a plan line names where a job changes them from `TrainConfig`'s defaults (the knobs it always shows
aside), so that two conditions that differ only there read differently."""


def plan_extras(cfg: TrainConfig) -> list[str]:
    """``name=value`` for each of `PLAN_EXTRAS` that ``cfg`` changes (a dict of task parameters item by item)."""
    default, parts = TrainConfig(), []
    for section, name in PLAN_EXTRAS:
        value = getattr(getattr(cfg, section), name)
        if value == getattr(getattr(default, section), name) or (name == "horizon" and cfg.env.reset_free):
            continue  # a non-episodic run's horizon ends no episode
        items = value.items() if isinstance(value, dict) else [(name, value)]
        parts += [f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in items]
    return parts


def print_plan(jobs: Sequence[Job], file=None) -> int:
    """One line per job: its directory, seeds, steps and whether it is done, or why it will fail; returns how
    many will fail.
    """
    file = file or sys.stdout
    failing = 0
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
            what += "".join(f", {extra}" for extra in plan_extras(c))
            if c.run.first_seed:
                what += f", seeds {c.run.first_seed}-{c.run.first_seed + c.run.seeds - 1}"
        clash = "" if job.is_measurement else settings_clash(job)
        failing += bool(clash)
        state = "clash" if clash else "restart" if job.restart else "done" if job_is_done_safely(job) else (
            "resume" if (Path(job.run_dir) / CHECKPOINT_NAME).exists() else "new")
        print(f"[{state:>6s}] {job.name}: {what}{clash}", file=file)
    return failing


def print_packs(jobs: Sequence[Job], pack: int, file=None) -> None:
    """One line per pack that `run_jobs` would form from the jobs not yet done (``pack`` as there)."""
    from train.experiments.jobs import Pack

    todo = [j for j in jobs if not job_is_done_safely(j)]
    for unit in pack_jobs(todo, pack):
        if isinstance(unit, Pack):
            seeds = sum(TrainConfig.from_dict(j.config).run.seeds for j in unit.jobs)
            print(f"[  pack] {unit.name}: trained as one process, {seeds} seeds", file=file or sys.stdout)


def settings_clash(job: Job) -> str:
    """Why a training job will fail on what its directory already holds (a run of other settings, or files ecorl
    did not write where it would start afresh), or "" if it will not.
    """
    from train.experiments.jobs import foreign_files, foreign_files_message
    from train.storage.rundir import RunDirError, check_same_run

    run_dir = Path(job.run_dir)
    starts_afresh = job.restart or not ((run_dir / CHECKPOINT_NAME).exists() or job_is_done_safely(job))
    if starts_afresh and (names := foreign_files(run_dir)):
        return f"\n         will fail: {foreign_files_message(run_dir, names).removesuffix('.')}"
    saved = run_dir / "config.json"
    if job.restart or not saved.is_file():
        return ""
    asked = TrainConfig.from_dict(job.config)
    try:
        check_same_run(TrainConfig.from_dict(load_json(saved)), asked, saved)
        step = _checkpoint_step(Path(job.run_dir))
        if step > asked.total_steps:
            raise RunDirError(f"the run stands at step {step}, beyond the {asked.total_steps} steps asked for; ask "
                              f"for at least {step} steps")
    except (RunDirError, ValueError) as err:
        return (f"\n         will fail: {' '.join(str(err).split()).removesuffix('.')}; or pass --restart "
                f"{Path(job.run_dir).name} to train it again from scratch")
    return ""


def _checkpoint_step(run_dir: Path) -> int:
    """The step of the run's checkpoint (`RunDir.saved_config`, no arrays read); -1 without one, or one that cannot
    be read (resuming then says why).
    """
    from train.storage.rundir import RunDir, RunDirError

    if not (run_dir / CHECKPOINT_NAME).is_file():
        return -1
    try:
        return RunDir(run_dir).saved_config()[1]
    except (RunDirError, OSError):
        return -1


def job_to_dict(job: Job) -> dict[str, Any]:
    """A JSON-friendly job."""
    return asdict(job)
