"""Reading a results directory: experiment directories, their trusted description, each condition's evaluations."""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from train.config import TrainConfig
from train.experiments.catalog import BUDGETS, EXPERIMENTS
from train.experiments.jobs import DONE_FILE
from train.experiments.report.stats import REWARD_BOUND, blown, diverged
from train.storage.checkpoint import CHECKPOINT_NAME
from train.storage.rundir import EXPERIMENT_FILE, MAX_METRIC_ROWS, MAX_METRICS_BYTES
from train.storage.safeio import load_json, read_text

REFERENCE_DIR = Path(__file__).resolve().parents[3] / "docs" / "results" / "paper"
"""Shipped paper-budget runs (metrics only): a report draws an experiment's quick curves over them."""


@dataclass
class Run:
    """The evaluations of one condition (all seeds) read from its run directory."""

    task: str
    condition: str
    label: str
    path: Path
    metric: str
    steps: np.ndarray
    """(E,) environment steps of the evaluations."""
    values: np.ndarray
    """(E, S) metric per evaluation and seed."""
    done: bool
    seed_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """(S,) the seeds' numbers."""
    blown: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))
    """(E, S) where a seed's values blew up at an evaluation (`stats.blown`; all False when unknown)."""
    top_share: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    """(E, S) the greedy policy's top-action share at each evaluation (NaN where the file predates it)."""
    config: dict[str, Any] = field(default_factory=dict)
    """The run's config.json as read (`run_config`; empty where unreadable)."""

    def top_shares(self, evaluation: int = -1) -> np.ndarray:
        """(S,) each seed's top-action share at evaluation ``evaluation`` (all NaN when unknown)."""
        if self.top_share.shape != self.values.shape:
            return np.full(self.seeds, np.nan)
        return self.top_share[evaluation]

    def diverged(self, evaluation: int = -1) -> np.ndarray:
        """(S,) seeds that diverged at or before evaluation number ``evaluation`` (`stats.diverged`)."""
        if self.blown.shape != self.values.shape:
            return np.zeros(self.seeds, dtype=bool)
        stop = evaluation % len(self.steps) + 1
        return diverged(self.blown[:stop])

    @property
    def seeds(self) -> int:
        """Number of seeds."""
        return self.values.shape[1]


@dataclass
class ExperimentResults:
    """What one experiment directory holds."""

    name: str
    path: Path
    info: dict[str, Any]
    runs: list[Run] = field(default_factory=list)
    measurements: list[dict[str, Any]] = field(default_factory=list)
    """Table 1 rows: task, measure, condition, mean, std, seeds, censored."""
    unevaluated: list[str] = field(default_factory=list)
    """The conditions (``task/condition``) whose run directory holds no evaluation yet."""

    @property
    def tasks(self) -> list[str]:
        """Tasks with results, in the experiment's panel order."""
        order = list(self.info.get("tasks", {}))
        present = {r.task for r in self.runs} | {m["task"] for m in self.measurements}
        return [t for t in order if t in present] + sorted(present - set(order))


def task_metric(task: str) -> str:
    """'success' or 'return' (the food collector's metric)."""
    from train.tasks import TASKS

    return TASKS[task].metric if task in TASKS else "success"


_DAMAGED = ("train that run again ('ecorl run ... --restart CONDITION', or 'ecorl train' into a new directory) or "
            "move its directory out of the results")


MAX_SEEDS = 1_024
"""Most seeds of one run a report reads (ecorl trains at most a few hundred per condition, even on a GPU)."""
MAX_EVALUATIONS = 100_000
"""Most evaluations of one run a report reads (a 1.5 M-step run evaluated every 5 000 steps has 300)."""
MAX_STEP = 2**53
"""Largest step or seed number a metrics.csv may hold (ecorl's configs stop there)."""
MAX_EXPERIMENT_BYTES = 4 << 20
"""Largest experiment.json read (ecorl writes about 10 KB)."""


def read_columns(path: Path, columns: tuple[str, ...], missing: float | tuple[float, ...] = 0.0
                 ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """(steps (E,), seeds (S,), one (E, S) array per column) of a metrics.csv; evaluations missing a seed are
    dropped, and a column a file lacks (or leaves empty) reads as ``missing`` (one value, or one per column).
    Rows are read one at a time and the file refused as soon as it passes `MAX_METRICS_BYTES`, `MAX_SEEDS` or
    `MAX_EVALUATIONS`, so a crafted file costs a bounded amount of memory.
    """
    missing = missing if isinstance(missing, tuple) else (missing,) * len(columns)
    by_step: dict[int, dict[int, list[float]]] = {}
    seeds: set[int] = set()
    text = read_text(path, MAX_METRICS_BYTES)  # a regular file only: no link, FIFO or device
    reader = csv.reader(io.StringIO(text, newline=""))
    header = next(reader, None)
    if header is None:
        return _no_rows(columns)
    if not {"step", "seed"} <= set(header):
        raise ReportError(f"{path} is not an ecorl metrics file (its header {header[:4]} has no step and seed "
                          f"columns); {_DAMAGED}")
    where = {name: i for i, name in enumerate(header)}  # a repeated name: its last column, as csv.DictReader
    layout = (len(header), where["step"], where["seed"], [where.get(c) for c in columns], missing)
    damaged = None  # (line, error) of a bad row: fine only if it is the last (a run interrupted mid-write)
    for row in reader:
        if not row:
            continue  # a blank line
        if damaged is not None:
            raise ReportError(f"{path} line {damaged[0]} is not a metrics row ({damaged[1]}); {_DAMAGED}")
        try:
            step, seed, values = _metrics_row(row, *layout)
        except ValueError as error:
            damaged = (reader.line_num, error)
            continue
        by_step.setdefault(step, {})[seed] = values
        seeds.add(seed)
        if len(seeds) > MAX_SEEDS or len(by_step) > MAX_EVALUATIONS or reader.line_num > MAX_METRIC_ROWS:
            raise ReportError(f"{path} holds more than {MAX_SEEDS:,} seeds, {MAX_EVALUATIONS:,} evaluations or "
                              f"{MAX_METRIC_ROWS:,} rows, the most a report reads per run; {_DAMAGED}")
    del text, reader
    if not by_step:
        return _no_rows(columns)
    order = sorted(seeds)
    steps = sorted(s for s, vals in by_step.items() if len(vals) == len(order))
    table = np.array([[by_step[s][k] for k in order] for s in steps], dtype=np.float64)
    table = table.reshape(len(steps), len(order), len(columns))
    return (np.array(steps, dtype=np.int64), np.array(order, dtype=np.int64),
            [table[..., i] for i in range(len(columns))])


def _no_rows(columns: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """`read_columns`' answer for a file with no complete evaluation."""
    return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), [np.zeros((0, 0)) for _ in columns]


def _metrics_row(row: list[str], width: int, step_at: int, seed_at: int, picks: list[int | None],
                 missing: tuple[float, ...]) -> tuple[int, int, list[float]]:
    """(step, seed, the picked cells' values) of one metrics.csv row of ``width`` header columns, else ValueError."""
    if len(row) < width:
        raise ValueError("fewer cells than the header")
    step, seed = int(row[step_at]), int(row[seed_at])
    if not (0 <= step <= MAX_STEP and 0 <= seed <= MAX_STEP):
        raise ValueError(f"step {step} or seed {seed} outside [0, {MAX_STEP}]")
    return step, seed, [float(row[i]) if i is not None and row[i] != "" else gap for i, gap in zip(picks, missing)]


def read_metrics(path: Path, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """(steps (E,), values (E, S)) of a metrics.csv; evaluations missing a seed are dropped."""
    steps, _, (values,) = read_columns(path, (metric,))
    return steps, values


def run_config(run_dir: Path) -> dict[str, Any]:
    """The run's config.json as read (an empty dict where unreadable): `Run.config`, read once per run."""
    try:
        config = load_json(run_dir / "config.json")
    except (OSError, ValueError):
        return {}
    return config if isinstance(config, dict) else {}


def config_gamma(config: dict[str, Any]) -> float:
    """The discount of a run's config.json (the default where it does not say)."""
    try:
        return float(config["dqn"]["gamma"])
    except (ValueError, KeyError, TypeError):
        return TrainConfig().dqn.gamma


def evaluation_size(config: dict[str, Any]) -> int | None:
    """How many validation layouts (food collector: episodes) each evaluation used, from a run's config.json
    (None where it does not say).
    """
    try:
        return int(config["eval"]["eval_rollouts"])
    except (ValueError, KeyError, TypeError):
        return None


REWARD_PARAMETERS = ("reward_ladder", "goal", "predator_penalty")
"""The task parameters that change what a step can pay (factory's ladder and goal, scavenging's predator cost); the
only ones `reward_bound` builds an environment with, so a results tree cannot make the report build a huge one."""


def reward_bound(config: dict[str, Any]) -> float:
    """The largest per-step |reward| of the training environment a run's config.json describes
    (`train.tasks.EnvInfo.reward_bound`; `stats.REWARD_BOUND` where unreadable).
    """
    from train.tasks import get_task, probe

    try:
        env = TrainConfig.from_dict(config).env
        if not set(env.env_kwargs) & set(REWARD_PARAMETERS) and env.task != "factory":
            return REWARD_BOUND  # no other task's rewards depend on its parameters
        kept = {k: v for k, v in env.env_kwargs.items() if k in REWARD_PARAMETERS}
        return probe(get_task(env.task), replace(env, env_kwargs=kept)).reward_bound
    except (ValueError, KeyError, TypeError):
        return REWARD_BOUND


def read_run(run_dir: Path, task: str, condition: str, label: str) -> Run | None:
    """The `Run` of one condition's run directory (None when it has no complete evaluation yet)."""
    metric = task_metric(task)
    steps, seeds, (values, loss, max_q, top_share) = read_columns(
        run_dir / "metrics.csv", (metric, "loss", "max_q", "top_action_share"), missing=(0.0, 0.0, 0.0, np.nan))
    if not len(steps):
        return None
    config = run_config(run_dir)
    return Run(task, condition, label, run_dir, metric, steps, values, (run_dir / DONE_FILE).exists(), seeds,
               blown(loss, max_q, config_gamma(config), reward_bound(config)), top_share, config)


def find_experiment_dirs(root: Path) -> list[Path]:
    """``root`` if it is an experiment directory, else the experiment directories right below it."""
    if (root / EXPERIMENT_FILE).exists():
        return [root]
    order = list(EXPERIMENTS)
    found = [p.parent for p in root.glob(f"*/{EXPERIMENT_FILE}")]
    return sorted(found, key=lambda p: (order.index(p.name) if p.name in order else len(order), p.name))


def reportable_below(source: Path, depth: int = 4) -> list[Path]:
    """Folders under ``source`` (at most ``depth`` levels down, ``source`` itself and its children aside) that
    `make_report` takes: an experiment's results or a train run; relative paths, sorted.
    """
    found = []
    for level in range(2, depth + 1):
        for path in sorted(source.glob("/".join(["*"] * level))):
            if path.name == EXPERIMENT_FILE or (path.name == "config.json" and (path.parent / "metrics.csv").exists()):
                parent = path.parent.relative_to(source)
                if not any(parent.is_relative_to(f) for f in found):
                    found.append(parent)
    return found


class ReportError(ValueError):
    """A results directory the report refuses to read (the message says why)."""


def trusted_info(path: Path) -> dict[str, Any]:
    """experiment.json of ``path``, checked against the known experiments: its name, tasks and conditions
    must be ones `train.experiments.catalog` defines (so no name can lead outside the results folder), and every
    text shown comes from the known experiment, not from the file.
    """
    try:
        saved = load_json(path / EXPERIMENT_FILE, MAX_EXPERIMENT_BYTES)
    except ValueError as err:
        raise ReportError(f"{path / EXPERIMENT_FILE} is not valid JSON ({err})") from None
    name = saved.get("name") if isinstance(saved, dict) else None
    if not isinstance(name, str) or name not in EXPERIMENTS:
        raise ReportError(f"{path / EXPERIMENT_FILE} names an unknown experiment {name!r}; the report reads only "
                          f"experiments written by ecorl run ({', '.join(EXPERIMENTS)})")
    known = EXPERIMENTS[name]
    tasks = saved.get("tasks", {})
    if not isinstance(tasks, dict):
        raise ReportError(f"{path / EXPERIMENT_FILE}: 'tasks' is not an object")
    for task, conds in tasks.items():
        allowed = {c.name for c in known.conditions.get(task, ())}
        names = [c.get("name") if isinstance(c, dict) else c for c in conds] if isinstance(conds, list) else [conds]
        bad = [n for n in names if n not in allowed]
        if task not in known.conditions or bad:
            what = f"task {task!r}" if task not in known.conditions else f"condition(s) {bad!r} of {task}"
            raise ReportError(f"{path / EXPERIMENT_FILE} names {what}, which experiment {name!r} does not have")
    info = known.describe()
    info["tasks"] = {t: c for t, c in info["tasks"].items() if t in tasks}
    budget = saved.get("budget")
    info["budget"] = budget if budget in BUDGETS else "?"
    return info


def _measurement_rows(table: Path, task: str, measure: str) -> list[dict]:
    """The rows of a measurement's table.csv, or a one-line ReportError naming the file and the line."""
    with io.StringIO(read_text(table), newline="") as f:
        rows = list(csv.DictReader(f))
    out = []
    for number, row in enumerate(rows, start=2):
        try:
            out.append({"task": task, "measure": measure, "condition": str(row["condition"]),
                        "mean": float(row["mean"]), "std": float(row["std"]), "seeds": int(row["seeds"]),
                        "censored": int(row["censored"])})
        except (KeyError, TypeError, ValueError) as error:
            raise ReportError(f"{table} line {number} is not a measurement row ({error}); {_DAMAGED}") from None
    return out


def load_experiment(path: Path) -> ExperimentResults:
    """Read the runs (or measurements) of one experiment directory."""
    info = trusted_info(path)
    result = ExperimentResults(info["name"], path, info)
    for task, conds in info.get("tasks", {}).items():
        for cond in conds:
            run_dir = path / task / cond["name"]
            if cond.get("measure"):
                table = run_dir / "table.csv"
                if table.exists() or table.is_symlink():
                    result.measurements += _measurement_rows(table, task, cond["measure"])
                continue
            run = read_run(run_dir, task, cond["name"], cond["label"]) if (run_dir / "metrics.csv").exists() else None
            if run is not None:
                result.runs.append(run)
            elif run_dir.is_dir():  # started (its directory made), not evaluated yet
                result.unevaluated.append(f"{task}/{cond['name']}")
    return result


def load_reference(exp: ExperimentResults, reference_dir: Path | None = None) -> ExperimentResults | None:
    """The shipped paper-budget runs of ``exp``'s experiment (under `REFERENCE_DIR` unless given), or None
    (none shipped, or ``exp`` is them).
    """
    path = (reference_dir or REFERENCE_DIR) / exp.name
    if not (path / EXPERIMENT_FILE).exists() or path.resolve() == exp.path.resolve():
        return None
    reference = load_experiment(path)
    return reference if reference.runs else None


def is_run_dir(path: Path) -> bool:
    """True for an ``ecorl train`` run directory (config.json and metrics.csv, no experiment.json); entries
    that are not regular files count here, so that reading them says what is wrong with them.
    """
    files = all(os.path.lexists(path / name) for name in ("config.json", "metrics.csv"))
    return files and not (path / EXPERIMENT_FILE).exists()


def stopped_before_evaluating(path: Path, shown: str | Path) -> str | None:
    """One line for an ``ecorl train`` run directory with no evaluation yet (config.json, no metrics.csv), naming
    the command that resumes it (``shown``: the directory as the user gave it); None for any other directory.
    """
    if (not (path / "config.json").is_file() or os.path.lexists(path / "metrics.csv")
            or os.path.lexists(path / EXPERIMENT_FILE)):
        return None
    try:
        task = TrainConfig.from_dict(load_json(path / "config.json")).env.task
    except (ValueError, TypeError, KeyError):
        return None  # not a run's configuration: the report's usual error names what it reads
    if not os.path.lexists(path / CHECKPOINT_NAME):
        return (f"{shown} holds a run stopped before its first evaluation and its first checkpoint: nothing to "
                f"report or resume; delete it and train it again")
    return (f"{shown} holds a run stopped before its first evaluation: nothing to report yet; continue it with: "
            f"ecorl train {task} --resume --out {shown}")


def load_single_run(path: Path) -> ExperimentResults:
    """An ``ecorl train`` run directory as an experiment of one condition (named from its knobs, so it gets
    the same colour as that condition in the experiments' figures).
    """
    from train.config import TrainConfig

    try:
        cfg = TrainConfig.from_dict(load_json(path / "config.json"))
    except (ValueError, TypeError, KeyError) as err:
        raise ReportError(f"{path / 'config.json'} is not a training configuration ({err})") from None
    env = cfg.env
    condition = f"{'dynamic' if env.dynamism else 'static'}-{'reset-free' if env.reset_free else 'episodic'}"
    label = (f"{'dynamic p=' + format(env.dynamism, 'g') if env.dynamism else 'static'}, "
             f"{'non-episodic' if env.reset_free else 'episodic'}, {env.reward} reward, lr {cfg.dqn.lr:g}"
             + (f", shaping {env.shaping}" if env.shaping not in ("0", "0.0") else ""))
    info = {"name": path.name, "paper": "ecorl train", "title": f"{env.task}: {label}",
            "description": f"One training run: {cfg.run.seeds} seed(s) x {cfg.total_steps:,} steps "
                           f"(first seed {cfg.run.first_seed}).",
            "heatmaps": True, "videos": True, "budget": "ecorl train", "milestones": [],
            "first_seed": cfg.run.first_seed,
            "tasks": {env.task: [{"name": condition, "label": label}]}}
    result = ExperimentResults(path.name, path, info)
    run = read_run(path, env.task, condition, label)  # the columns an experiment's report reads, so the same counts
    if run is not None:
        run.done = int(run.steps[-1]) >= cfg.total_steps
        result.runs.append(run)
    return result
