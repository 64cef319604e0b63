"""The report's pages: ``report.md`` and ``index.html`` for a results directory, and `make_report`.

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

import html
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from train.experiments.catalog import EXPERIMENTS
from train.experiments.report.figures import plot_curves, plot_heatmaps, reference_label
from train.experiments.report.paper import load_paper
from train.experiments.report.runs import (
    ExperimentResults,
    ReportError,
    find_experiment_dirs,
    load_experiment,
    load_reference,
)
from train.experiments.report.stats import BOOTSTRAP_NOTE, DIVERGED_RULE
from train.experiments.report.tables import (
    FINAL_COLUMNS,
    MEASUREMENT_COLUMNS,
    final_rows,
    measurement_rows,
    milestone_columns,
    milestone_rows,
)
from train.experiments.report.webvideo import find_videos, render_missing_videos, web_copy
from train.experiments.sweep import EXPERIMENT_FILE
from train.fileio import atomic_text


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


def _md_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> list[str]:
    """A markdown table of ``rows`` with (key, header) columns."""
    out = ["| " + " | ".join(h for _, h in columns) + " |", "|" + "---|" * len(columns)]
    out += ["| " + " | ".join(str(r[k]) for k, _ in columns) + " |" for r in rows]
    return out


def write_markdown(root: Path, sections: Sequence[Section]) -> Path:
    """``report.md``: per experiment its figures, final results beside the paper's, and the paper's claims."""
    lines = [f"# ecorl report: `{_shown(root)}`", "",
             "Success = fraction of the 100 fixed validation layouts of the test MDP solved (food collector: mean "
             "return over validation episodes), at the last evaluation; mean over seeds with a 95% confidence "
             f"interval ({BOOTSTRAP_NOTE}). Seeds diverged: {DIVERGED_RULE}. Paper column: **≈** a value read "
             "from a figure or quoted in the paper's text (approximate), **=** a value from a table (exact), — "
             "the paper reports no number.", ""]
    for s in sections:
        info = s.exp.info
        lines += [f"## {s.exp.name} ({info.get('paper', '')}): {info.get('title', '')}", "",
                  info.get("description", ""), "", _budget_line(s.exp), ""]
        if s.curves:
            lines += [f"![learning curves]({s.curves.relative_to(root).as_posix()})", ""]
        if s.curves and s.reference:
            lines += [f"Dashed: the mean of the {reference_label(s.reference).replace(' (dashed)', '')} shipped in "
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
             "also as <a href='report.md'>report.md</a>. Intervals: 95%, " + html.escape(BOOTSTRAP_NOTE) + ". "
             "Seeds diverged: " + html.escape(DIVERGED_RULE) + ". Paper column: ≈ approximate (figure or text), "
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
