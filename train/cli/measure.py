"""``ecorl measure MEASUREMENT --task T``: Table 1, what a uniform random policy experiences."""

from __future__ import annotations

import argparse
from pathlib import Path

from train.cli.common import DEFAULT_OUT, UserError, nonnegative, positive
from train.experiments.choices import GRID_TASKS


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl measure {hitting-time,entropy} --task T [--seeds N] [--steps N] [--out DIR]``."""
    from train.experiments.table1 import MEASUREMENTS

    parser = subparsers.add_parser(
        "measure", help="Table 1: a random policy's hitting time or view entropy",
        description="Measure what a uniform random policy experiences in the non-episodic training envs "
                    "(paper Table 1): the first-reward hitting time in static, dynamic and shaped worlds, or "
                    "the marginal entropy of its egocentric view as dynamism grows. Prints mean ± std over "
                    "seeds and writes DIR/MEASUREMENT_TASK.csv and .md.")
    parser.add_argument("measurement", choices=MEASUREMENTS)
    parser.add_argument("--task", required=True, choices=(*GRID_TASKS, "all"), help="grid task, or all of them")
    parser.add_argument("--seeds", type=positive, default=25, help="worlds (seeds) per condition (default: 25)")
    parser.add_argument("--steps", type=positive, default=50_000,
                        help="step budget per seed (hitting time is censored there; default: 50000)")
    parser.add_argument("--seed", type=nonnegative, default=0, help="first seed (default: 0)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT / "measure",
                        help="directory for the tables (default: results/measure)")
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Measure each requested task, print the table and write it."""
    from train.experiments.table1 import format_value, measure_rows, write_table

    if args.out.exists() and not args.out.is_dir():
        raise UserError(f"--out {args.out} is a file, not a directory; choose a directory path")
    tasks = GRID_TASKS if args.task == "all" else (args.task,)
    for task in tasks:
        rows = measure_rows(args.measurement, task, args.seeds, args.steps, args.seed)
        title = f"{args.measurement} ({task}, {args.seeds} seeds, {args.steps} steps, uniform random policy)"
        csv_path, md_path = write_table(args.measurement, rows, args.out / f"{args.measurement}_{task}", title)
        print(title)
        for r in rows:
            print(f"  {r['condition']:>24s}: {format_value(args.measurement, r)}  (n={r['seeds']})")
        print(f"  -> {csv_path}, {md_path}")
    return 0
