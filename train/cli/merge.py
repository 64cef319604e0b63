"""``ecorl merge-seeds PART PART ... --out RUN_DIR``: join runs that trained parts of one condition's seeds."""

from __future__ import annotations

import argparse
from pathlib import Path

from train.cli.common import check_out_dir, user_errors
from train.storage.rundir import RunDirError


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl merge-seeds PART PART ... --out RUN_DIR``."""
    parser = subparsers.add_parser(
        "merge-seeds", help="join runs that each trained a part of one condition's seeds",
        description="Write the run directory of all the seeds of finished runs that differ only in their seeds "
                    "(trained with --seeds and --first-seed, e.g. on two cores): metrics, visitation counts, "
                    "the best and median policies and, for conditions of 'ecorl run', the done marker. The "
                    "merged run has no checkpoint, so it cannot be trained further.")
    parser.add_argument("parts", type=Path, nargs="+", metavar="PART", help="finished run directories")
    parser.add_argument("--out", type=Path, required=True,
                        help="run directory to write (new or empty), e.g. the condition's directory of an "
                             "experiment, where 'ecorl run' then counts it as done and the report reads it")
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Merge the parts and say what was written."""
    from train.experiments.merge import merge_seed_runs
    from train.storage.policy import run_config

    check_out_dir(args.out)
    with user_errors(ValueError, OSError, RunDirError):
        out = merge_seed_runs(args.parts, args.out)
        cfg = run_config(out)
    print(f"{out}: seeds {cfg.run.first_seed}-{cfg.run.first_seed + cfg.run.seeds - 1} of {len(args.parts)} runs, "
          f"{cfg.total_steps:,} steps each")
    return 0
