"""``ecorl evaluate POLICY``: a policy's success on the validation layouts, beside a random policy's."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from train.cli.common import check_out_file, positive, probability, user_errors
from train.storage.rundir import RunDirError

MAX_RANDOM_WORLDS = 100_000
"""Most worlds `--random-draws` steps at once (draws x rollouts: 1 000 draws of the 100 layouts)."""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl evaluate POLICY [--agent K] [--rollouts N] [--epsilon E]``."""
    parser = subparsers.add_parser(
        "evaluate", help="a policy's success on the validation layouts, beside a random policy's",
        description="Evaluate a trained policy (a policy file, or one seed of a run) by the paper's protocol: "
                    "epsilon-greedy rollouts of the test horizon on the fixed validation layouts of the test "
                    "MDP. A uniform random policy is evaluated on the same layouts for comparison.")
    parser.add_argument("policy", type=Path, metavar="POLICY", help="policy file (.npz), run directory or checkpoint")
    parser.add_argument("--agent", type=int, default=0, help="which of a run's seeds, by index (default: 0)")
    parser.add_argument("--rollouts", type=positive, default=100, help="validation layouts (default: 100)")
    parser.add_argument("--epsilon", type=probability, default=None,
                        help="exploration during evaluation (default: the run's, 0.1 in the paper)")
    parser.add_argument("--random-draws", type=positive, default=1, metavar="N",
                        help="evaluate the random policy N times with independent draws and print their mean, "
                             "spread and range (default: 1; a single draw of 100 layouts varies by a few points)")
    grid = parser.add_argument_group(
        "evaluation grid", "any of these options tabulates success at every (layouts, horizon, epsilon), split by "
        "whether an object needed first (salad: an ingredient) is in the first view, on the tasks that define one")
    grid.add_argument("--epsilons", type=probability, nargs="+", metavar="E",
                      help="e.g. 0 0.1 0.3 (default: --epsilon)")
    grid.add_argument("--horizons", type=positive, nargs="+", metavar="H", help="e.g. 100 400 (default: the run's)")
    grid.add_argument("--fresh", type=int, default=None, metavar="N",
                      help="also N fresh test-MDP layouts (seeds 2 000 000 000 + i), beside --rollouts validation ones")
    grid.add_argument("--no-split", action="store_true",
                      help="do not split by the first view (a task without one, e.g. hunting, never is)")
    grid.add_argument("--test-dynamism", type=probability, default=None, metavar="P",
                      help="evaluate in the test MDP with dynamism P instead of the paper's static one (e.g. 0.2: "
                           "hunting's deer keep moving, as in the released validation layouts)")
    grid.add_argument("--out", type=Path, default=None, help="also write the grid as CSV to this file")
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Print the policy's and a random policy's success and mean return."""
    import numpy as np

    from train.policy import load_policy

    with user_errors(ValueError, OSError, RunDirError):
        if args.random_draws * args.rollouts > MAX_RANDOM_WORLDS:
            raise ValueError(f"--random-draws {args.random_draws} x --rollouts {args.rollouts} would step "
                             f"{args.random_draws * args.rollouts:,} worlds at once; keep it to {MAX_RANDOM_WORLDS:,} "
                             f"(e.g. --random-draws {max(1, MAX_RANDOM_WORLDS // args.rollouts)})")
        policy = load_policy(args.policy, args.agent)
        grid_options = (args.epsilons, args.horizons, args.fresh, args.out, args.test_dynamism)
        if any(x is not None for x in grid_options) or args.no_split:
            if args.random_draws != 1:
                raise ValueError("--random-draws goes without the evaluation grid's options (the grid tabulates "
                                 "--epsilons 1 for a random policy)")
            return handle_grid(args, policy)
        results = {"policy": policy.evaluate(args.rollouts, args.epsilon),
                   "random": policy.random_draws(args.random_draws, args.rollouts)}
    eps = policy.cfg.eval.eval_epsilon if args.epsilon is None else args.epsilon
    print(f"{policy.task}, {args.rollouts} validation layouts of the test MDP:")
    for name, r in results.items():
        how = f"epsilon {eps:g}" if name == "policy" else "uniform random"
        steps = float(np.median(r.steps_to_solve[r.solved])) if r.solved.any() else math.nan
        speed = "" if math.isnan(steps) else f", median {steps:g} steps to solve (solved layouts)"
        print(f"  {name:>6s} ({how}): success {100 * r.success.mean():.{1 if len(r.success) > 1 else 0}f} %, "
              f"mean return {r.returns.mean():.1f}{speed}")
    if args.random_draws > 1:
        s = 100 * results["random"].success
        half = 1.959964 * s.std(ddof=1) / math.sqrt(len(s))  # normal 95 % interval of the mean
        low, high = max(s.mean() - half, 0.0), min(s.mean() + half, 100.0)
        print(f"  random: the mean of {len(s)} independent draws, 95 % CI [{low:.1f}, {high:.1f}]; "
              f"one draw's standard deviation {s.std(ddof=1):.1f} points, "
              f"range {s.min():.0f}-{s.max():.0f} %")
    return 0


def handle_grid(args: argparse.Namespace, policy) -> int:
    """Print (and with --out write as CSV) the policy's evaluation grid."""
    import csv

    from train.evaluation.grid import GRID_COLUMNS, evaluate_grid, format_grid

    if args.fresh is not None and args.fresh < 0:
        raise ValueError(f"--fresh must be 0 or more layouts, got {args.fresh}")
    if args.out is not None:  # refused now, not after the grid's rollouts
        check_out_file(args.out, "CSV file", "grid.csv")
    eps = args.epsilons or [policy.cfg.eval.eval_epsilon if args.epsilon is None else args.epsilon]
    horizons = args.horizons or [int(policy.test_kwargs["horizon"])]
    rows = evaluate_grid(policy, eps, horizons, args.rollouts, args.fresh or 0, split=not args.no_split,
                         dynamism=args.test_dynamism)
    where = "" if args.test_dynamism is None else f", test MDP with dynamism {args.test_dynamism:g}"
    print(f"{policy.task}, {policy.meta.get('source', args.policy)} (seed {policy.seed}){where}:")
    print("\n".join(format_grid(rows)))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=GRID_COLUMNS, lineterminator="\n")
            writer.writeheader()
            writer.writerows(rows)
        print(f"wrote {args.out}")
    return 0
