"""``ecorl report DIR``: figures, tables and an HTML page from a results directory."""

from __future__ import annotations

import argparse
from pathlib import Path

from train.cli.common import user_errors


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl report DIR``."""
    parser = subparsers.add_parser(
        "report", help="plots, tables and an HTML page from a results directory",
        description="Write learning curves (mean and 95% bootstrap CI over seeds), visitation heat-maps, "
                    "report.md (final results beside the paper's numbers) and index.html (with videos) into "
                    "DIR, for DIR = an experiment directory or a directory of them.")
    parser.add_argument("dir", type=Path, metavar="DIR", help="results directory (e.g. results or results/dynamism)")
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

    with user_errors(OSError, ValueError):
        paths = make_report(args.dir, args.videos)
    for path in paths:
        print(path)
    return 0
