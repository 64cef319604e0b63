"""How much of a run's time its agents spent in the corners of the grid, and how evenly they spread over it (the
paper's Fig. 9 reading of its heat-maps).

For each of the snapshots the heat-maps draw, each seed's share of all its visits so far that fell on the four
corner cells inside the grid's outer wall, as mean [95 % CI] over seeds, beside the share a visitor spread evenly
over the cells the run ever reached would leave there; and each seed's evenness, the entropy of its visits over
those cells as a share of its largest possible value (100 %: every cell visited equally often; 0: one cell only)::

    python -m train.experiments.report.corners RUN_DIR [RUN_DIR ...]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ecology import corner_cells, corner_share, count_entropy
from train.experiments.report.figures import heatmap_snapshot_files
from train.experiments.report.stats import summarize
from train.storage.rundir import read_visits


def corner_shares(visits: np.ndarray) -> np.ndarray:
    """(S,) each seed's share of its visits on the four inner corner cells; ``visits`` is (S, H, W) counts."""
    return corner_share(visits, wall=1)


def evenness(visits: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(S,) each seed's entropy of its visits over the (H, W) boolean ``cells``, divided by log(their count)."""
    n = int(cells.sum())
    return count_entropy(visits[:, cells]) / np.log(n) if n > 1 else np.zeros(len(visits))


def corner_rows(run_dir: Path) -> list[str]:
    """Markdown rows of one run: step, corner share mean [95 % CI], the even-spread share, evenness [95 % CI]."""
    snapshots = [(int(f.stem), read_visits(f)) for f in heatmap_snapshot_files(run_dir)]
    if not snapshots:
        raise ValueError(f"{run_dir} has no visitation snapshots in {run_dir / 'visits'}")
    reached = snapshots[-1][1].sum(0) > 0
    even = 100.0 * reached[corner_cells(reached.shape)].sum() / max(int(reached.sum()), 1)
    rows = []
    for step, visits in snapshots:
        share = summarize(corner_shares(visits), "success")[0]  # a fraction, shown like success: 17.3% [14.8, 20.0]
        spread = summarize(evenness(visits, reached), "success")[0]  # a fraction of its largest value, in %
        rows.append(f"| {run_dir.as_posix()} | {step} | {share} | {even:.1f}% | {spread} |")
    return rows


def corner_table(run_dirs: Sequence[Path]) -> str:
    """The markdown table of `corner_rows` for each run directory."""
    lines = ["| run | step | visits in the 4 corners | if spread evenly | evenness |", "|---|---|---|---|---|"]
    for run_dir in run_dirs:
        lines += corner_rows(run_dir)
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table for the run directories on the command line."""
    parser = argparse.ArgumentParser(prog="python -m train.experiments.report.corners",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN_DIR", help="grid-task run directories")
    args = parser.parse_args(argv)
    try:
        print(corner_table(args.runs))
    except (OSError, ValueError) as err:
        print(f"corners: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
