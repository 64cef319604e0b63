r"""The released code's runs (`run_released.py`) beside an ecorl run of the same condition, at matched steps.

For each step asked for, the evaluation nearest to it (within 2 500 steps) of every seed of each side: validation
success (mean [min, max]) and, with ``--axe`` (factory), the share of validation layouts where an axe was made
(the released runs' ``made_axe``, ecorl's ``made``), the largest |Q| of the validation rollouts (median [min, max],
seeds above 10^3, scaled with ``--reward-bound``), the released trainer's batch statistic `Y Predictions Max` where
there is one, and the greedy top-action share (median; seeds above the collapse threshold 0.6). A last row counts,
at the last step asked for, by the rules of ecorl's reports: mean success [95 % bootstrap CI], seeds learned (above
20 %), seeds whose largest |Q| passed 200 / (1 - 0.99) = 20 000 at any validation up to there (the |Q| half of
ecorl's divergence rule, the half both codes measure alike; ecorl's reports also count a TD loss above 1 000;
``--reward-bound`` raises the 200 for a task that pays more a step, e.g. 10 100 for the released factory ladder's
10 000 delivery) and seeds collapsed (top-action share above 0.6)::

    python tools/original/compare.py docs/results/original/hunting-fig4/dynamic-reset-free-waypoint \
        docs/results/paper/dynamism-waypoint/hunting/dynamic-reset-free --at 50000 100000 300000
    python tools/original/compare.py docs/results/original/factory-fig4/dynamic-reset-free-waypoint \
        docs/results/paper/factory-released/factory/dynamic-reset-free --at 250000 1225000 --reward-bound 10100 --axe

The first directory holds one ``seed<N>/metrics.csv`` per released seed; the others are ecorl run directories.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
from pathlib import Path

import numpy as np

from train.experiments.report.stats import (
    COLLAPSE_SHARE,
    LEARNED,
    REWARD_BOUND,
    blown,
    bootstrap_ci,
    collapsed,
    q_bound,
)

MATCH = 2_500
"""The largest distance between a step asked for and the evaluation that stands for it."""
BLOWN = 1e3
"""|Q| above which a seed's values count as blown up in the table (for the default reward bound: five times it)."""
Q = "max \\|Q\\|"
"""How a cell names the largest |Q| (its bars escaped for a markdown table)."""
COLLAPSE = COLLAPSE_SHARE
"""Top-action share above which a seed counts as collapsed (ecorl's)."""
GAMMA = 0.99
"""The discount of every run compared here (both codes' hunting and factory settings)."""


def released_seeds(folder: Path) -> dict[str, list[dict[str, float]]]:
    """Each released seed's metrics rows (``seed*/metrics.csv``), as numbers; of an epoch written twice (by a run
    killed past its checkpoint, then resumed) the last row.
    """
    out = {}
    for path in sorted(folder.glob("seed*/metrics.csv")):
        with path.open() as f:
            rows = [{k: float(v) for k, v in row.items() if v not in ("", None)} for row in csv.DictReader(f)]
        out[path.parent.name] = list({row["epoch"]: row for row in rows}.values())
    return out


def ecorl_seeds(run_dir: Path) -> dict[str, list[dict[str, float]]]:
    """Each seed's rows of an ecorl run's metrics.csv."""
    out: dict[str, list[dict[str, float]]] = {}
    with (run_dir / "metrics.csv").open() as f:
        for row in csv.DictReader(f):
            values = {k: float(v) for k, v in row.items() if v not in ("", None)}
            out.setdefault(f"seed{int(values['seed'])}", []).append(values)
    return out


def at(rows: list[dict[str, float]], step: int) -> dict[str, float] | None:
    """The row nearest to ``step`` within `MATCH`, else None."""
    best = min(rows, key=lambda r: abs(r["step"] - step), default=None)
    return best if best is not None and abs(best["step"] - step) <= MATCH else None


def axe_made(row: dict[str, float]) -> float:
    """The share of validation layouts where an axe was made: ``made_axe`` in a released run, ``made`` in ecorl's
    (NaN in an ecorl file written before the column).
    """
    return row.get("made_axe", row.get("made", math.nan))


def summary(seeds: dict[str, list[dict[str, float]]], step: int, reward_bound: float = REWARD_BOUND,
            axe: bool = False) -> str:
    """One table cell: the seeds' evaluations nearest to ``step``; |Q| counts as blown up above `BLOWN` scaled by
    ``reward_bound`` (the task's largest per-step |reward|) over hunting's; ``axe``: add the axe-made share.
    """
    blown_at = BLOWN * max(reward_bound, REWARD_BOUND) / REWARD_BOUND
    rows = [r for r in (at(v, step) for v in seeds.values()) if r is not None]
    if not rows:
        return "—"
    success = [r["success"] for r in rows]
    q = [r["max_q"] for r in rows]
    finite = [v for v in q if math.isfinite(v)]
    parts = [f"n={len(rows)}", f"success {statistics.mean(success):.1%} [{min(success):.0%}, {max(success):.0%}]"]
    if axe:
        parts.append(f"axe made {statistics.mean(axe_made(r) for r in rows):.1%}")
    parts += [f"{Q} {statistics.median(finite):.3g} [{min(finite):.3g}, {max(finite):.3g}]" if finite else f"{Q} —",
              f"{sum(not (v <= blown_at) for v in q)} above {blown_at:g}"]
    if all("y_pred_max" in r for r in rows):
        parts.append(f"batch Q(s,a) max {statistics.median(r['y_pred_max'] for r in rows):.3g}")
    if all("top_action_share" in r and math.isfinite(r["top_action_share"]) for r in rows):
        shares = [r["top_action_share"] for r in rows]
        parts.append(f"top action {statistics.median(shares):.0%} ({sum(s > COLLAPSE for s in shares)} collapsed)")
    return "; ".join(parts)


def verdict(seeds: dict[str, list[dict[str, float]]], step: int, reward_bound: float = REWARD_BOUND) -> str:
    """The last row's cell: the seeds evaluated near ``step`` counted by ecorl's report rules (module docstring);
    ``reward_bound``: the task's largest per-step |reward| (as in ecorl's `blown`).
    """
    evaluated = {name: at(rows, step) for name, rows in seeds.items()}
    names = [name for name, row in evaluated.items() if row is not None]
    if not names:
        return "—"
    success = np.array([evaluated[name]["success"] for name in names])
    mean, low, high = bootstrap_ci(success)
    diverged = sum(bool(blown(math.nan, [r["max_q"] for r in seeds[name] if r["step"] <= evaluated[name]["step"]],
                              GAMMA, reward_bound).any()) for name in names)  # a NaN loss: the |Q| half alone
    shares = np.array([evaluated[name].get("top_action_share", math.nan) for name in names])
    fell = f"{int(collapsed(shares).sum())}" if np.isfinite(shares).all() else "—"
    bound = q_bound(GAMMA, max(reward_bound, REWARD_BOUND))  # the bound `blown` applies, for the label
    return (f"n={len(names)}; {mean:.1%} [{low:.1%}, {high:.1%}]; learned {int((success > LEARNED).sum())}; "
            f"{Q} past {bound:,.0f} {diverged}; collapsed {fell}")


def main(argv: list[str] | None = None) -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("released", type=Path, help="a folder of released runs, seed<N>/metrics.csv")
    parser.add_argument("ecorl", type=Path, nargs="+", help="ecorl run directories of the same condition")
    parser.add_argument("--at", type=int, nargs="+", required=True, help="steps to compare at")
    parser.add_argument("--reward-bound", type=float, default=REWARD_BOUND,
                        help=f"the task's largest per-step |reward| for the |Q| bound of the last row (default "
                             f"{REWARD_BOUND:g}; the released factory ladder: 10100)")
    parser.add_argument("--axe", action="store_true", help="add the share of validation layouts where an axe was "
                                                           "made (factory)")
    args = parser.parse_args(argv)
    sides = [(f"released ({args.released.as_posix()})", released_seeds(args.released))]
    sides += [(f"ecorl ({path.as_posix()})", ecorl_seeds(path)) for path in args.ecorl]
    print("| step | " + " | ".join(name for name, _ in sides) + " |")
    print("|---|" + "---|" * len(sides))
    for step in args.at:
        cells = [summary(seeds, step, args.reward_bound, args.axe) for _, seeds in sides]
        print(f"| {step:,} | " + " | ".join(cells) + " |")
    last = args.at[-1]
    cells = [verdict(seeds, last, args.reward_bound) for _, seeds in sides]
    print(f"| {last:,}, by ecorl's report rules | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
