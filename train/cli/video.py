"""``ecorl video TASK``: an MP4 of a trained (or random) policy in the task's test MDP."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from train.cli.common import UserError, check_out_file, integer, nonnegative, positive, probability, user_errors
from train.storage.rundir import FILM_NAME, RunDirError

VIDEO_DIR = Path("results") / "videos"
"""Where a film of a policy file or a random policy goes unless --out says otherwise (results/ is git-ignored)."""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl video TASK [--policy RUN_DIR_OR_FILE | --random] [--out FILE.mp4] ...``."""
    from train.tasks import TASKS

    parser = subparsers.add_parser(
        "video", help="an MP4 of a rollout (trained or random policy)",
        description="Render a rollout to an MP4, headless, in the task's test MDP (or its training env). "
                    "The acting policy is, in order: --policy (one seed of a run, or a policy file), --random, "
                    "or else the trained policy shipped for the task in train/data/policies/ (random if none).")
    parser.add_argument("task", choices=tuple(TASKS), metavar="TASK", help=f"one of: {', '.join(TASKS)}")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--policy", type=Path, metavar="RUN_DIR_OR_FILE",
                        help="run directory, its checkpoint.npz, or a policy file (.npz) whose network acts")
    source.add_argument("--random", action="store_true", help="a uniform random policy")
    parser.add_argument("--out", type=Path, default=None,
                        help="output MP4 (default: RUN_DIR/video.mp4 for a run, else results/videos/TASK-trained.mp4 "
                             "or results/videos/TASK-random.mp4)")
    length = parser.add_mutually_exclusive_group()
    length.add_argument("--episodes", type=positive, default=None,
                        help="whole episodes to film, each at most the test horizon (default: three, fewer where "
                             "the first already fills the film, as a 1 000-decision food-collector episode does)")
    length.add_argument("--steps", type=positive, default=None,
                        help="film exactly this many steps instead (new episodes after each end)")
    parser.add_argument("--seed", type=nonnegative, default=0, help="first layout and exploration seed (default: 0)")
    parser.add_argument("--agent", type=integer, default=0, help="which of the run's seeds acts, by index (default: 0)")
    parser.add_argument("--epsilon", type=probability, default=0.05,
                        help="exploration of the policy (default: 0.05)")
    parser.add_argument("--train-env", action="store_true",
                        help="film the run's training env (its knobs) instead of the test MDP")
    parser.set_defaults(handler=handle)
    return parser


def _video_source(args: argparse.Namespace) -> tuple[Path | None, Path]:
    """The policy to film (None: random) and the default output path, from the parsed arguments."""
    from train.storage.policy import POLICY_DIR, is_policy_file, resolve_run_dir, shipped_policy

    if args.random:
        return None, VIDEO_DIR / f"{args.task}-random.mp4"
    if args.policy is None:
        shipped = shipped_policy(args.task)
        if shipped is None:
            print(f"ecorl video: no trained policy for {args.task} in {POLICY_DIR}; filming a random policy "
                  f"(pass --policy to film your own)", file=sys.stderr)
        return shipped, VIDEO_DIR / f"{args.task}-{'trained' if shipped else 'random'}.mp4"
    if is_policy_file(args.policy):
        return args.policy, VIDEO_DIR / f"{args.task}-trained.mp4"
    return args.policy, resolve_run_dir(args.policy) / FILM_NAME


def check_out(out: Path | None, task: str) -> None:
    """Raise `UserError` for an --out that cannot be the MP4 written: a directory, a path under a file, or another
    format's name.
    """
    if out is None:
        return
    check_out_file(out, "file", f"{task}.mp4")
    if out.suffix.lower() != ".mp4":
        raise UserError(f"--out {out}: ecorl video writes an H.264 MP4; give a file name ending in .mp4")


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Render the video and print its path."""
    from train.experiments.video import VIDEO_EPISODES, VIDEO_MAX_FRAMES, record_video

    check_out(args.out, args.task)
    with user_errors(ValueError, OSError, RunDirError):
        policy, default_out = _video_source(args)
        video = record_video(args.task, args.out or default_out, policy_path=policy, steps=args.steps,
                             seed=args.seed, seed_index=args.agent, train_env=args.train_env, epsilon=args.epsilon,
                             episodes=args.episodes or VIDEO_EPISODES,
                             max_frames=None if args.episodes else VIDEO_MAX_FRAMES)
    print(video.summary(), file=sys.stderr)
    print(video.path)
    return 0
