"""The report's pages: ``report.md`` and ``index.html`` for a results directory, and `make_report`.

``make_report(DIR)`` reads every experiment directory under DIR (or DIR itself) written by `train.experiments.sweep`
and writes into DIR:

* ``figures/<experiment>_curves.png``: learning curves, one panel per task (Fig. 8: per setting), mean and 95%
  bootstrap CI over seeds against environment steps, the paper's reported values as dotted lines;
* ``figures/<experiment>_<task>_heatmaps.png``: cumulative visitation counts (summed over seeds) at four
  points of training, for experiments that ask for them (Fig. 2, 9, 10); a second directory of the same
  experiment in one report names its figures after itself (`figure_stems`);
* ``report.md``: final success (or return) per condition, mean ± 95% CI over seeds at the last
  evaluation, beside the paper's numbers (``train/data/paper/*.json``; ≈ marks values read from a figure or
  quoted in the text, = values from a table), and Table 1 measurements;
* ``index.html``: all of it on one static page, with the rollout videos found in the run directories
  (``video.mp4``) or in DIR, re-encoded to WebM so that browsers play them.
"""

from __future__ import annotations

import html
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ecology import NUM_VALIDATION_LAYOUTS
from train.experiments.catalog import EXPERIMENTS
from train.experiments.report.figures import (
    plot_collapse,
    plot_curves,
    plot_heatmaps,
    plot_seed_curves,
    reference_label,
)
from train.experiments.report.lead import (
    Lead,
    build_leads,
    lead_html,
    lead_markdown,
    lead_names,
    missing_shipped_note,
    separation_sentence,
    source_name,
)
from train.experiments.report.paper import load_paper
from train.experiments.report.runs import (
    REFERENCE_DIR,
    ExperimentResults,
    ReportError,
    evaluation_size,
    find_experiment_dirs,
    is_run_dir,
    load_experiment,
    load_reference,
    load_single_run,
    reportable_below,
    stopped_before_evaluating,
)
from train.experiments.report.stats import BOOTSTRAP_NOTE, COLLAPSED_RULE, DIVERGED_RULE
from train.experiments.report.tables import (
    FINAL_COLUMNS,
    MEASUREMENT_COLUMNS,
    final_rows,
    measurement_rows,
    milestone_columns,
    milestone_rows,
)
from train.experiments.report.webvideo import (
    WebVideo,
    caption_of,
    find_videos,
    render_missing_videos,
    video_tag,
    web_copy,
)
from train.storage.fileio import atomic_text
from train.storage.rundir import EXPERIMENT_FILE
from train.storage.safeio import no_link_below
from train.tasks import TASKS


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
    collapse: Path | None = None
    """The greedy top-action share over training (`plot_collapse`), where the runs record it."""


def load_all(source: Path) -> list[ExperimentResults]:
    """The experiments under ``source``: one single-run experiment for an ``ecorl train`` run directory."""
    if is_run_dir(source):
        return [load_single_run(source)]
    return [load_experiment(path) for path in find_experiment_dirs(source)]


def figure_stems(experiments: Sequence[ExperimentResults]) -> list[str]:
    """The name each experiment's figures start with: the experiment's own, or where an earlier directory of
    the report already has it (say a run continued in ``settings-1m`` beside ``settings``), the directory's
    name, numbered if that is taken too, so no figure overwrites another.
    """
    stems: list[str] = []
    for exp in experiments:
        stem = exp.name if exp.name not in stems else exp.path.name
        number = 2
        while stem in stems:
            stem, number = f"{exp.name}-{number}", number + 1
        stems.append(stem)
    return stems


def build_sections(source: Path, out: Path, videos: bool | None = None) -> list[Section]:
    """Read every experiment under ``source``, draw its figures into ``out/figures`` and compute its tables."""
    paper_all = load_paper()
    sections = []
    experiments = load_all(source)
    for exp, stem in zip(experiments, figure_stems(experiments), strict=True):
        paper = paper_all.get(exp.name, {})
        if videos or (videos is None and exp.info.get("videos")):
            render_missing_videos(exp, source)
        figures = out / "figures"
        single = exp.info.get("budget") == "ecorl train"
        reference = None if single else load_reference(exp)
        curves = (plot_seed_curves(exp, figures / f"{stem}_curves.png") if single
                  else plot_curves(exp, paper, figures / f"{stem}_curves.png", reference))
        collapse = plot_collapse(exp, figures / f"{stem}_collapse.png")
        heatmaps = []
        if exp.info.get("heatmaps"):
            heatmaps = [p for t in exp.tasks if (p := plot_heatmaps(exp, t, figures / f"{stem}_{t}_heatmaps.png"))]
        tasks_run = set(exp.tasks)
        claims = [c for c in paper.get("claims", []) if c.get("task") in (None, *tasks_run)]
        sections.append(Section(exp, curves, heatmaps, final_rows(exp, paper), measurement_rows(exp, paper),
                                claims, paper.get("sources", []), milestone_rows(exp), reference, collapse))
    return sections


def _shown(path: Path) -> str:
    """How a page names a directory: relative to the working directory or to the repository when inside
    them, else by its name alone (a page names no absolute path, so it reads the same on every machine).
    """
    path = Path(path).resolve()
    for base in (Path.cwd().resolve(), REFERENCE_DIR.parents[2].resolve()):
        try:
            return path.relative_to(base).as_posix() or "."
        except ValueError:
            continue
    return path.name


def _budget_line(exp: ExperimentResults) -> str:
    """The budget, the seeds and steps the runs reached, and the directory."""
    known = EXPERIMENTS.get(exp.name)
    budget = exp.info.get("budget", "?")
    paper_seeds = f"; the paper's budget is {known.paper_seeds} seeds" if known else ""
    seeds = "/".join(map(str, sorted({r.seeds for r in exp.runs})))
    reached = f" ({seeds} seeds, up to {max(int(r.steps[-1]) for r in exp.runs):,} steps)" if exp.runs else ""
    return f"Budget: `{budget}`{reached}{paper_seeds}. Directory: `{_shown(exp.path)}`."


def _unevaluated_line(exp: ExperimentResults) -> str:
    """The sentence naming the conditions that have no evaluation yet ('' when there are none)."""
    if not exp.unevaluated:
        return ""
    return (f"Not evaluated yet, so not shown: {', '.join(sorted(exp.unevaluated))}; re-run the same command to "
            f"train them.")


def _md_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> list[str]:
    """A markdown table of ``rows`` with (key, header) columns."""
    out = ["| " + " | ".join(h for _, h in columns) + " |", "|" + "---|" * len(columns)]
    out += ["| " + " | ".join(str(r[k]) for k, _ in columns) + " |" for r in rows]
    return out


LIVE_NOTE = ("the runs of this results directory (on this machine, usually shorter and with fewer seeds than the "
             "shipped runs above, so their curves show the beginning of those).")
"""What the page says between the shipped lead and the directory's own runs."""


def _layouts(sections: Sequence[Section]) -> str:
    """How many layouts an evaluation used: 100 in the shipped runs, and what this directory's runs used."""
    sizes = sorted({n for s in sections for r in s.exp.runs
                    if r.metric == "success" and (n := evaluation_size(r.config)) is not None})
    here = (f"; this directory's runs: {' or '.join(map(str, sizes))}" if sizes and sizes != [NUM_VALIDATION_LAYOUTS]
            else "")
    return f"{NUM_VALIDATION_LAYOUTS} per evaluation at the paper's budget{here}"


def write_markdown(source: Path, out: Path, sections: Sequence[Section], leads: Sequence[Lead] = ()) -> Path:
    """``report.md``: the shipped lead, then per experiment its figures, final results beside the paper's,
    and the paper's claims.
    """
    lines = [f"# ecorl report: `{_shown(source)}`", "",
             f"Success = fraction of the fixed validation layouts of the test MDP solved ({_layouts(sections)}; "
             f"food collector: mean return over its evaluation episodes, {TASKS['foodcollector'].eval_rollouts} a "
             "seed at the paper's budget), at the "
             "last evaluation; mean over seeds with a 95% confidence "
             f"interval ({BOOTSTRAP_NOTE}). Seeds diverged: {DIVERGED_RULE}. Seeds collapsed: {COLLAPSED_RULE}. "
             "Paper column: **≈** a value read "
             "from a figure or quoted in the paper's text (approximate), **=** a value from a table (exact), — "
             "the paper reports no number.", ""]
    lines += lead_markdown(list(leads), out, _md_table)
    note = missing_shipped_note([s.exp.name for s in sections], source)
    lines += [note, ""] if note else []
    if leads:
        lines += [f"**Below: {LIVE_NOTE}**", ""]
    for s in sections:
        lines += _section_markdown(s, out)
    return atomic_text(out / "report.md", "\n".join(lines).rstrip() + "\n")


def _section_markdown(s: Section, out: Path) -> list[str]:
    """One experiment's part of report.md."""
    info = s.exp.info
    lines = [f"## {s.exp.name} ({info.get('paper', '')}): {info.get('title', '')}", "",
             info.get("description", ""), "", _budget_line(s.exp), ""]
    if separation := separation_sentence(s.exp):  # the headline pair: do this run's intervals separate yet?
        lines += [f"**{separation}**", ""]
    if s.curves:
        lines += [f"![learning curves]({s.curves.relative_to(out).as_posix()})", ""]
    if s.curves and s.reference:
        lines += [f"Dashed: the mean of the {reference_label(s.reference).replace(' (dashed)', '')} shipped in "
                  f"`{source_name(s.reference.path)}` (re-draw it with `ecorl report "
                  f"{source_name(s.reference.path)}`).", ""]
    if s.collapse:
        lines += [f"![greedy top-action share]({s.collapse.relative_to(out).as_posix()})", ""]
    for h in s.heatmaps:
        lines += [f"![visitation heat-maps]({h.relative_to(out).as_posix()})", ""]
    if s.finals:
        unfinished = [r for r in s.finals if not r["done"]]
        lines += _md_table(s.finals, FINAL_COLUMNS) + [""]
        if unfinished:
            lines += [f"{len(unfinished)} run(s) not finished yet (their latest evaluation is shown); "
                      f"re-run the same command to complete them.", ""]
    if not_yet := _unevaluated_line(s.exp):
        lines += [not_yet, ""]
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
    return lines


def _html_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for _, h in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(r[k]))}</td>" for k, _ in columns) + "</tr>"
                   for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


STYLE = ("body{font-family:sans-serif;max-width:1400px;margin:auto;padding:1em}img{max-width:100%}"
         "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;font-size:90%}"
         "video{width:300px;margin:4px;background:#000}figure{display:inline-block;margin:4px;vertical-align:top}"
         "figcaption{font-size:80%;max-width:300px}.lead{border:2px solid #888;padding:0 1em;margin:1em 0}"
         ".claim{font-size:110%}figure.strip{display:block}.strip figcaption{max-width:none}")
"""The page's style sheet."""


def write_html(source: Path, out: Path, sections: Sequence[Section], videos: Sequence[WebVideo],
               leads: Sequence[Lead] = ()) -> Path:
    """``index.html``: the report as one static page: the shipped lead, then each experiment and its videos."""
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>ecorl report</title><style>{STYLE}"
             "</style></head><body>", f"<h1>ecorl report</h1><p><code>{html.escape(_shown(source))}</code> — "
             "also as <a href='report.md'>report.md</a>. Intervals: 95%, " + html.escape(BOOTSTRAP_NOTE) + ". "
             "Seeds diverged: " + html.escape(DIVERGED_RULE) + ". Seeds collapsed: " + html.escape(COLLAPSED_RULE)
             + ". Paper column: ≈ approximate (figure or text), "
             "= exact (table).</p>", lead_html(list(leads), out, _html_table)]
    note = missing_shipped_note([s.exp.name for s in sections], source)
    if note:
        parts.append(f"<p class='claim'>{html.escape(note)}</p>")
    if leads:
        parts.append(f"<p class='claim'><b>Below: {html.escape(LIVE_NOTE)}</b></p>")
    shown = set()
    for s in sections:
        info = s.exp.info
        parts.append(f"<h2>{html.escape(s.exp.name)} ({html.escape(info.get('paper', ''))}): "
                     f"{html.escape(info.get('title', ''))}</h2><p>{html.escape(info.get('description', ''))}</p>"
                     f"<p>{html.escape(_budget_line(s.exp).replace('`', ''))}</p>")
        if separation := separation_sentence(s.exp):
            parts.append(f"<p class='claim'><b>{html.escape(separation)}</b></p>")
        for img in [f for f in (s.curves, s.collapse) if f] + s.heatmaps:
            parts.append(f"<p><img src='{html.escape(img.relative_to(out).as_posix())}' alt='{img.stem}'></p>")
        for rows, columns in ((s.finals, FINAL_COLUMNS), (s.milestones, milestone_columns(s.exp)),
                              (s.measures, MEASUREMENT_COLUMNS)):
            if rows:
                parts.append(_html_table(rows, columns))
        if not_yet := _unevaluated_line(s.exp):
            parts.append(f"<p>{html.escape(not_yet)}</p>")
        if s.claims:
            parts.append("<p>What the paper reports:</p><ul>" + "".join(
                f"<li>{html.escape(c['text'])} ({html.escape(c['figure'])})</li>" for c in s.claims) + "</ul>")
        mine = [v for v in videos if s.exp.path in v.source.parents]
        parts += [video_tag(out, v) for v in mine]
        shown.update(v.mp4 for v in mine)
    loose = [v for v in videos if v.mp4 not in shown]
    if loose:
        parts.append("<h2>Videos</h2>" + "".join(video_tag(out, v) for v in loose))
    parts.append("</body></html>")
    return atomic_text(out / "index.html", "\n".join(parts) + "\n")


def web_videos(source: Path, out: Path, sections: Sequence[Section]) -> list[WebVideo]:
    """H.264 copies (with posters and captions) in ``out/figures/videos`` of every video under ``source``;
    a caption names the video's place from its experiment's directory on (or from ``source`` for loose ones).
    """
    made = []
    for video in find_videos(source):
        if out / "figures" in video.parents:  # the report's own copies
            continue
        owner = next((s.exp.path for s in sections if s.exp.path in video.parents), None)
        name = "_".join(video.relative_to(source).with_suffix("").parts)
        try:
            web = web_copy(video, out / "figures" / "videos", name,
                           caption_of(video, owner.parent if owner else source), video)
        except (ValueError, OSError) as err:  # oversized frames, a file swapped for a FIFO: skipped, named
            print(f"ecorl report: skipped a video: {err}", file=sys.stderr)
            continue
        if web is not None:
            made.append(web)
    return made


def default_out(source: Path) -> Path:
    """Where a report of ``source`` goes unless told: ``source`` itself, except for a shipped result
    (``docs/results/paper/NAME``), which is re-drawn into ``results/report/NAME`` (tracked files stay as they are);
    for an ``ecorl train`` run directory, its ``report/`` folder.
    """
    source = Path(source).resolve()
    try:
        source.relative_to(REFERENCE_DIR.resolve())
        return Path("results") / "report" / source.name
    except ValueError:
        pass
    return source / "report" if is_run_dir(source) else source


def make_report(root: str | Path, videos: bool | None = None, out: str | Path | None = None) -> list[Path]:
    """Write the figures, ``report.md`` and ``index.html`` of the results under ``root`` into ``out`` (default:
    `default_out`); return the paths written.

    ``root`` is an experiment directory, a directory of them, or an ``ecorl train`` run directory. ``videos``:
    True films missing rollout videos for every finished run, False none, None only for experiments that ask
    for them (the headline experiments, single runs).
    """
    source = Path(root).resolve()
    if source.is_file():
        raise FileNotFoundError(f"{root} is a file; give the directory that holds it ({Path(root).parent})")
    if not source.is_dir():
        raise FileNotFoundError(f"no results directory {root}")
    target = Path(out).resolve() if out is not None else default_out(source)
    if out is None and target.is_relative_to(source):  # the default inside the tree: no link may lead out of it
        no_link_below(source, target)
    target = target.resolve()
    for name in ("figures", "report.md", "index.html"):
        if (target / name).is_symlink():
            raise ReportError(f"{target / name} is a symbolic link; the report writes only inside {target}: remove it")
    if stopped := stopped_before_evaluating(source, root):
        raise ReportError(stopped)
    sections = build_sections(source, target, videos)
    if not sections:
        inside = reportable_below(source)
        advice = (f"report one of those deeper inside it: {', '.join(str(Path(root) / p) for p in inside[:3])}"
                  f"{' ...' if len(inside) > 3 else ''}" if inside else
                  "give a directory written by `ecorl run EXPERIMENT --out DIR` or by `ecorl train`")
        raise ReportError(f"{root} is neither an experiment's results ({EXPERIMENT_FILE} not found in it or in "
                          f"the folders directly inside it) nor an ecorl train run directory (config.json and "
                          f"metrics.csv); {advice}")
    leads = build_leads(lead_names([s.exp.name for s in sections], source), target, load_paper(),
                        [s.exp for s in sections])
    md = write_markdown(source, target, sections, leads)
    page = write_html(source, target, sections, web_videos(source, target, sections), leads)
    written = [lead.figure for lead in leads]
    written += [p for s in sections for p in [f for f in (s.curves, s.collapse) if f] + s.heatmaps]
    return [*written, md, page]
