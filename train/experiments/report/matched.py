"""Runs side by side at the same points of training, as mean [95 % CI] over each run's seeds.

At chosen evaluation steps, and averaged over each seed's evaluations up to a step (how soon a run learned,
not only how far)::

    python -m train.experiments.report.matched RUN_DIR [RUN_DIR ...] --at 100200 1000200 --average-to 280200

A markdown table on standard output, one row per run directory. It compares runs of different lengths, or of
different experiments, where their evaluations meet (figures.md's Fig. 5 food-collector panel).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from train.experiments.report.runs import read_metrics, task_metric
from train.experiments.report.stats import summarize
from train.storage.safeio import load_json


def run_metric(run_dir: Path) -> tuple[np.ndarray, np.ndarray, str]:
    """(steps (E,), values (E, S), metric) of a run directory's evaluations, in its task's metric."""
    try:
        task = load_json(run_dir / "config.json")["env"]["task"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{run_dir} is not a run directory with a readable config.json ({err})") from None
    metric = task_metric(task)
    steps, values = read_metrics(run_dir / "metrics.csv", metric)
    return steps, values, metric


def matched_row(run_dir: Path, at: Sequence[int], average_to: Sequence[int]) -> list[str]:
    """One table row: the run, then its mean [95 % CI] at each step of ``at`` ('—' where it has no complete
    evaluation there), then over its evaluations up to each step of ``average_to`` (each seed's average first).
    """
    steps, values, metric = run_metric(run_dir)
    cells = [run_dir.as_posix()]
    for step in at:
        hit = np.flatnonzero(steps == step)
        cells.append(summarize(values[hit[0]], metric)[0] if hit.size else "—")
    for step in average_to:
        upto = steps <= step
        cells.append(summarize(values[upto].mean(0), metric)[0] if upto.any() else "—")
    return cells


def matched_table(run_dirs: Sequence[Path], at: Sequence[int], average_to: Sequence[int] = ()) -> str:
    """The markdown table of `matched_row` for each run directory."""
    header = ["run", *(f"at {s}" for s in at), *(f"average to {s}" for s in average_to)]
    rows = [header, ["---"] * len(header), *(matched_row(d, at, average_to) for d in run_dirs)]
    return "\n".join("| " + " | ".join(row) + " |" for row in rows)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table for the run directories and steps on the command line."""
    parser = argparse.ArgumentParser(prog="python -m train.experiments.report.matched",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN_DIR", help="run directories (with metrics.csv)")
    parser.add_argument("--at", nargs="+", type=int, default=[], metavar="STEP", help="evaluation steps")
    parser.add_argument("--average-to", nargs="+", type=int, default=[], metavar="STEP",
                        help="average each seed's evaluations up to these steps")
    args = parser.parse_args(argv)
    if not args.at and not args.average_to:
        parser.error("give --at or --average-to (or both)")
    try:
        print(matched_table(args.runs, args.at, args.average_to))
    except (OSError, ValueError) as err:
        print(f"matched: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
