"""``ecorl evaluate POLICY``: a policy's success on the validation layouts, beside a random policy's."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from train.cli.common import check_out_file, integer, positive, probability, user_errors
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
    parser.add_argument("--agent", type=integer, default=0, help="which of a run's seeds, by index (default: 0)")
    parser.add_argument("--rollouts", type=positive, default=100, help="validation layouts (default: 100)")
    parser.add_argument("--epsilon", type=probability, default=None,
                        help="exploration during evaluation (default: the run's, 0.1 in the paper)")
    parser.add_argument("--random-draws", type=positive, default=1, metavar="N",
                        help="evaluate the random policy N times with independent draws and print their mean, "
                             "95 %% bootstrap interval (from 10 draws), spread and range (default: 1; a single "
                             "draw of 100 layouts varies by a few points); with --test-dynamism, in that test MDP")
    grid = parser.add_argument_group(
        "evaluation grid", "any of these options tabulates success at every (layouts, horizon, epsilon), split by "
        "whether an object needed first (salad: an ingredient) is in the first view, on the tasks that define one")
    grid.add_argument("--epsilons", type=probability, nargs="+", metavar="E",
                      help="e.g. 0 0.1 0.3 (default: --epsilon)")
    grid.add_argument("--horizons", type=positive, nargs="+", metavar="H", help="e.g. 100 400 (default: the run's)")
    grid.add_argument("--fresh", type=integer, default=None, metavar="N",
                      help="also N fresh test-MDP layouts (seeds 2 000 000 000 + i), beside --rollouts validation ones")
    grid.add_argument("--no-split", action="store_true",
                      help="do not split by the first view (a task without one, e.g. hunting, never is)")
    grid.add_argument("--test-dynamism", type=probability, default=None, metavar="P",
                      help="evaluate in the test MDP with dynamism P instead of the paper's static one (e.g. 0.2: "
                           "hunting's deer keep moving, as in the released validation layouts)")
    grid.add_argument("--out", type=Path, default=None, help="also write the grid as CSV to this file")
    parser.set_defaults(handler=handle)
    return parser


MIN_DRAWS_FOR_CI = 10
"""Fewer random draws than this print their mean and range without an interval (a bootstrap of a handful of
draws is far too narrow)."""


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Print the policy's and a random policy's success and mean return (the return alone on a task measured
    by it), and with ``--random-draws`` the spread of the random baseline.
    """
    from train.storage.policy import load_policy
    from train.tasks import get_task

    with user_errors(ValueError, OSError, RunDirError):
        check_world_count(args.random_draws, args.rollouts)
        policy = load_policy(args.policy, args.agent)
        metric = get_task(policy.task).metric
        grid_options = (args.epsilons, args.horizons, args.fresh, args.out, args.test_dynamism)
        if any(x is not None for x in grid_options) or args.no_split:
            if metric != "success":
                raise ValueError(f"the evaluation grid tabulates success, and {policy.task} is measured by its "
                                 f"return: evaluate it without the grid's options")
            if args.random_draws != 1 and (args.epsilons, args.horizons, args.fresh) != (None, None, None):
                raise ValueError("--random-draws goes without --epsilons, --horizons and --fresh (the grid tabulates "
                                 "--epsilons 1 for a random policy); of the grid's options it takes --test-dynamism")
            return handle_grid(args, policy)
        results = {"policy": policy.evaluate(args.rollouts, args.epsilon),
                   "random": policy.random_draws(args.random_draws, args.rollouts)}
    eps = policy.cfg.eval.eval_epsilon if args.epsilon is None else args.epsilon
    print(f"{policy.task}, {args.rollouts} validation layouts of the test MDP ({policy.describe_test_mdp()}):")
    print(f"  policy (epsilon {eps:g}; other exploration draws than the training run's evaluations, so it differs "
          f"from theirs by sampling noise): {outcome(results['policy'], metric)}")
    if args.random_draws == 1:
        print(f"  random (uniform random): {outcome(results['random'], metric)}")
    else:
        print(draws_line(results["random"], metric))
    return 0


def check_world_count(draws: int, rollouts: int) -> None:
    """Refuse an evaluation that would step more than `MAX_RANDOM_WORLDS` worlds at once, naming the option."""
    if draws * rollouts <= MAX_RANDOM_WORLDS:
        return
    if draws == 1:
        raise ValueError(f"--rollouts {rollouts:,} would step {rollouts:,} worlds at once; keep it to "
                         f"{MAX_RANDOM_WORLDS:,}")
    raise ValueError(f"--random-draws {draws} x --rollouts {rollouts} would step {draws * rollouts:,} worlds at once; "
                     f"keep it to {MAX_RANDOM_WORLDS:,} (e.g. --random-draws {max(1, MAX_RANDOM_WORLDS // rollouts)})")


def outcome(result, metric: str) -> str:
    """One agent's (or the draws' mean) success and mean return; the return alone on a task measured by it."""
    import numpy as np

    solved = result.solved
    steps = float(np.median(result.steps_to_solve[solved])) if metric == "success" and solved.any() else math.nan
    speed = "" if math.isnan(steps) else f", median {steps:g} steps to solve (solved layouts)"
    success = "" if metric != "success" else f"success {100 * result.success.mean():.1f} %, "
    return f"{success}mean return {result.returns.mean():.1f}{speed}"


def draws_line(result, metric: str) -> str:
    """The random draws' mean, its 95 % bootstrap interval (from `MIN_DRAWS_FOR_CI` draws), spread and range."""
    from train.experiments.report.stats import bootstrap_ci

    values = 100 * result.success if metric == "success" else result.returns
    unit, spread_unit, what = (" %", " points", "success") if metric == "success" else ("", "", "mean return")
    mean, low, high = (float(v) for v in bootstrap_ci(values))
    ci = (f", 95 % bootstrap CI [{low:.1f}, {high:.1f}]" if len(values) >= MIN_DRAWS_FOR_CI
          else f" (no interval under {MIN_DRAWS_FOR_CI} draws)")
    return (f"  random (uniform random), {len(values)} independent draws: {what} {mean:.1f}{unit}{ci}; one draw's "
            f"standard deviation {values.std(ddof=1):.1f}{spread_unit}, range [{values.min():.1f}, "
            f"{values.max():.1f}]{unit}")


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
    print(f"{policy.task}, {policy.meta.get('source', args.policy)} (seed {policy.seed}), test MDP "
          f"({policy.describe_test_mdp(args.test_dynamism, horizon=False)}):")
    print("\n".join(format_grid(rows)))
    if args.random_draws > 1:
        draws = policy.random_draws(args.random_draws, args.rollouts, dynamism=args.test_dynamism)
        print(draws_line(draws, "success"))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=GRID_COLUMNS, lineterminator="\n")
            writer.writeheader()
            writer.writerows(rows)
        print(f"wrote {args.out}")
    return 0
