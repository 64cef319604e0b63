"""What a page shows first: the shipped paper-budget runs of its experiment, re-drawn, with their numbers.

A quick or time-boxed run shows only the first part of the paper's curves; the page of the headline
experiments therefore leads with the shipped 10-seed x 1 M-step panels (``docs/results/paper``) and one
sentence of the claim: static non-episodic fails, dynamic non-episodic learns.
"""

from __future__ import annotations

import html
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from train.experiments.report import runs
from train.experiments.report.figures import condition_colors, plot_curves, pyplot, save_figure
from train.experiments.report.runs import ExperimentResults, Run, load_experiment
from train.experiments.report.stats import LEARNED, bootstrap_ci, summarize
from train.experiments.report.tables import FINAL_COLUMNS, final_rows
from train.storage.rundir import EXPERIMENT_FILE

LEAD = {"headline": ("headline", "headline-waypoint"), "headline-waypoint": ("headline-waypoint", "headline")}
"""Experiment -> the shipped experiments its page leads with: its own first (drawn with the live runs on it)."""

CONTRAST = ("static-reset-free", "dynamic-reset-free")
"""The two conditions of the paper's claim: without resets, a static world fails and a dynamic one learns."""


@dataclass
class Lead:
    """A shipped experiment as the page's lead shows it."""

    exp: ExperimentResults
    figure: Path
    rows: list[dict[str, Any]]
    sentence: str


def source_name(path: Path) -> str:
    """A shipped experiment's directory as the repository names it (docs/results/paper/NAME)."""
    root = runs.REFERENCE_DIR.parents[2]
    try:
        return path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        return path.name


def contrast_sentence(exp: ExperimentResults, paper: dict) -> str:
    """'static non-episodic: 0.3% [..], 0 / 10 learned; dynamic non-episodic: ... (paper ≈ 0% and ≈ 70%)', or ''
    when the experiment lacks either condition.
    """
    from train.experiments.report.paper import paper_value

    runs = {r.condition: r for r in exp.runs}
    if not all(c in runs for c in CONTRAST):
        return ""
    parts = []
    for name in CONTRAST:
        run = runs[name]
        ours, learned = summarize(run.values[-1], run.metric)
        ref = paper_value(paper, run.task, name)
        quoted = f" (paper ≈ {ref['value']:.0%})" if ref else ""
        parts.append(f"{name.replace('-reset-free', ' non-episodic')}: {ours}, {learned} seeds learned{quoted}")
    step = int(max(runs[c].steps[-1] for c in CONTRAST))
    return f"At {step:,} steps, " + "; ".join(parts) + f" (learned: > {LEARNED:.0%} of the layouts solved)."


def build_leads(names: list[str], out: Path, paper_all: dict,
                live: list[ExperimentResults] | None = None) -> list[Lead]:
    """Re-draw the shipped experiments ``names`` (those shipped with runs) into ``out/figures``; the one of the
    same name as a ``live`` experiment (the page's own runs) is drawn with the live runs' contrast on it
    (`plot_live_contrast`).
    """
    leads = []
    own = {exp.name: exp for exp in live or []}
    for name in names:
        path = runs.REFERENCE_DIR / name
        if not (path / EXPERIMENT_FILE).exists():
            continue
        exp = load_experiment(path)
        if not exp.runs:
            continue
        paper = paper_all.get(name, {})
        figure = None
        if name in own:
            figure = plot_live_contrast(exp, own[name], out / "figures" / f"live_vs_shipped_{name}.png")
        if figure is None:
            figure = plot_curves(exp, paper, out / "figures" / f"shipped_{name}_curves.png")
        if figure is not None:
            leads.append(Lead(exp, figure, final_rows(exp, paper), contrast_sentence(exp, paper)))
    return leads


def _contrast_runs(exp: ExperimentResults) -> list[Run]:
    """The experiment's `CONTRAST` runs, in that order (those it has; none when it spans several tasks)."""
    if len(exp.tasks) != 1:
        return []
    by_name = {r.condition: r for r in exp.runs}
    return [by_name[c] for c in CONTRAST if c in by_name]


def plot_live_contrast(shipped: ExperimentResults, live: ExperimentResults, out: Path) -> Path | None:
    """The `CONTRAST` pair on one axis: the shipped runs' mean and 95% CI over their whole budget, the live runs'
    (this machine's) on the same scale, each curve labelled at its end with its final value and interval. None
    when either side lacks the pair.
    """
    ours, theirs = _contrast_runs(live), _contrast_runs(shipped)
    if len(ours) != len(CONTRAST) or len(theirs) != len(CONTRAST):
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 5.2), layout="constrained")
    colors = condition_colors(CONTRAST)
    labels = []
    for index, (run, kind) in enumerate([(r, "shipped") for r in theirs] + [(r, "live") for r in ours]):
        mean, low, high = bootstrap_ci(run.values)
        color = colors[run.condition]
        style = {"shipped": dict(lw=1.4, ls="--", alpha=0.9), "live": dict(lw=2.6, ls="-", alpha=1.0)}[kind]
        ax.plot(run.steps, mean, color=color, **style)
        ax.fill_between(run.steps, low, high, color=color, alpha=0.12 if kind == "shipped" else 0.25, lw=0)
        text, _ = summarize(run.values[-1], run.metric)
        label = (f"{run.condition.replace('-reset-free', ' non-episodic')}, {kind} "
                 f"({run.seeds} seeds): {text}")
        box = dict(boxstyle="round,pad=0.25", fc="white", ec=color, alpha=0.9) if kind == "live" else None
        rise = (-12 if index % 2 == 0 else 14) if kind == "live" else 0  # the two live labels apart, even at 0
        labels.append(ax.annotate(label, (run.steps[-1], mean[-1]), xytext=(8, rise),
                                  textcoords="offset points", color=color, fontsize=8.5, va="center", bbox=box,
                                  fontweight="bold" if kind == "live" else "normal"))
    ax.set_xlim(0, max(int(r.steps[-1]) for r in theirs) * 1.6)
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("fraction of validation tasks solved")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
    ax.grid(alpha=0.3)
    steps = max(int(r.steps[-1]) for r in ours)
    ax.set_title(textwrap.fill(f"{shipped.info.get('title', shipped.name)}: your live runs (solid, to {steps:,} "
                               f"steps) on the shipped 10-seed runs (dashed); mean and 95% CI", 110), fontsize=10)
    keep_apart(fig, labels)
    save_figure(fig, out, dpi=110)
    return out


def keep_apart(fig, labels: list) -> None:
    """Move each label (an annotation placed in offset points) up or down, a line at a time, to the nearest place
    where its box overlaps none of the labels before it: those keep theirs. A live run that ends halfway had its
    label drawn over the shipped run's at the end of the axis.
    """
    fig.canvas.draw()  # the layout settles first, so that the boxes are where they will be saved
    renderer = fig.canvas.get_renderer()
    placed = []
    for text in labels:
        x, y = text.xyann
        line = text.get_tightbbox(renderer).height * 72 / fig.dpi + 1  # points
        for shift in (0, 1, -1, 2, -2, 3, -3, 4, -4):
            text.xyann = (x, y + shift * line)
            box = text.get_tightbbox(renderer)
            if not any(box.overlaps(other) for other in placed):
                break
        placed.append(text.get_tightbbox(renderer))


def separation_sentence(exp: ExperimentResults) -> str:
    """Whether the `CONTRAST` pair's final intervals separate, in words ('' without the pair)."""
    pair = _contrast_runs(exp)
    if len(pair) != len(CONTRAST):
        return ""
    (static, dynamic) = pair
    _, s_low, s_high = bootstrap_ci(static.values[-1])
    _, d_low, d_high = bootstrap_ci(dynamic.values[-1])
    if d_low > s_high:
        verdict = "the intervals separate: dynamic above static"
    elif s_low > d_high:
        verdict = "the intervals separate: static above dynamic"
    else:
        verdict = "the intervals overlap: this run cannot tell the two apart yet"
    step = int(max(r.steps[-1] for r in pair))
    return f"At {step:,} steps {verdict}."


def lead_names(experiments: list[str], source: Path) -> list[str]:
    """The shipped experiments a page of ``experiments`` leads with (none when it re-draws the shipped ones)."""
    try:
        source.resolve().relative_to(runs.REFERENCE_DIR.resolve())
        return []
    except ValueError:
        pass
    return list(dict.fromkeys(n for e in experiments for n in LEAD.get(e, ())))


def missing_shipped_note(experiments: list[str], source: Path) -> str:
    """One sentence when a page of ``experiments`` would lead with shipped runs that this installation lacks (a
    wheel carries the code and the paper's numbers, not ``docs/results/paper``); else ''.
    """
    if runs.REFERENCE_DIR.is_dir() or not lead_names(experiments, source):
        return ""
    return ("The shipped paper-budget runs this page leads with (docs/results/paper/) come with the source "
            "repository, not with a pip installation: run from a clone to see your runs beside them.")


def lead_markdown(leads: list[Lead], out: Path, table) -> list[str]:
    """The lead as markdown lines (``table(rows, columns)`` makes a table)."""
    if not leads:
        return []
    lines = ["## At the paper's budget (shipped runs, 10 seeds x 1 M steps)", ""]
    for lead in leads:
        info = lead.exp.info
        lines += [f"### {lead.exp.name}: {info.get('title', '')}", ""]
        if lead.sentence:
            lines += [f"**{lead.sentence}**", ""]
        lines += [f"![{lead.exp.name} at the paper's budget]({lead.figure.relative_to(out).as_posix()})", ""]
        lines += table(lead.rows, FINAL_COLUMNS) + ["", f"Source: `{source_name(lead.exp.path)}`.", ""]
    return lines


def lead_html(leads: list[Lead], out: Path, table) -> str:
    """The lead as HTML (``table(rows, columns)`` makes a table)."""
    if not leads:
        return ""
    parts = ["<section class='lead'><h2>At the paper's budget (shipped runs, 10 seeds × 1 M steps)</h2>"]
    for lead in leads:
        info = lead.exp.info
        parts.append(f"<h3>{html.escape(lead.exp.name)}: {html.escape(info.get('title', ''))}</h3>")
        if lead.sentence:
            parts.append(f"<p class='claim'><b>{html.escape(lead.sentence)}</b></p>")
        parts.append(f"<p><img src='{html.escape(lead.figure.relative_to(out).as_posix())}' "
                     f"alt='{html.escape(lead.exp.name)} at the paper budget'></p>")
        parts.append(table(lead.rows, FINAL_COLUMNS))
        parts.append(f"<p>Source: <code>{html.escape(source_name(lead.exp.path))}</code></p>")
    return "".join(parts) + "</section>"


def run_summary(path: Path) -> list[str]:
    """Lines that sum up an experiment directory: each condition's last evaluation (named with its task
    when the directory holds several) and, for the headline experiments, the claim at the paper's budget from
    the shipped runs.
    """
    from train.experiments.report.paper import load_paper

    exp = load_experiment(path)
    lines = [f"{exp.name}, this run:"]
    several_tasks = len(exp.tasks) > 1
    for run in exp.runs:
        ours, learned = summarize(run.values[-1], run.metric)
        name = f"{run.task}, {run.label}" if several_tasks else run.label
        lines.append(f"  {name}: {ours} at {int(run.steps[-1]):,} steps, {learned} seeds learned")
    separation = separation_sentence(exp)
    if separation:
        lines.append(f"  {separation}")
    paper_all = load_paper()
    for name in lead_names([exp.name], path):
        shipped = runs.REFERENCE_DIR / name
        if (shipped / EXPERIMENT_FILE).exists():
            sentence = contrast_sentence(load_experiment(shipped), paper_all.get(name, {}))
            if sentence:
                lines.append(f"{name} at the paper's budget (shipped, 10 seeds, the decisive runs: "
                             f"{source_name(shipped)}): {sentence}")
    note = missing_shipped_note([exp.name], path)
    return [*lines, note] if note else lines
