"""Turn a results directory into the paper's pictures and tables, beside the paper's own numbers.

``make_report(DIR)`` reads every experiment directory under DIR (or DIR itself) written by `train.experiments.sweep`
and writes into DIR:

* ``figures/<experiment>_curves.png``: learning curves, one panel per task, mean and 95% bootstrap CI
  over seeds against environment steps, the paper's reported values as dotted lines;
* ``figures/<experiment>_<task>_heatmaps.png``: cumulative visitation counts (summed over seeds) at four
  points of training, for experiments that ask for them (Fig. 2, 9, 10);
* ``report.md``: final success (or return) per condition, mean ± 95% CI over seeds at the last
  evaluation, beside the paper's numbers (``assets/paper/*.json``; ≈ marks values read from a figure or
  quoted in the text, = values from a table), and Table 1 measurements;
* ``index.html``: all of it on one static page, with the rollout videos found in the run directories
  (``video.mp4``) or in DIR, re-encoded to WebM so that browsers play them.
"""

from __future__ import annotations

import csv
import html
import json
import math
import os
import sys
import textwrap
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from train.checkpoint import CHECKPOINT_NAME
from train.experiments.catalog import BUDGETS, EXPERIMENTS
from train.experiments.sweep import DONE_FILE, EXPERIMENT_FILE
from train.experiments.table1 import format_value
from train.fileio import atomic_file, atomic_path, atomic_text, is_temporary

PAPER_DIR = Path(__file__).resolve().parents[3] / "assets" / "paper"
REFERENCE_DIR = Path(__file__).resolve().parents[3] / "docs" / "results" / "paper"
"""Shipped paper-budget runs (metrics only): a report draws an experiment's quick curves over them."""
"""Where the paper's transcribed numbers live (``assets/paper`` of the source tree)."""
CI_LEVEL = 0.95
BOOTSTRAP_SAMPLES = 2000
HEATMAP_POINTS = 4
LEARNED = 0.2
"""A seed 'learned' the task when it solves more than this fraction of the validation layouts (outcomes are
bimodal: a seed finds the task or it does not)."""
MILESTONE_TOLERANCE = 5_000
"""An evaluation stands for a milestone step when it lies within this many steps of it."""
"""Points of training shown in each heat-map row (the paper's Fig. 9-10 show four)."""


# ---- statistics ----------------------------------------------------------------------------------------


def bootstrap_ci(values: np.ndarray, level: float = CI_LEVEL, samples: int = BOOTSTRAP_SAMPLES,
                 seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over the last axis (seeds) and its percentile-bootstrap confidence interval.

    ``values`` is (..., seeds); returns (mean, low, high), each of shape (...). With one seed the
    interval collapses onto the value.
    """
    values = np.asarray(values, dtype=np.float64)
    n = values.shape[-1]
    mean = values.mean(-1)
    if n < 2:
        return mean, mean.copy(), mean.copy()
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, size=(samples, n))
    boots = values[..., idx].mean(-1)  # (..., samples)
    tail = (1.0 - level) / 2.0 * 100.0
    low, high = np.percentile(boots, [tail, 100.0 - tail], axis=-1)
    return mean, low, high


# ---- reading runs --------------------------------------------------------------------------------------


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


def read_metrics(path: Path, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """(steps (E,), values (E, S)) of a metrics.csv; evaluations missing a seed are dropped."""
    by_step: dict[int, dict[int, float]] = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            by_step.setdefault(int(row["step"]), {})[int(row["seed"])] = float(row[metric])
    if not by_step:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 0))
    seeds = sorted(set().union(*by_step.values()))
    steps = sorted(s for s, vals in by_step.items() if len(vals) == len(seeds))
    values = np.array([[by_step[s][k] for k in seeds] for s in steps], dtype=np.float64).reshape(len(steps), -1)
    return np.array(steps, dtype=np.int64), values


def find_experiment_dirs(root: Path) -> list[Path]:
    """``root`` if it is an experiment directory, else the experiment directories right below it."""
    if (root / EXPERIMENT_FILE).exists():
        return [root]
    order = list(EXPERIMENTS)
    found = [p.parent for p in root.glob(f"*/{EXPERIMENT_FILE}")]
    return sorted(found, key=lambda p: (order.index(p.name) if p.name in order else len(order), p.name))


class ReportError(ValueError):
    """A results directory the report refuses to read (the message says why)."""


def trusted_info(path: Path) -> dict[str, Any]:
    """experiment.json of ``path``, checked against the known experiments: its name, tasks and conditions
    must be ones `train.experiments.catalog` defines (so no name can lead outside the results folder), and every
    text shown comes from the known experiment, not from the file."""
    try:
        saved = json.loads((path / EXPERIMENT_FILE).read_text())
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


def load_experiment(path: Path) -> ExperimentResults:
    """Read the runs (or measurements) of one experiment directory."""
    info = trusted_info(path)
    result = ExperimentResults(info["name"], path, info)
    for task, conds in info.get("tasks", {}).items():
        for cond in conds:
            run_dir = path / task / cond["name"]
            if cond.get("measure"):
                table = run_dir / "table.csv"
                if table.exists():
                    with open(table, newline="") as f:
                        for row in csv.DictReader(f):
                            result.measurements.append({
                                "task": task, "measure": cond["measure"], "condition": row["condition"],
                                "mean": float(row["mean"]), "std": float(row["std"]), "seeds": int(row["seeds"]),
                                "censored": int(row["censored"])})
                continue
            metrics = run_dir / "metrics.csv"
            if not metrics.exists():
                continue
            metric = task_metric(task)
            steps, values = read_metrics(metrics, metric)
            if len(steps):
                result.runs.append(Run(task, cond["name"], cond["label"], run_dir, metric, steps, values,
                                       (run_dir / DONE_FILE).exists()))
    return result


def load_reference(exp: ExperimentResults, reference_dir: Path | None = None) -> ExperimentResults | None:
    """The shipped paper-budget runs of ``exp``'s experiment (under `REFERENCE_DIR` unless given), or None
    (none shipped, or ``exp`` is them)."""
    path = (reference_dir or REFERENCE_DIR) / exp.name
    if not (path / EXPERIMENT_FILE).exists() or path.resolve() == exp.path.resolve():
        return None
    reference = load_experiment(path)
    return reference if reference.runs else None


# ---- the paper's numbers -------------------------------------------------------------------------------


def load_paper(paper_dir: Path = PAPER_DIR) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """experiment -> {'values': [...], 'claims': [...], 'sources': [...]} from ``assets/paper/*.json``."""
    out: dict[str, dict[str, list[dict[str, Any]]]] = {}
    if not paper_dir.is_dir():
        return out
    for path in sorted(paper_dir.glob("*.json")):
        data = json.loads(path.read_text())
        for exp in data.get("experiments", []):
            entry = out.setdefault(exp, {"values": [], "claims": [], "sources": []})
            entry["values"] += [{**v, "figure": data["figure"]} for v in data.get("values", [])]
            entry["claims"] += [{**c, "figure": data["figure"]} for c in data.get("claims", [])
                                if c.get("experiment", exp) == exp]
            entry["sources"].append({"figure": data["figure"], "source": data.get("source", ""),
                                     "note": data.get("note", "")})
    return out


def paper_value(paper: dict, task: str, condition: str) -> dict[str, Any] | None:
    """The paper's reported final value of a condition, if any."""
    for v in paper.get("values", []):
        if v.get("task") == task and v.get("condition") == condition and "value" in v:
            return v
    return None


def format_paper(v: dict[str, Any] | None, scale: float = 100.0, unit: str = "%") -> str:
    """'≈ 12%' for approximate values, '= 12%' for exact ones, '—' when the paper has none."""
    if v is None:
        return "—"
    mark = "≈" if v.get("approximate", True) else "="
    return f"{mark} {v['value'] * scale:.0f}{unit} ({v['figure']})"


# ---- figures -------------------------------------------------------------------------------------------


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _reference_label(reference: ExperimentResults) -> str:
    seeds = sorted({r.seeds for r in reference.runs})
    steps = max(int(r.steps[-1]) for r in reference.runs)
    return f"shipped run, {'/'.join(map(str, seeds))} seeds × {steps / 1e6:.2g} M steps (dashed)"


def plot_curves(exp: ExperimentResults, paper: dict, out: Path,
                reference: ExperimentResults | None = None) -> Path | None:
    """One panel per task: mean and 95% CI over seeds of every condition, each seed as a thin line; the
    paper's values dotted; the same conditions of a ``reference`` experiment (shipped paper-budget runs)
    dashed, so a short run shows where its curves are heading."""
    tasks = [t for t in exp.tasks if any(r.task == t for r in exp.runs)]
    if not tasks:
        return None
    plt = _pyplot()
    ncols = min(len(tasks), 5)
    nrows = math.ceil(len(tasks) / ncols)
    width = max(4.2 * ncols, 7.5)
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, 3.4 * nrows + 1.2), squeeze=False,
                             layout="constrained")
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    names = list(dict.fromkeys(r.condition for r in exp.runs))  # one color per condition, in every panel
    color_of = {name: palette[i % len(palette)] for i, name in enumerate(names)}
    labels = {r.condition: set() for r in exp.runs}
    for r in exp.runs:
        labels[r.condition].add(r.label)
    shared_legend = all(len(v) == 1 for v in labels.values())  # else each panel gets its own legend
    handles: dict[str, Any] = {}
    has_paper = False
    for ax, task in zip(axes.flat, tasks):
        runs = [r for r in exp.runs if r.task == task]
        for run in runs:
            color = color_of[run.condition]
            mean, low, high = bootstrap_ci(run.values)
            ax.plot(run.steps, run.values, color=color, lw=0.5, alpha=0.35)  # each seed: the bimodality
            (line,) = ax.plot(run.steps, mean, color=color, lw=1.6, label=run.label)
            ax.fill_between(run.steps, low, high, color=color, alpha=0.2, lw=0)
            handles.setdefault(run.label, line)
            for old in (reference.runs if reference else []):
                if old.task == task and old.condition == run.condition:
                    ax.plot(old.steps, bootstrap_ci(old.values)[0], color=color, lw=1.2, ls="--")
            ref = paper_value(paper, task, run.condition)
            if ref is not None:
                ax.axhline(ref["value"], color=color, ls=":", lw=1.3)
                has_paper = True
        metric = runs[0].metric
        ax.set_title(task)
        ax.set_xlabel("environment steps")
        ax.set_ylabel("fraction of validation tasks solved" if metric == "success" else "mean validation return")
        if metric == "success":
            ax.set_ylim(-0.03, 1.03)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
        ax.grid(alpha=0.3)
        if not shared_legend:
            ax.legend(fontsize=7, frameon=False, loc="upper left")
    for ax in list(axes.flat)[len(tasks):]:
        ax.set_visible(False)
    if not shared_legend:
        handles = {}
    if has_paper:
        from matplotlib.lines import Line2D

        handles["paper's final value (dotted; ≈, quoted in its text)"] = Line2D([], [], color="gray", ls=":")
    if reference is not None:
        from matplotlib.lines import Line2D

        handles[_reference_label(reference)] = Line2D([], [], color="gray", ls="--")
    if handles:
        legend_cols = max(1, min(len(handles), int(width // 3.6)))
        fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncol=legend_cols,
                   frameon=False, fontsize=9)
    seeds = sorted({r.seeds for r in exp.runs})
    title = (f"{exp.info.get('paper', '')}: {exp.info.get('title', exp.name)} (mean and {CI_LEVEL:.0%} bootstrap "
             f"CI over {'/'.join(map(str, seeds))} seeds; thin lines: single seeds)")
    fig.suptitle(textwrap.fill(title, int(width * 11)), fontsize=11)
    _save_figure(fig, out, dpi=110)
    return out


def _save_figure(fig, out: Path, dpi: int) -> None:
    """Write a figure as PNG atomically and close it."""
    try:
        with atomic_file(out) as f:
            fig.savefig(f, format="png", dpi=dpi)
    finally:
        _pyplot().close(fig)


def visit_snapshots(run_dir: Path, points: int = HEATMAP_POINTS) -> list[tuple[int, np.ndarray]]:
    """Up to ``points`` evenly spaced (step, counts summed over seeds) snapshots of a run's visitation."""
    files = sorted((run_dir / "visits").glob("*.npy"), key=lambda p: int(p.stem))
    if not files:
        return []
    picks = sorted(set(np.round(np.linspace(0, len(files) - 1, points)).astype(int)))
    return [(int(files[i].stem), np.load(files[i]).sum(0)) for i in picks]


def plot_heatmaps(exp: ExperimentResults, task: str, out: Path) -> Path | None:
    """Rows: conditions; columns: four points of training; cumulative visit counts summed over seeds."""
    rows = [(r, visit_snapshots(r.path)) for r in exp.runs if r.task == task]
    rows = [(r, snaps) for r, snaps in rows if snaps]
    if not rows:
        return None
    plt = _pyplot()
    ncols = max(len(s) for _, s in rows)
    fig, axes = plt.subplots(len(rows), ncols, figsize=(2.3 * ncols + 1.6, 2.3 * len(rows) + 0.6), squeeze=False,
                             layout="constrained")
    for (run, snaps), axrow in zip(rows, axes):
        for ax, (step, counts) in zip(axrow, snaps):
            ax.imshow(counts, cmap="viridis", interpolation="nearest")
            ax.set_title(f"step {step:,}", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
        axrow[0].set_ylabel(run.label, fontsize=8)
        for ax in axrow[len(snaps):]:
            ax.set_visible(False)
    width = 2.3 * ncols + 1.6
    title = (f"{exp.info.get('paper', '')}: state visitation counts on {task} (cumulative, summed over seeds; "
             f"yellow = often, purple = rarely)")
    fig.suptitle(textwrap.fill(title, int(width * 13)), fontsize=9)
    _save_figure(fig, out, dpi=100)
    return out


# ---- tables --------------------------------------------------------------------------------------------


def metric_scale(metric: str) -> tuple[float, str]:
    """(factor, unit) that shows a metric: success as a percentage, returns as they are."""
    return (100.0, "%") if metric == "success" else (1.0, "")


def summarize(values: np.ndarray, metric: str) -> tuple[str, str]:
    """('mean [95% CI]', 'k / S' seeds learned, or '—' for returns) of one evaluation's per-seed values."""
    mean, low, high = bootstrap_ci(values)
    scale, unit = metric_scale(metric)
    ours = f"{float(mean) * scale:.1f}{unit} [{float(low) * scale:.1f}, {float(high) * scale:.1f}]"
    learned = f"{int((values > LEARNED).sum())} / {values.size}" if metric == "success" else "—"
    return ours, learned


def final_rows(exp: ExperimentResults, paper: dict) -> list[dict[str, Any]]:
    """Per condition: last evaluation's mean and 95% CI over seeds and the seeds that learned, beside the
    paper's value."""
    rows = []
    for run in exp.runs:
        ours, learned = summarize(run.values[-1], run.metric)
        scale, unit = metric_scale(run.metric)
        rows.append({"task": run.task, "condition": run.label, "metric": run.metric, "ours": ours,
                     "learned": learned, "seeds": run.seeds, "step": int(run.steps[-1]), "done": run.done,
                     "paper": format_paper(paper_value(paper, run.task, run.condition), scale, unit)})
    return rows


def _milestones(exp: ExperimentResults) -> list[int]:
    """The experiment's milestone steps (its info comes from the known definition, see `trusted_info`)."""
    return list(exp.info.get("milestones", []))


def milestone_rows(exp: ExperimentResults) -> list[dict[str, Any]]:
    """Per condition and milestone step of the experiment (``info['milestones']``): the evaluation closest
    to it (within `MILESTONE_TOLERANCE`), mean [95% CI] and seeds learned; '—' where the run has not reached
    it."""
    milestones = _milestones(exp)
    rows = []
    for run in exp.runs:
        row = {"task": run.task, "condition": run.label}
        for m in milestones:
            distance = np.abs(run.steps - m)
            if distance.size and distance.min() <= MILESTONE_TOLERANCE:
                ours, learned = summarize(run.values[int(distance.argmin())], run.metric)
                row[f"at{m}"] = f"{ours}; learned {learned}"
            else:
                row[f"at{m}"] = "—"
        rows.append(row)
    return rows if milestones else []


def milestone_columns(exp: ExperimentResults) -> tuple[tuple[str, str], ...]:
    """The (key, header) columns of `milestone_rows`."""
    heads = [(f"at{m}", f"at {m:,} steps: mean [95% CI]; seeds > {LEARNED:.0%}") for m in _milestones(exp)]
    return (("task", "task"), ("condition", "condition"), *heads)


def measurement_rows(exp: ExperimentResults, paper: dict) -> list[dict[str, Any]]:
    """Table 1 rows: ours (mean ± std over seeds) beside the paper's exact values."""
    refs = {(v["task"], v.get("measure"), v["condition"]): v for v in paper.get("values", [])}
    rows = []
    for m in exp.measurements:
        ref = refs.get((m["task"], m["measure"], m["condition"]))
        rows.append({"task": m["task"], "measure": m["measure"], "condition": m["condition"],
                     "ours": format_value(m["measure"], m), "seeds": m["seeds"],
                     "paper": "—" if ref is None else f"= {ref['mean']:g} ± {ref['std']:g} ({ref['figure']})"})
    return rows


def _md_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> list[str]:
    """A markdown table of ``rows`` with (key, header) columns."""
    out = ["| " + " | ".join(h for _, h in columns) + " |", "|" + "---|" * len(columns)]
    out += ["| " + " | ".join(str(r[k]) for k, _ in columns) + " |" for r in rows]
    return out


FINAL_COLUMNS = (("task", "task"), ("condition", "condition"), ("ours", "ours: final mean [95% CI]"),
                 ("learned", f"seeds learned (> {LEARNED:.0%})"), ("seeds", "seeds"), ("step", "at step"),
                 ("paper", "paper"))
MEASUREMENT_COLUMNS = (("task", "task"), ("measure", "measurement"), ("condition", "condition"),
                   ("ours", "ours: mean ± std"), ("seeds", "seeds"), ("paper", "paper"))


# ---- videos --------------------------------------------------------------------------------------------


def render_missing_videos(exp: ExperimentResults) -> list[Path]:
    """Render ``video.mp4`` (seed 0's final policy in the test MDP) for finished runs without one."""
    from train.experiments.video import record_video
    from train.rundir import RunDirError

    made = []
    for run in exp.runs:
        target = run.path / "video.mp4"
        if run.done and not target.exists() and (run.path / CHECKPOINT_NAME).exists():
            try:
                made.append(record_video(None, target, policy_path=run.path).path)
            except (RunDirError, ValueError, FileNotFoundError) as err:
                print(f"ecorl report: no video of {run.path}: {err}", file=sys.stderr)
    return made


def find_videos(root: Path) -> list[Path]:
    """Every MP4 below ``root`` (run directories and the top level), sorted."""
    return sorted(p for p in root.rglob("*.mp4") if ".partial" not in p.name and not is_temporary(p.name))


@contextmanager
def _quiet_stderr():
    """Silence the process's stderr (file descriptor 2, so C libraries too) inside the block."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def web_copy(video: Path, out_dir: Path, root: Path) -> Path | None:
    """A WebM (VP8) copy of an MP4 for the HTML page (OpenCV's MP4 codec does not play in browsers)."""
    import cv2

    name = "_".join(video.relative_to(root).with_suffix("").parts) + ".webm"
    target = out_dir / name
    if target.exists() and target.stat().st_mtime >= video.stat().st_mtime:
        return target
    cap = cv2.VideoCapture(str(video))
    try:
        with atomic_path(target) as tmp:
            if not _transcode(cap, tmp):
                raise _NoFrames
    except _NoFrames:
        return None
    finally:
        cap.release()
    return target


class _NoFrames(Exception):
    """A video that could not be read or re-encoded (its web copy is skipped)."""


def _transcode(cap, out: Path) -> bool:
    """Re-encode every frame of an opened capture to a VP8 WebM at ``out``; False if nothing was written."""
    import cv2

    fps = cap.get(cv2.CAP_PROP_FPS) or 8.0
    writer = None
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            if writer is None:
                with _quiet_stderr():  # FFMPEG names its tag fallback on stderr; the file is fine
                    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"VP80"), fps,
                                             (frame.shape[1], frame.shape[0]))
                if not writer.isOpened():
                    return False
            writer.write(frame)
    finally:
        if writer is not None:
            writer.release()
    return writer is not None


# ---- the report ----------------------------------------------------------------------------------------


@dataclass
class Section:
    """What the report shows for one experiment."""

    exp: ExperimentResults
    curves: Path | None
    heatmaps: list[Path]
    finals: list[dict[str, Any]]
    measures: list[dict[str, Any]]
    claims: list[dict[str, Any]]
    sources: list[dict[str, Any]]
    milestones: list[dict[str, Any]] = field(default_factory=list)
    reference: ExperimentResults | None = None
    """Shipped paper-budget runs drawn dashed under this experiment's curves."""


def build_sections(root: Path, videos: bool | None = None) -> list[Section]:
    """Read every experiment under ``root``, draw its figures and compute its tables."""
    paper_all = load_paper()
    sections = []
    for path in find_experiment_dirs(root):
        exp = load_experiment(path)
        paper = paper_all.get(exp.name, {})
        if videos or (videos is None and exp.info.get("videos")):
            render_missing_videos(exp)
        figures = root / "figures"
        reference = load_reference(exp)
        curves = plot_curves(exp, paper, figures / f"{exp.name}_curves.png", reference)
        heatmaps = []
        if exp.info.get("heatmaps"):
            heatmaps = [p for t in exp.tasks if (p := plot_heatmaps(exp, t, figures / f"{exp.name}_{t}_heatmaps.png"))]
        tasks_run = set(exp.tasks)
        claims = [c for c in paper.get("claims", []) if c.get("task") in (None, *tasks_run)]
        sections.append(Section(exp, curves, heatmaps, final_rows(exp, paper), measurement_rows(exp, paper),
                                claims, paper.get("sources", []), milestone_rows(exp), reference))
    return sections


def _shown(path: Path) -> Path:
    """``path`` relative to the working directory when it lies inside it (reports get copied around)."""
    try:
        return Path(path).resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return Path(path)


def _budget_line(exp: ExperimentResults) -> str:
    known = EXPERIMENTS.get(exp.name)
    budget = exp.info.get("budget", "?")
    paper_seeds = f"; the paper's budget is {known.paper_seeds} seeds" if known else ""
    return f"Budget: `{budget}`{paper_seeds}. Directory: `{_shown(exp.path)}`."


def write_markdown(root: Path, sections: Sequence[Section]) -> Path:
    """``report.md``: per experiment its figures, final results beside the paper's, and the paper's claims."""
    lines = [f"# ecorl report: `{_shown(root)}`", "",
             "Success = fraction of the 100 fixed validation layouts of the test MDP solved (food collector: mean "
             "return over validation episodes), at the last evaluation; mean over seeds with a 95% bootstrap "
             "confidence interval. Paper column: **≈** a value read from a figure or quoted in the paper's text "
             "(approximate), **=** a value from a table (exact), — the paper reports no number.", ""]
    for s in sections:
        info = s.exp.info
        lines += [f"## {s.exp.name} ({info.get('paper', '')}): {info.get('title', '')}", "",
                  info.get("description", ""), "", _budget_line(s.exp), ""]
        if s.curves:
            lines += [f"![learning curves]({s.curves.relative_to(root).as_posix()})", ""]
        if s.curves and s.reference:
            lines += [f"Dashed: the mean of the {_reference_label(s.reference).replace(' (dashed)', '')} shipped in "
                      f"`{_shown(s.reference.path)}` (re-draw it with `ecorl report {_shown(s.reference.path)}`).", ""]
        for h in s.heatmaps:
            lines += [f"![visitation heat-maps]({h.relative_to(root).as_posix()})", ""]
        if s.finals:
            unfinished = [r for r in s.finals if not r["done"]]
            lines += _md_table(s.finals, FINAL_COLUMNS) + [""]
            if unfinished:
                lines += [f"{len(unfinished)} run(s) not finished yet (their latest evaluation is shown); "
                          f"re-run the same `ecorl run` command to complete them.", ""]
        if s.milestones:
            lines += _md_table(s.milestones, milestone_columns(s.exp)) + [""]
        if s.measures:
            lines += _md_table(s.measures, MEASUREMENT_COLUMNS) + [""]
        if s.claims:
            lines += ["What the paper reports:", ""]
            lines += [f"- {c['text']} ({c['figure']}{', ' + c['task'] if c.get('task') else ''})" for c in s.claims]
            lines += [""]
        for src in s.sources:
            if src.get("note"):
                lines += [f"*{src['figure']}: {src['note']}*", ""]
    return atomic_text(root / "report.md", "\n".join(lines).rstrip() + "\n")


def _html_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for _, h in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(r[k]))}</td>" for k, _ in columns) + "</tr>"
                   for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def write_html(root: Path, sections: Sequence[Section], videos: Sequence[Path]) -> Path:
    """``index.html``: the report as one static page, with the videos."""
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>ecorl report</title><style>",
             "body{font-family:sans-serif;max-width:1400px;margin:auto;padding:1em}img{max-width:100%}"
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;"
             "font-size:90%}video{width:260px;margin:4px}figure{display:inline-block;margin:4px}"
             "figcaption{font-size:80%;max-width:260px}",
             "</style></head><body>", f"<h1>ecorl report</h1><p><code>{html.escape(str(root))}</code> — "
             "also as <a href='report.md'>report.md</a>. Paper column: ≈ approximate (figure or text), "
             "= exact (table).</p>"]
    for s in sections:
        info = s.exp.info
        parts.append(f"<h2>{html.escape(s.exp.name)} ({html.escape(info.get('paper', ''))}): "
                     f"{html.escape(info.get('title', ''))}</h2><p>{html.escape(info.get('description', ''))}</p>"
                     f"<p>{html.escape(_budget_line(s.exp).replace('`', ''))}</p>")
        for img in ([s.curves] if s.curves else []) + s.heatmaps:
            parts.append(f"<p><img src='{html.escape(img.relative_to(root).as_posix())}'></p>")
        if s.finals:
            parts.append(_html_table(s.finals, FINAL_COLUMNS))
        if s.milestones:
            parts.append(_html_table(s.milestones, milestone_columns(s.exp)))
        if s.measures:
            parts.append(_html_table(s.measures, MEASUREMENT_COLUMNS))
        if s.claims:
            parts.append("<p>What the paper reports:</p><ul>" + "".join(
                f"<li>{html.escape(c['text'])} ({html.escape(c['figure'])})</li>" for c in s.claims) + "</ul>")
        mine = [v for v in videos if s.exp.path in v.parents]
        parts += [_video_tag(root, v) for v in mine]
    loose = [v for v in videos if not any(s.exp.path in v.parents for s in sections)]
    if loose:
        parts.append("<h2>Videos</h2>" + "".join(_video_tag(root, v) for v in loose))
    parts.append("</body></html>")
    return atomic_text(root / "index.html", "\n".join(parts))


def _video_tag(root: Path, video: Path) -> str:
    """A captioned <video> with a WebM copy (plays in browsers) and the original MP4."""
    rel = video.relative_to(root).as_posix()
    web = web_copy(video, root / "figures" / "videos", root)
    sources = (f"<source src='{html.escape(web.relative_to(root).as_posix())}' type='video/webm'>" if web else "")
    sources += f"<source src='{html.escape(rel)}' type='video/mp4'>"
    caption = html.escape(str(Path(rel).parent) if video.name == "video.mp4" else rel)
    return (f"<figure><video controls loop muted>{sources}</video>"
            f"<figcaption>{caption} (<a href='{html.escape(rel)}'>mp4</a>)</figcaption></figure>")


def make_report(root: str | Path, videos: bool | None = None) -> list[Path]:
    """Write the figures, ``report.md`` and ``index.html`` for the results under ``root``; return their paths.

    ``videos``: True renders missing rollout videos for every finished run, False for none, None only
    for experiments that ask for them (the headline experiment).
    """
    root = Path(root).resolve()
    if not root.is_dir():
        raise FileNotFoundError(f"no results directory {root}")
    for name in ("figures", "report.md", "index.html"):
        if (root / name).is_symlink():
            raise ReportError(f"{root / name} is a symbolic link; the report writes only inside {root}: remove it")
    sections = build_sections(root, videos)
    if not sections:
        raise FileNotFoundError(f"{root} holds no experiment results ({EXPERIMENT_FILE} not found in it or in its "
                                f"subdirectories); run `ecorl run EXPERIMENT --out {root}` first")
    md = write_markdown(root, sections)
    page = write_html(root, sections, find_videos(root))
    written = [p for s in sections for p in ([s.curves] if s.curves else []) + s.heatmaps]
    return [*written, md, page]
