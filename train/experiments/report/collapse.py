"""Collapse, measured after the fact: for runs whose metrics.csv predates the collapse columns, what their exported
policies and visitation snapshots still tell.

For each run directory (or every condition of the experiment directories given): each exported policy's (best and
median seed, ``policies/*.npz``) greedy action shares over the validation rollouts, its most frequent action and
whether it collapsed (`stats.COLLAPSED_RULE`), and for every seed the share of its training visits between the
last two visitation snapshots that fell on the four corner cells inside the wall, beside an even spread's::

    python -m train.experiments.report.collapse docs/results/paper/dynamism [RUN_OR_EXPERIMENT_DIR ...]

Runs trained since the collapse columns existed record all of this at every evaluation (metrics.csv), so an
experiment directory's conditions among them are left out; name such a run's own directory to measure it anyway.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ecology import corner_cells, corner_share
from train.experiments.report.figures import heatmap_snapshot_files
from train.experiments.report.runs import find_experiment_dirs, read_columns, trusted_info
from train.experiments.report.stats import collapsed, summarize
from train.storage.rundir import read_visits
from train.storage.safeio import load_json

GRID_ACTIONS = ("west", "east", "north", "south", "pick up", "interact", "place")
"""The grid tasks' actions (`gridtasks.engine.ACTION_NAMES`), named here so the report needs no engine."""
POLICY_NAMES = ("best", "median")
"""The exported policies of a shipped run (`train.storage.policy.export_run_policies`)."""


def action_name(num_actions: int, action: int) -> str:
    """A readable name of ``action``: the grid tasks' names, the food collector's three components."""
    if num_actions == len(GRID_ACTIONS):
        return GRID_ACTIONS[action]
    forward, strafe, turn = action // 9, action // 3 % 3, action % 3
    signs = ("0", "+", "-")
    return f"forward {signs[forward]}, strafe {signs[strafe]}, turn {signs[turn]}"


def policy_rows(run_dir: Path) -> list[str]:
    """One cell text per exported policy: 'best (seed 3): north 81% of greedy steps, collapsed; success 0%'."""
    from train.storage.policy import load_policy_file

    cells = []
    for name in POLICY_NAMES:
        path = run_dir / "policies" / f"{name}.npz"
        if not path.is_file():
            continue
        policy = load_policy_file(path)
        result = policy.evaluate()
        counts = result.action_counts[0]
        top = int(counts.argmax())
        share = float(counts[top] / max(counts.sum(), 1))
        verdict = "collapsed" if collapsed(share) else "not collapsed"
        metric = (f"success {float(result.success[0]):.0%}" if policy.task != "foodcollector"
                  else f"return {float(result.returns[0]):.1f}")
        cells.append(f"{name} (seed {policy.seed}): {action_name(counts.size, top)} {share:.0%}, {verdict}; {metric}")
    return cells


def late_corner_share(run_dir: Path) -> tuple[str, str, int, int]:
    """(corner share of every seed's visits between the last two snapshots, mean [95% CI]; an even spread's
    share over the cells the run reached; the two snapshots' steps).
    """
    files = heatmap_snapshot_files(run_dir)
    if len(files) < 2:
        raise ValueError(f"{run_dir} has fewer than two visitation snapshots in {run_dir / 'visits'}")
    before, last = read_visits(files[-2]), read_visits(files[-1])
    wall = 0 if _task(run_dir) == "foodcollector" else 1  # the food collector's map has no wall ring
    share = summarize(corner_share(last - before, wall), "success")[0]
    reached = last.sum(0) > 0
    even = reached[corner_cells(reached.shape, wall)].sum() / max(int(reached.sum()), 1)
    return share, f"{even:.1%}", int(files[-2].stem), int(files[-1].stem)


def _task(run_dir: Path) -> str:
    """The task of a run directory, from its config.json."""
    return str(load_json(run_dir / "config.json")["env"]["task"])


def records_collapse(run_dir: Path) -> bool:
    """Whether the run's metrics.csv records the greedy top-action share (so its own report counts collapse), read
    as the report reads it (`runs.read_columns`: a column the file lacks or leaves empty is NaN).
    """
    _, _, (share,) = read_columns(run_dir / "metrics.csv", ("top_action_share",), missing=np.nan)
    return bool(np.isfinite(share).any())


def run_dirs_of(path: Path) -> list[Path]:
    """The run directories of ``path``: itself when it is one, else every condition of its experiments that was
    trained before the collapse columns (the later ones record collapse at every evaluation).
    """
    if (path / "metrics.csv").is_file():
        return [path]
    found = []
    for exp_dir in find_experiment_dirs(path):
        info = trusted_info(exp_dir)
        for task, conditions in info.get("tasks", {}).items():
            runs = [exp_dir / task / c["name"] for c in conditions if not c.get("measure")]
            found += [run for run in runs if (run / "metrics.csv").is_file() and not records_collapse(run)]
    if not found:
        raise ValueError(f"{path} is neither a run directory (no metrics.csv) nor holds experiments with runs "
                         "trained before the collapse columns (later runs' reports count collapse themselves)")
    return found


def collapse_table(paths: Sequence[Path]) -> str:
    """The markdown table of every run under ``paths``."""
    lines = ["| run | exported policies: top greedy action, share of greedy steps | corner share of visits, "
             "last snapshot interval (all seeds) | if spread evenly | interval |", "|---|---|---|---|---|"]
    for path in paths:
        for run_dir in run_dirs_of(path):
            share, even, start, end = late_corner_share(run_dir)
            policies = "<br>".join(policy_rows(run_dir)) or "—"
            lines.append(f"| {run_dir.as_posix()} | {policies} | {share} | {even} | {start:,}–{end:,} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table for the directories on the command line."""
    parser = argparse.ArgumentParser(prog="python -m train.experiments.report.collapse",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="+", type=Path, metavar="DIR", help="run or experiment directories")
    args = parser.parse_args(argv)
    try:
        print(collapse_table(args.paths))
    except (OSError, ValueError) as err:
        print(f"collapse: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
