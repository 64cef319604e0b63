"""The report's tables as rows: final results beside the paper's, milestones, Table 1 measurements."""

from __future__ import annotations

from typing import Any

import numpy as np

from train.experiments.report.paper import format_paper, paper_value
from train.experiments.report.runs import ExperimentResults
from train.experiments.report.stats import (
    LEARNED,
    format_collapsed,
    format_diverged,
    learned_level,
    metric_scale,
    summarize,
)
from train.experiments.table1 import format_value

MILESTONE_TOLERANCE = 5_000
"""An evaluation stands for a milestone step when it lies within this many steps of it."""


FINAL_COLUMNS = (("task", "task"), ("condition", "condition"), ("ours", "ours: final mean [95% CI]"),
                 ("learned", f"seeds learned (> {LEARNED:.0%})"),
                 ("level", "learned seeds' success"), ("diverged", "seeds diverged"),
                 ("collapsed", "seeds collapsed"), ("seeds", "seeds"),
                 ("step", "at step"),
                 ("paper", "paper"))


MEASUREMENT_COLUMNS = (("task", "task"), ("measure", "measurement"), ("condition", "condition"),
                   ("ours", "ours: mean ± std"), ("seeds", "seeds"), ("paper", "paper"))


def final_rows(exp: ExperimentResults, paper: dict) -> list[dict[str, Any]]:
    """Per condition: last evaluation's mean and 95% CI over seeds and the seeds that learned, beside the
    paper's value.
    """
    rows = []
    for run in exp.runs:
        ours, learned = summarize(run.values[-1], run.metric)
        scale, unit = metric_scale(run.metric)
        rows.append({"task": run.task, "condition": run.label, "metric": run.metric, "ours": ours,
                     "learned": learned, "level": learned_level(run.values[-1], run.metric),
                     "diverged": format_diverged(run.diverged(), run.seed_ids),
                     "collapsed": format_collapsed(run.top_shares(), run.seed_ids),
                     "seeds": run.seeds, "step": int(run.steps[-1]), "done": run.done,
                     "paper": format_paper(paper_value(paper, run.task, run.condition), scale, unit)})
    return rows


def _milestones(exp: ExperimentResults) -> list[int]:
    """The experiment's milestone steps (its info comes from the known definition, see `trusted_info`)."""
    return list(exp.info.get("milestones", []))


def milestone_rows(exp: ExperimentResults) -> list[dict[str, Any]]:
    """Per condition and milestone step of the experiment (``info['milestones']``): the evaluation closest
    to it (within `MILESTONE_TOLERANCE`), mean [95% CI] and seeds learned; '—' where the run has not reached
    it.
    """
    milestones = _milestones(exp)
    rows = []
    for run in exp.runs:
        row = {"task": run.task, "condition": run.label}
        for m in milestones:
            distance = np.abs(run.steps - m)
            if distance.size and distance.min() <= MILESTONE_TOLERANCE:
                at = int(distance.argmin())
                ours, learned = summarize(run.values[at], run.metric)
                level = learned_level(run.values[at], run.metric)
                learned += "" if level == "—" else f" at {level}"
                collapse = format_collapsed(run.top_shares(at), run.seed_ids).split(" (")[0]
                row[f"at{m}"] = (f"{ours}; learned {learned}; diverged {int(run.diverged(at).sum())}"
                                 + ("" if collapse == "—" else f"; collapsed {collapse.split(' / ')[0]}"))
            else:
                row[f"at{m}"] = "—"
        rows.append(row)
    return rows if milestones else []


def milestone_columns(exp: ExperimentResults) -> tuple[tuple[str, str], ...]:
    """The (key, header) columns of `milestone_rows`."""
    heads = [(f"at{m}", f"at {m:,} steps: mean [95% CI]; seeds > {LEARNED:.0%}; seeds diverged (; collapsed)")
             for m in _milestones(exp)]
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
