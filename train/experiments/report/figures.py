"""The report's figures: learning curves per task and visitation heat-maps, written as PNG atomically."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from train.experiments.report.paper import paper_value
from train.experiments.report.runs import ExperimentResults, Run
from train.experiments.report.stats import CI_LEVEL, bootstrap_ci
from train.fileio import atomic_file

HEATMAP_POINTS = 4
"""Points of training shown in each heat-map row (the paper's Fig. 9-10 show four)."""


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def reference_label(reference: ExperimentResults) -> str:
    """The legend entry of a reference experiment's dashed curves: its seeds and steps."""
    seeds = sorted({r.seeds for r in reference.runs})
    steps = max(int(r.steps[-1]) for r in reference.runs)
    return f"shipped run, {'/'.join(map(str, seeds))} seeds × {steps / 1e6:.2g} M steps (dashed)"


def plot_curves(exp: ExperimentResults, paper: dict, out: Path,
                reference: ExperimentResults | None = None) -> Path | None:
    """One panel per task: mean and 95% CI over seeds of every condition, each seed as a thin line; the
    paper's values dotted; the same conditions of a ``reference`` experiment (shipped paper-budget runs)
    dashed, so a short run shows where its curves are heading.
    """
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
            line, quoted = _draw_run(ax, run, color_of[run.condition], paper, reference)
            handles.setdefault(run.label, line)
            has_paper = has_paper or quoted
        _style_panel(ax, task, runs[0].metric, own_legend=not shared_legend)
    for ax in list(axes.flat)[len(tasks):]:
        ax.set_visible(False)
    if not shared_legend:
        handles = {}
    if has_paper:
        from matplotlib.lines import Line2D

        handles["paper's final value (dotted; ≈, quoted in its text)"] = Line2D([], [], color="gray", ls=":")
    if reference is not None:
        from matplotlib.lines import Line2D

        handles[reference_label(reference)] = Line2D([], [], color="gray", ls="--")
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


def _draw_run(ax, run: Run, color: str, paper: dict, reference: ExperimentResults | None) -> tuple[Any, bool]:
    """One condition in a panel: each seed thin, the mean and its CI, the reference's mean dashed, the paper's
    value dotted; returns the mean's line and whether the paper's value was drawn.
    """
    mean, low, high = bootstrap_ci(run.values)
    ax.plot(run.steps, run.values, color=color, lw=0.5, alpha=0.35)  # each seed: the bimodality
    (line,) = ax.plot(run.steps, mean, color=color, lw=1.6, label=run.label)
    ax.fill_between(run.steps, low, high, color=color, alpha=0.2, lw=0)
    for old in (reference.runs if reference else []):
        if old.task == run.task and old.condition == run.condition:
            ax.plot(old.steps, bootstrap_ci(old.values)[0], color=color, lw=1.2, ls="--")
    ref = paper_value(paper, run.task, run.condition)
    if ref is not None:
        ax.axhline(ref["value"], color=color, ls=":", lw=1.3)
    return line, ref is not None


def _style_panel(ax, task: str, metric: str, own_legend: bool) -> None:
    """Title, axis labels and limits, grid and (when conditions are labelled per task) a legend of one panel."""
    ax.set_title(task)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("fraction of validation tasks solved" if metric == "success" else "mean validation return")
    if metric == "success":
        ax.set_ylim(-0.03, 1.03)
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
    ax.grid(alpha=0.3)
    if own_legend:
        ax.legend(fontsize=7, frameon=False, loc="upper left")


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
