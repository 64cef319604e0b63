"""The report's figures: learning curves per task and visitation heat-maps, written as PNG atomically.

Every figure of a report gives a condition the same colour (`report_colors`: keyed by the condition's name
and distinct within the report; one per arm where the curves have a panel per setting), and a figure's bytes
depend only on what it shows (no date or software version in the file).
"""

from __future__ import annotations

import math
import textwrap
import zlib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from train.experiments.report.paper import paper_value
from train.experiments.report.runs import ExperimentResults, Run
from train.experiments.report.stats import CI_LEVEL, COLLAPSE_SHARE, bootstrap_ci
from train.storage.fileio import atomic_file
from train.storage.rundir import read_visits

MAX_SEED_LINES = 100
"""Most seeds of a condition drawn as lines of their own (every seed enters the mean and its interval)."""
HEATMAP_POINTS = 4
"""Points of training shown in each heat-map row (the paper's Fig. 9-10 show four)."""

CONDITION_COLORS = {"static-episodic": "#1f77b4", "static-reset-free": "#d62728",
                    "dynamic-episodic": "#2ca02c", "dynamic-reset-free": "#ff7f0e"}
"""The colour of each condition of the headline experiments in every figure and page (static non-episodic
red: the condition the paper finds fails)."""

OTHER_COLORS = ("#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#393b79", "#637939",
                "#000000", "#98df8a", "#7b4173", "#3182bd")
"""Colours of other conditions, chosen by a stable hash of the condition's name (see `condition_colors`)."""

PNG_METADATA = {"Software": None}
"""PNG metadata of every figure: none (matplotlib would otherwise write its version)."""
LEGEND_INCHES_PER_CHAR = 0.065
"""About how wide a character of the legend's 9-point text is: the legend takes as many columns as its
longest label leaves room for, so no label runs off the figure."""


def condition_colors(names: Iterable[str]) -> dict[str, str]:
    """The colour of each condition of one report: the headline conditions' own (`CONDITION_COLORS`), the
    others the colour their name hashes to, or where an earlier name (in sorted order) has it, the next one
    of `OTHER_COLORS` still free. So a condition keeps its colour wherever it appears beside no condition
    whose colour it shares, and no two conditions of a report share one while colours are left.
    """
    names = sorted(set(names))
    colors = {n: CONDITION_COLORS[n] for n in names if n in CONDITION_COLORS}
    for name in (n for n in names if n not in colors):
        start = zlib.crc32(name.encode()) % len(OTHER_COLORS)
        ring = [OTHER_COLORS[(start + i) % len(OTHER_COLORS)] for i in range(len(OTHER_COLORS))]
        colors[name] = next((c for c in ring if c not in colors.values()), ring[0])
    return colors


SETTING_SUFFIXES = ("-reset-free", "-episodic")
"""The endings of the names of one arm's conditions in an experiment with a panel per setting (``walls``)."""
ARM_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f")
"""The arms' colours in an experiment with a panel per setting, in the order of its conditions."""


def report_colors(exp: ExperimentResults) -> dict[str, str]:
    """The colour of each condition of an experiment's figures (`condition_colors`); where its curves have a
    panel per setting, each arm's (conditions named alike but for `SETTING_SUFFIXES`) from `ARM_COLORS` in the
    experiment's order, so the two panels read alike.
    """
    if not exp.info.get("panel_per_setting"):
        return condition_colors(r.condition for r in exp.runs)
    listed = [c["name"] for conds in exp.info.get("tasks", {}).values() for c in conds]
    arms: dict[str, str] = {}
    for name in listed + sorted({r.condition for r in exp.runs} - set(listed)):
        arm = name
        for suffix in SETTING_SUFFIXES:
            arm = arm.removesuffix(suffix)
        arms[name] = arm
    order = list(dict.fromkeys(arms.values()))
    return {name: ARM_COLORS[order.index(arm) % len(ARM_COLORS)] for name, arm in arms.items()}


def condition_color(name: str) -> str:
    """The colour of condition ``name`` shown alone (`condition_colors` of it alone)."""
    return condition_colors([name])[name]


def pyplot():
    """Matplotlib's pyplot on the headless Agg backend (imported on first use)."""
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
    """One panel per task (or per task and setting, `curve_panels`): mean and 95% CI over seeds of every
    condition, each seed as a thin line; the paper's values dotted; the same conditions of a ``reference``
    experiment (shipped paper-budget runs) dashed, so a short run shows where its curves are heading.
    """
    panels = curve_panels(exp)
    if not panels:
        return None
    plt = pyplot()
    ncols = min(len(panels), 5)
    nrows = math.ceil(len(panels) / ncols)
    width = max(4.2 * ncols, 7.5)
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, 3.4 * nrows + 1.2), squeeze=False,
                             layout="constrained")
    color_of = report_colors(exp)
    labels = {r.condition: set() for r in exp.runs}
    for r in exp.runs:
        labels[r.condition].add(r.label)
    # one legend below the panels where every condition has one label and the panels split no task's
    # conditions; else each panel gets its own
    shared_legend = all(len(v) == 1 for v in labels.values()) and len(panels) == len({t for t, _, _ in panels})
    handles: dict[str, Any] = {}
    has_paper = False
    for ax, (_, title, runs) in zip(axes.flat, panels):
        for run in runs:
            line, quoted = _draw_run(ax, run, color_of[run.condition], paper, reference)
            handles.setdefault(run.label, line)
            has_paper = has_paper or quoted
        _style_panel(ax, title, runs[0].metric, own_legend=not shared_legend)
        if reference is not None:  # the live steps fill the panel; the shipped runs are drawn in full elsewhere
            ax.set_xlim(0, max(int(r.steps[-1]) for r in runs) * 1.03)
    for ax in list(axes.flat)[len(panels):]:
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
        longest = max(len(label) for label in handles) * LEGEND_INCHES_PER_CHAR + 0.6  # text and its line
        legend_cols = max(1, min(len(handles), int(width // max(3.6, longest))))
        fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncol=legend_cols,
                   frameon=False, fontsize=9)
    seeds = sorted({r.seeds for r in exp.runs})
    title = (f"{exp.info.get('paper', '')}: {exp.info.get('title', exp.name)} (mean and {CI_LEVEL:.0%} bootstrap "
             f"CI over {'/'.join(map(str, seeds))} seeds; thin lines: single seeds)")
    fig.suptitle(textwrap.fill(title, int(width * 11)), fontsize=11)
    save_figure(fig, out, dpi=110)
    return out


def plot_collapse(exp: ExperimentResults, out: Path) -> Path | None:
    """One panel per curve panel: each condition's greedy top-action share over training (mean and 95% CI over
    seeds, each seed thin), with the collapse threshold dashed; None when no run records the share.
    """
    panels = [(title, [r for r in runs if not np.isnan(r.top_share).all() and r.top_share.shape == r.values.shape])
              for _, title, runs in curve_panels(exp)]
    panels = [(title, runs) for title, runs in panels if runs]
    if not panels:
        return None
    plt = pyplot()
    ncols = min(len(panels), 5)
    nrows = math.ceil(len(panels) / ncols)
    width = max(4.2 * ncols, 7.5)
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, 3.0 * nrows + 1.0), squeeze=False, layout="constrained")
    color_of = report_colors(exp)
    for ax, (title, runs) in zip(axes.flat, panels):
        for run in runs:
            color = color_of[run.condition]
            mean, low, high = bootstrap_ci(np.nan_to_num(run.top_share, nan=0.0))
            ax.plot(run.steps, run.top_share[:, :MAX_SEED_LINES], color=color, lw=0.5, alpha=0.35)
            ax.plot(run.steps, mean, color=color, lw=1.6, label=run.label, marker=point_marker(run.steps))
            ax.fill_between(run.steps, low, high, color=color, alpha=0.2, lw=0)
        ax.axhline(COLLAPSE_SHARE, color="gray", ls="--", lw=1.0)
        ax.set_title(title)
        ax.set_xlabel("environment steps")
        ax.set_ylabel("greedy top-action share")
        ax.set_ylim(0.0, 1.02)
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, frameon=False, loc="upper left")
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    title = (f"{exp.info.get('paper', '')}: how often the greedy policy picks its most frequent action on the "
             f"validation rollouts (dashed: {COLLAPSE_SHARE:.0%}, above it a seed counts as collapsed)")
    fig.suptitle(textwrap.fill(title, int(width * 11)), fontsize=10)
    save_figure(fig, out, dpi=100)
    return out


def curve_panels(exp: ExperimentResults) -> list[tuple[str, str, list[Run]]]:
    """(task, title, runs) of each panel of the curves, in panel order: one per task with results, or where
    the experiment asks for it (``panel_per_setting``), one per task and setting, non-episodic first.
    """
    panels = []
    for task in exp.tasks:
        runs = [r for r in exp.runs if r.task == task]
        if not runs:
            continue
        if not exp.info.get("panel_per_setting"):
            panels.append((task, task, runs))
            continue
        resets = {c["name"]: bool(c["overrides"].get("reset_free", False))  # the config's default: episodic
                  for c in exp.info.get("tasks", {}).get(task, [])}
        for reset_free, setting in ((True, "non-episodic"), (False, "episodic")):
            chosen = [r for r in runs if resets.get(r.condition, False) == reset_free]
            if chosen:
                panels.append((task, f"{task}, {setting}", chosen))
    return panels


def point_marker(steps) -> str | None:
    """A marker for a curve of one evaluation (a line through one point draws nothing), else none."""
    return "o" if len(steps) < 2 else None


def _draw_run(ax, run: Run, color: str, paper: dict, reference: ExperimentResults | None) -> tuple[Any, bool]:
    """One condition in a panel: each seed thin, the mean and its CI, the reference's mean dashed, the paper's
    value dotted; returns the mean's line and whether the paper's value was drawn.
    """
    mean, low, high = bootstrap_ci(run.values)
    ax.plot(run.steps, run.values[:, :MAX_SEED_LINES], color=color, lw=0.5, alpha=0.35)  # each seed: bimodality
    (line,) = ax.plot(run.steps, mean, color=color, lw=1.6, label=run.label, marker=point_marker(run.steps))
    ax.fill_between(run.steps, low, high, color=color, alpha=0.2, lw=0)
    for old in (reference.runs if reference else []):
        if old.task == run.task and old.condition == run.condition:
            ax.plot(old.steps, bootstrap_ci(old.values)[0], color=color, lw=1.2, ls="--")
    ref = paper_value(paper, run.task, run.condition)
    if ref is not None:
        ax.axhline(ref["value"], color=color, ls=":", lw=1.3)
    return line, ref is not None


def _style_panel(ax, title: str, metric: str, own_legend: bool) -> None:
    """Title, axis labels and limits, grid and (when conditions are labelled per panel) a legend of one panel."""
    ax.set_title(title)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("fraction of validation tasks solved" if metric == "success" else "mean validation return")
    if metric == "success":
        ax.set_ylim(-0.03, 1.03)
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
    ax.grid(alpha=0.3)
    if own_legend:
        ax.legend(fontsize=7, frameon=False, loc="upper left")


def save_figure(fig, out: Path, dpi: int) -> None:
    """Write a figure as PNG atomically and close it."""
    try:
        with atomic_file(out) as f:
            fig.savefig(f, format="png", dpi=dpi, metadata=PNG_METADATA)
    finally:
        pyplot().close(fig)


def heatmap_snapshot_files(run_dir: Path, points: int = HEATMAP_POINTS) -> list[Path]:
    """The up to ``points`` evenly spaced files of ``run_dir/visits/`` that the heat-maps draw, oldest first.
    Picking again among only these files picks the same ones, so a shipped run may keep just them.
    """
    files = sorted((run_dir / "visits").glob("*.npy"), key=lambda p: int(p.stem))
    if not files:
        return []
    picks = sorted(set(np.round(np.linspace(0, len(files) - 1, points)).astype(int)))
    return [files[i] for i in picks]


def visit_snapshots(run_dir: Path, points: int = HEATMAP_POINTS) -> list[tuple[int, np.ndarray]]:
    """Up to ``points`` evenly spaced (step, counts summed over seeds) snapshots of a run's visitation."""
    return [(int(f.stem), read_visits(f).sum(0)) for f in heatmap_snapshot_files(run_dir, points)]


def plot_heatmaps(exp: ExperimentResults, task: str, out: Path) -> Path | None:
    """Rows: conditions; columns: four points of training; the share of all visits so far in each cell
    (summed over seeds), on one colour scale per row with its colour bar.
    """
    rows = [(r, visit_snapshots(r.path)) for r in exp.runs if r.task == task]
    rows = [(r, snaps) for r, snaps in rows if snaps]
    if not rows:
        return None
    color_of = report_colors(exp)  # as in the report's curves
    plt = pyplot()
    ncols = max(len(s) for _, s in rows)
    width = 2.3 * ncols + 3.2
    fig, axes = plt.subplots(len(rows), ncols, figsize=(width, 2.3 * len(rows) + 0.8), squeeze=False,
                             layout="constrained")
    for (run, snaps), axrow in zip(rows, axes):
        shares = [counts / max(counts.sum(), 1) for _, counts in snaps]
        top = max(float(x.max()) for x in shares) or 1.0
        for ax, (step, _), share in zip(axrow, snaps, shares):
            image = ax.imshow(share, cmap="viridis", interpolation="nearest", vmin=0.0, vmax=top)
            ax.set_title(f"step {step:,}", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
        axrow[0].set_ylabel(textwrap.fill(run.label, 24), fontsize=8, color=color_of[run.condition])
        for ax in axrow[len(snaps):]:
            ax.set_visible(False)
        bar = fig.colorbar(image, ax=list(axrow[:len(snaps)]), shrink=0.85, pad=0.02)
        bar.set_label("share of visits", fontsize=7)
        bar.ax.tick_params(labelsize=7)
    title = (f"{exp.info.get('paper', '')}: where the agent was on {task} (share of all visits so far per cell, "
             f"summed over seeds; one colour scale per row)")
    fig.suptitle(textwrap.fill(title, int(width * 13)), fontsize=9)
    save_figure(fig, out, dpi=100)
    return out


def plot_seed_curves(exp: ExperimentResults, out: Path) -> Path | None:
    """A single run's learning curve per seed (each its own line, its last value in the legend), the mean
    in the condition's colour.
    """
    if not exp.runs:
        return None
    run = exp.runs[0]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.6), layout="constrained")
    cmap = plt.get_cmap("tab10")
    first = int(exp.info.get("first_seed", 0))
    scale = 100.0 if run.metric == "success" else 1.0
    for k in range(run.seeds):
        last = run.values[-1, k] * scale
        ax.plot(run.steps, run.values[:, k], color=cmap(k % 10), lw=1.0, alpha=0.8, marker=point_marker(run.steps),
                label=f"seed {first + k}: {last:.0f}{'%' if run.metric == 'success' else ''} at the end")
    ax.plot(run.steps, run.values.mean(1), color=condition_color(run.condition), lw=2.4, label="mean over seeds")
    _style_panel(ax, run.task, run.metric, own_legend=False)
    ax.legend(fontsize=8, frameon=False, loc="upper left", ncol=2 if run.seeds > 5 else 1)
    fig.suptitle(textwrap.fill(exp.info.get("title", exp.name), 90), fontsize=10)
    save_figure(fig, out, dpi=110)
    return out
