"""``ecorl report DIR``: figures, tables and an HTML page from a results directory."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from train.cli.common import check_out_dir, relative, user_errors


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl report DIR``."""
    parser = subparsers.add_parser(
        "report", help="plots, tables and an HTML page from a results directory",
        description="Write learning curves (mean and 95% bootstrap CI over seeds), visitation heat-maps, "
                    "report.md (final results beside the paper's numbers) and index.html (with videos) for DIR = an "
                    "experiment directory, a directory of them, or an `ecorl train` run directory (curves per seed, "
                    "heat-maps, a video of the best seed). Written into DIR (a run directory: DIR/report; a shipped "
                    "result docs/results/paper/NAME: results/report/NAME) unless --out is given.")
    parser.add_argument("dir", type=Path, metavar="DIR",
                        help="results directory (e.g. results/headline) or run directory (e.g. runs/salad-...)")
    parser.add_argument("--out", type=Path, default=None,
                        help="write the report here instead (a film a run lacks is still made in its run "
                             "directory, beside its checkpoint, where later reports find it; --no-videos makes none)")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--videos", dest="videos", action="store_true", default=None,
                       help="render a rollout video of every finished run that has none")
    group.add_argument("--no-videos", dest="videos", action="store_false",
                       help="render no videos (default: only for experiments that ask for them, e.g. headline)")
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Write the report and print the paths written."""
    from train.experiments.report import make_report

    if args.out is not None:
        check_out_dir(args.out)
    with user_errors(OSError, ValueError):
        paths = make_report(args.dir, args.videos, args.out)
    for path in paths:
        print(relative(path))
    print(f"open {relative(paths[-1])} in a browser", file=sys.stderr)
    return 0

