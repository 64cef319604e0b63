"""``ecorl evaluate POLICY``: a policy's success on the validation layouts, beside a random policy's."""

from __future__ import annotations

import argparse
from pathlib import Path

from train.cli.common import positive, probability, user_errors
from train.rundir import RunDirError


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
    parser.set_defaults(handler=handle)
    return parser


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Print the policy's and a random policy's success and mean return."""
    from train.policy import load_policy

    with user_errors(ValueError, OSError, RunDirError):
        policy = load_policy(args.policy, args.agent)
        results = {"policy": policy.evaluate(args.rollouts, args.epsilon),
                   "random": policy.evaluate(args.rollouts, epsilon=1.0)}
    eps = policy.cfg.eval.eval_epsilon if args.epsilon is None else args.epsilon
    print(f"{policy.task}, {args.rollouts} validation layouts of the test MDP:")
    for name, r in results.items():
        how = f"epsilon {eps:g}" if name == "policy" else "uniform random"
        print(f"  {name:>6s} ({how}): success {100 * r.success[0]:.0f} %, mean return {r.returns[0]:.1f}")
    return 0
