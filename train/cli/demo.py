"""``ecorl demo``: random-policy MP4s of every task and a picture of them side by side."""

from __future__ import annotations

import argparse
from pathlib import Path

from train.cli.common import check_out_dir, nonnegative, positive


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl demo [--out DIR] [--steps N]``."""
    parser = subparsers.add_parser(
        "demo", help="render a short random-policy MP4 of every task and a picture of them all",
        description="Render a short MP4 of every task (dynamic, reset-free worlds, uniform random policy) "
                    "and tasks.png, a still of each side by side.")
    parser.add_argument("--out", type=Path, default=Path("results/demo"), help="output folder (default: %(default)s)")
    parser.add_argument("--steps", type=positive, default=150, help="steps per video (default: %(default)s)")
    parser.add_argument("--seed", type=nonnegative, default=0, help="seed of worlds and actions (default: %(default)s)")
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Render the videos and the picture; print the paths written."""
    from train.experiments.demo import run_demo

    check_out_dir(args.out)
    for path in run_demo(args.out, steps=args.steps, seed=args.seed):
        print(path)
    return 0
