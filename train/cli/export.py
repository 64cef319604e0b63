"""``ecorl export RUN_DIR --out FILE.npz``: one seed's trained network as a small policy file."""

from __future__ import annotations

import argparse
from pathlib import Path

from train.cli.common import integer, user_errors
from train.storage.rundir import RunDirError


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl export RUN_DIR --out FILE.npz [--agent K]``."""
    parser = subparsers.add_parser(
        "export", help="save one seed's trained network as a small policy file",
        description="Write one seed's Q-network of a run (default: the seed with the best validation success "
                    "at the checkpoint's evaluation) with the run's configuration to a policy file (.npz, about "
                    "60 KB for a grid task) that 'ecorl video --policy' and 'ecorl evaluate' read.")
    parser.add_argument("run", type=Path, metavar="RUN_DIR", help="run directory (or its checkpoint.npz)")
    parser.add_argument("--out", type=Path, required=True, help="policy file to write (.npz)")
    parser.add_argument("--agent", type=integer, default=None,
                        help="seed index to export (default: the best at the checkpoint's evaluation)")
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Export the policy and print what was written."""
    from train.storage.policy import export_policy, load_policy_file

    with user_errors(ValueError, OSError, RunDirError):
        path = export_policy(args.run, args.out, args.agent)
    meta = load_policy_file(path).meta
    success, ret = meta.get("validation_success"), meta.get("validation_return")
    shown = (f"validation return {ret:.1f}" if ret is not None else
             f"validation success {'n/a' if success is None else f'{100 * success:.0f} %'}")
    print(f"{path}: agent {meta['agent']} at step {meta['step']}, {shown} (the run's own "
          f"evaluation; `ecorl evaluate {path}` draws the exploration afresh, so its figure differs by sampling noise)")
    return 0
