"""Where two shipped conditions' success intervals lie apart, evaluation by evaluation.

    python tools/intervals_apart.py RUN_A RUN_B [--at STEP ...] [--reach 0.8]

RUN_A and RUN_B are run directories (each with its ``metrics.csv``, all seeds). At every evaluation step both have,
it takes the mean success over seeds with its 95 % percentile-bootstrap interval by the rules of ecorl's reports,
and counts the evaluations where A's interval lies wholly above B's and wholly below it (the last step of each);
then prints both at the steps asked for, and for each seed the first evaluation at or above ``--reach``. This is
what the sentences "its interval lies above the other's at N evaluations" in docs/results/paper/figures.md count.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from train.experiments.report.runs import read_metrics
from train.experiments.report.stats import bootstrap_ci


def success_matrix(run_dir: Path) -> tuple[list[int], np.ndarray]:
    """The evaluation steps of a run directory and its (steps, seeds) success matrix, read as the reports read it."""
    steps, values = read_metrics(run_dir / "metrics.csv", "success")
    return [int(s) for s in steps], values


def first_reaching(steps: list[int], matrix: np.ndarray, level: float) -> list[int | None]:
    """Each seed's first evaluation step with success at or above ``level`` (None: never)."""
    hit = matrix >= level
    return [steps[int(np.argmax(hit[:, j]))] if hit[:, j].any() else None for j in range(matrix.shape[1])]


def main(argv: list[str] | None = None) -> None:
    """Print where the two runs' intervals lie apart, their values at ``--at``, and when seeds reached ``--reach``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_a", type=Path)
    parser.add_argument("run_b", type=Path)
    parser.add_argument("--at", type=int, nargs="*", default=[], help="steps at which to print both (evaluation steps)")
    parser.add_argument("--reach", type=float, default=0.8, help="the success level whose first evaluation to print")
    args = parser.parse_args(argv)
    (steps_a, a), (steps_b, b) = success_matrix(args.run_a), success_matrix(args.run_b)
    steps = [s for s in steps_a if s in steps_b]
    if not steps:
        raise SystemExit("the two runs share no evaluation step: compare runs evaluated on the same schedule")
    mean_a, low_a, high_a = bootstrap_ci(a[[steps_a.index(s) for s in steps]])
    mean_b, low_b, high_b = bootstrap_ci(b[[steps_b.index(s) for s in steps]])
    at = np.array(steps)
    for side, apart in (("above", low_a > high_b), ("below", high_a < low_b)):
        last = f", the last at {at[apart].max():,}" if apart.any() else ""
        print(f"A's interval {side} B's at {apart.sum()} of {len(steps)} evaluations{last}")
    for step in args.at:
        if step not in steps:
            print(f"{step:,}: not an evaluation step of both")
            continue
        i = steps.index(step)
        print(f"{step:,}: A {100 * mean_a[i]:.1f} % [{100 * low_a[i]:.1f}, {100 * high_a[i]:.1f}], "
              f"B {100 * mean_b[i]:.1f} % [{100 * low_b[i]:.1f}, {100 * high_b[i]:.1f}]")
    for name, (s, m) in (("A", (steps_a, a)), ("B", (steps_b, b))):
        first = first_reaching(s, m, args.reach)
        reached = sorted(x for x in first if x is not None)
        print(f"{name} seeds first at >= {args.reach:.0%}: {', '.join(f'{x:,}' for x in reached) or 'none'}"
              f"; never: {first.count(None)}")


if __name__ == "__main__":
    main()
