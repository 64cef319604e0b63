r"""Each seed of the released code's runs of one condition as a table row, and, beside them, an ecorl run's seeds.

A row: the success at the last validation and the best one, how many validations reached 10 %, where the largest |Q|
of a validation first passed 10^3, that |Q| and the greedy top-action share at the last validation, how many
validations found the greedy policy collapsed (one action above ecorl's 60 % of the steps), the task completions per
5 000 training steps early and late, the share of the late training visits that fell on the four corner cells inside
the wall (where ecorl's failed agents sit), and whether the seed learned (above 20 % at the end, ecorl's rule); under
each table one line sums its seeds up. A released run counts completions in ``metrics.csv``'s ``train_solves``; an ecorl
run has only its training reward, so ``--solve-reward`` (a sparse reward's pay per completion, 100 on the grid
tasks) turns that into completions, and without it that column is left out::

    python tools/original/seed_table.py docs/results/original/hunting-shaping/env-shaping-sparse-260k \
        --ecorl docs/results/paper/hunting-released/hunting/env-shaping-sparse-260k --solve-reward 100
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from collections.abc import Callable
from pathlib import Path

import numpy as np
from compare import BLOWN, ecorl_seeds, released_seeds

from ecology import corner_cells, corner_share
from train.experiments.report.figures import heatmap_snapshot_files
from train.experiments.report.stats import LEARNED, collapsed
from train.storage.rundir import read_visits

EARLY = 50_000
"""Training steps of the early window (from the start)."""
LATE = 500_000
"""Training steps of the late window (up to the last validation)."""
PER = 5_000
"""Completions are counted per this many training steps."""
CORNER_WINDOW = 400_000
"""The corner share counts the visits since the last visit snapshot at least this many steps before the last one."""
WARMUP, EPOCH = 200, 500
"""The released lifetime loop's steps before training and per epoch: its ``visit_N.npy`` counts 200 + 500 (N + 1)."""


def spaced(number: float) -> str:
    """A whole number with thin groups: 1 240 700."""
    return f"{number:,.0f}".replace(",", " ")


def percent(share: float) -> str:
    """A share as a whole percentage; a dash for one not recorded (NaN)."""
    return f"{share:.0%}" if math.isfinite(share) else "—"


COMPLETIONS = f"completions per {spaced(PER)} training steps, first {spaced(EARLY)} → last {spaced(LATE)}"
"""The header of the completions column."""
CORNERS = "late visits in the 4 corners"
"""The header of the corners column."""
HEADER = ("| seed | last validation at | success there | best validation | validations at or above 10 % | "
          "largest \\|Q\\| first above 10³ at | largest \\|Q\\| at the last validation | top-action share there | "
          "share of the validations collapsed (top action above 60 %) | "
          f"{COMPLETIONS} | {CORNERS} | learned (above 20 %) |")
"""The table's header row."""


def rate(windows: list[tuple[float, float, float]], low: float, high: float) -> float:
    """Completions per `PER` steps over the windows (start, end, count) that lie inside (low, high]."""
    inside = [(start, end, count) for start, end, count in windows if start >= low and end <= high]
    steps = sum(end - start for start, end, _ in inside)
    return sum(count for _, _, count in inside) / steps * PER if steps else math.nan


def training_windows(rows: list[dict[str, float]],
                     count: Callable[[dict[str, float]], float]) -> list[tuple[float, float, float]]:
    """(start, end, completions) between consecutive validations (the first from step 0), ``count`` reading a row's
    completions since the one before: a released run's ``train_solves``, an ecorl run's reward over a completion's.
    """
    ends = [row["step"] for row in rows]
    return [(start, end, count(row)) for start, end, row in zip([0.0, *ends], ends, rows)]


def collapsed_share(rows: list[dict[str, float]]) -> float:
    """The share of a seed's validations with the greedy policy collapsed; NaN for a run that did not record it."""
    shares = [r.get("top_action_share", math.nan) for r in rows]
    return float(collapsed(shares).mean()) if all(map(math.isfinite, shares)) else math.nan


def released_visits(seed_dir: Path) -> dict[int, np.ndarray]:
    """A released seed's lifetime visit counts (H, W) by training step, its ``visit_N.npy`` files and its resumed
    parts' (``resumed-EPOCH/``; a later part's file wins).
    """
    parts = [seed_dir, *sorted(seed_dir.glob("resumed-*"), key=lambda p: int(p.name.split("-")[1]))]
    return {WARMUP + EPOCH * (int(f.stem.split("_")[1]) + 1): np.load(f)
            for part in parts for f in sorted(part.glob("visit_*.npy"))}


def ecorl_visits(run_dir: Path) -> dict[str, dict[int, np.ndarray]]:
    """Each seed's visit counts (H, W) so far by training step, from the snapshots of an ecorl run's ``visits/`` that
    its heat-maps draw (`heatmap_snapshot_files`, all a shipped run keeps; seeds x H x W, the first seed
    ``first_seed`` of its config).
    """
    first = json.loads((run_dir / "config.json").read_text())["run"]["first_seed"]
    snapshots = {int(f.stem): read_visits(f) for f in heatmap_snapshot_files(run_dir)}
    seeds = next(iter(snapshots.values())).shape[0] if snapshots else 0
    return {f"seed{first + i}": {step: counts[i] for step, counts in snapshots.items()} for i in range(seeds)}


def late_corners(snapshots: dict[int, np.ndarray]) -> tuple[float, int, int]:
    """The share of the late visits that fell on the four corner cells inside the wall, with the window's first and
    last step: the visits since the last snapshot `CORNER_WINDOW` or more steps before the last one (from step 0 if
    none). NaN (and zeros) without snapshots.
    """
    if not snapshots:
        return math.nan, 0, 0
    last = max(snapshots)
    start = max((step for step in snapshots if step <= last - CORNER_WINDOW), default=None)
    late = snapshots[last].astype(np.int64) - (snapshots[start] if start is not None else 0)
    return float(corner_share(late)), start or 0, last


def row(name: str, rows: list[dict[str, float]], windows: list[tuple[float, float, float]] | None,
        corners: float = math.nan) -> str:
    """One seed's table row (``corners``: its late corner share, `late_corners`)."""
    last = rows[-1]
    best = max(rows, key=lambda r: r["success"])
    blown = next((r["step"] for r in rows if r["max_q"] > BLOWN), None)
    best_cell = f"{best['success']:.0%} at {spaced(best['step'])}" if best["success"] else "0% throughout"
    cells = [name, spaced(last["step"]), f"{last['success']:.0%}", best_cell,
             f"{sum(r['success'] >= 0.1 for r in rows)} of {len(rows)}",
             spaced(blown) if blown is not None else f"never ({max(r['max_q'] for r in rows):.3g} at most)",
             f"{last['max_q']:.3g}", percent(last.get("top_action_share", math.nan)), percent(collapsed_share(rows))]
    if windows is not None:
        early, late = rate(windows, 0, EARLY + 2_500), rate(windows, last["step"] - LATE - 2_500, last["step"])
        cells.append(f"{early:.2g} → {late:.2g}")
    cells.append(percent(corners))
    cells.append("yes" if last["success"] > LEARNED else "no")
    return "| " + " | ".join(cells) + " |"


def table(seeds: dict[str, list[dict[str, float]]], windows: dict[str, list] | None,
          corners: dict[str, float]) -> list[str]:
    """The header and a row per seed (``windows``: per seed, or None to leave the completions column out;
    ``corners``: each seed's late corner share, `late_corners`).
    """
    header = HEADER if windows is not None else HEADER.replace(f" {COMPLETIONS} |", "")
    lines = [header, "|" + "---|" * (header.count(" | ") + 1)]
    return lines + [row(name, rows, windows[name] if windows is not None else None, corners.get(name, math.nan))
                    for name, rows in seeds.items()]


def corner_summary(corners: dict[str, tuple[float, int, int]], reached: np.ndarray | None) -> str:
    """The seeds' late corner shares (`late_corners`) as mean (range) with their windows, beside an even spread's
    over the cells the seeds ever ``reached`` ((H, W) booleans: inner walls, never entered, are left out).
    """
    late = [c for c in corners.values() if math.isfinite(c[0])]
    if not late or reached is None:
        return "corner visits not recorded"
    shares = [share for share, _, _ in late]
    windows = sorted({f"{spaced(start)}–{spaced(last)}" for _, start, last in late})
    even = reached[corner_cells(reached.shape)].sum() / max(int(reached.sum()), 1)
    return (f"visits in the 4 corners over steps {', '.join(windows)}: {statistics.mean(shares):.1%} "
            f"({min(shares):.1%}–{max(shares):.1%}; an even spread {even:.1%})")


def summary(seeds: dict[str, list[dict[str, float]]], corners: str) -> str:
    """One line over the seeds: collapsed at the last validation, the share of all validations collapsed (the
    seeds' range), seeds whose largest |Q| passed 10³ at some validation, ``corners`` (`corner_summary`), seeds
    learned.
    """
    shares = [collapsed_share(rows) for rows in seeds.values()]
    last = [rows[-1] for rows in seeds.values()]
    collapse = (f"{int(collapsed([r['top_action_share'] for r in last]).sum())} collapsed at the last validation; "
                f"{statistics.mean(shares):.0%} of the validations collapsed (a seed: {min(shares):.0%}–"
                f"{max(shares):.0%})" if all(map(math.isfinite, shares)) else "collapse not recorded")
    return (f"{len(seeds)} seeds: {collapse}; largest \\|Q\\| above 10³ at some validation in "
            f"{sum(any(r['max_q'] > BLOWN for r in rows) for rows in seeds.values())}; {corners}; "
            f"{sum(r['success'] > LEARNED for r in last)} learned")


def print_seeds(seeds: dict[str, list[dict[str, float]]], windows: dict[str, list] | None,
                visits: dict[str, dict[int, np.ndarray]]) -> None:
    """Print one code's table of seeds and its summary line."""
    corners = {name: late_corners(visits.get(name, {})) for name in seeds}
    last = [snapshots[max(snapshots)] for snapshots in visits.values() if snapshots]
    reached = np.any([counts > 0 for counts in last], axis=0) if last else None
    print("\n".join(table(seeds, windows, {name: share for name, (share, _, _) in corners.items()})))
    print(f"\n{summary(seeds, corner_summary(corners, reached))}")


def main(argv: list[str] | None = None) -> None:
    """Print the released seeds' table and, with ``--ecorl``, the ecorl run's."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("released", type=Path, help="a folder of released runs, seed<N>/metrics.csv")
    parser.add_argument("--ecorl", type=Path, help="an ecorl run directory of the same condition")
    parser.add_argument("--solve-reward", type=float, default=None,
                        help="the ecorl run's reward per completion (a sparse reward: 100), to count its completions")
    args = parser.parse_args(argv)
    released = released_seeds(args.released)
    if not released:
        raise SystemExit(f"no seed*/metrics.csv in {args.released}")
    print(f"released ({args.released})\n")
    solves = {name: training_windows(rows, lambda r: r["train_solves"]) for name, rows in released.items()}
    visits = {name: released_visits(args.released / name) for name in released}
    print_seeds(released, solves, visits)
    if args.ecorl:
        ecorl = ecorl_seeds(args.ecorl)
        windows = ({name: training_windows(rows, lambda r: r["train_reward"] / args.solve_reward)
                    for name, rows in ecorl.items()} if args.solve_reward else None)
        print(f"\necorl ({args.ecorl})\n")
        print_seeds(ecorl, windows, ecorl_visits(args.ecorl))


if __name__ == "__main__":
    main()
