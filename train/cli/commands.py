"""The ``ecorl`` subcommands ``run``, ``report``, ``measure``, ``video``, ``export`` and ``evaluate``.

Each ``add_<name>_parser(subparsers)`` adds one subcommand whose handler is ``handler(args, parser) -> int``
(the convention of `train.cli`). ``python -m train.cli.commands ...`` runs them without the rest of the CLI.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from train.experiments.catalog import BUDGETS, EXPERIMENTS, GRID_TASKS, get_experiment
from train.rundir import RunDirError

DEFAULT_OUT = Path("results")
"""Where ``ecorl run`` puts experiments unless told otherwise."""


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text}")
    return value


def _error(command: str, err: BaseException) -> int:
    """Report a user error of ``ecorl COMMAND`` on stderr; the exit status 2 (argparse's, for bad input)."""
    print(f"ecorl {command}: error: {err}", file=sys.stderr)
    return 2


def _probability(text: str) -> float:
    value = float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1], got {text}")
    return value


# ---- ecorl run -----------------------------------------------------------------------------------------


def add_run_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl run EXPERIMENT [--task T ...] [--budget B] [--executor local|ray] ...``."""
    listing = "\n".join(f"  {e.name:<24s}{e.paper}: {e.title}" for e in EXPERIMENTS.values())
    parser = subparsers.add_parser(
        "run", help="run a named experiment of the paper (resumable sweep)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run every condition of a named experiment, one process per condition (its seeds trained "
                    "together), locally or on Ray. Runs go to OUT/EXPERIMENT/TASK/CONDITION/. Re-running the "
                    "same command skips finished runs and resumes interrupted ones.\n\nexperiments:\n" + listing)
    parser.add_argument("experiment", nargs="?", metavar="EXPERIMENT", help="experiment name (see --list)")
    parser.add_argument("--list", action="store_true", help="list the experiments and their budgets, then exit")
    parser.add_argument("--task", nargs="+", metavar="T", help="only these tasks of the experiment")
    parser.add_argument("--budget", choices=BUDGETS, default="quick",
                        help="smoke (seconds, for tests), quick (minutes on a laptop, default) or paper")
    parser.add_argument("--executor", choices=("local", "ray"), default="local",
                        help="local processes (default) or Ray tasks")
    parser.add_argument("--address", default=None,
                        help="Ray cluster address (e.g. 'auto' or HOST:PORT; default: start a local Ray). "
                             "Every node must see --out at the same path.")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"results directory (default: {DEFAULT_OUT})")
    parser.add_argument("--jobs", type=_positive, default=None,
                        help="local processes running at once (default: the number of CPU cores)")
    parser.add_argument("--seeds", type=_positive, default=None, help="override the budget's seeds per condition")
    parser.add_argument("--steps", type=_positive, default=None, help="override the budget's steps per seed")
    parser.add_argument("--dry-run", action="store_true", help="print the runs (and their state), run nothing")
    parser.add_argument("--report", action="store_true", help="write the report of OUT/EXPERIMENT afterwards")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    parser.set_defaults(handler=run_command)
    return parser


def _list_experiments() -> None:
    from train.experiments.sweep import plan

    for exp in EXPERIMENTS.values():
        print(f"{exp.name} ({exp.paper}): {exp.title}")
        print(f"    tasks: {', '.join(exp.tasks)}")
        for name in BUDGETS:
            b = exp.budget(name)
            jobs = plan(exp, name, "/nonexistent")
            steps = sorted({b.steps_for(t) for t in exp.tasks})
            print(f"    {name:<6s} {len(jobs)} runs x {b.seeds} seeds x {'/'.join(f'{s:,}' for s in steps)} steps")


def run_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Plan the experiment's runs and execute those not done yet."""
    from train.experiments.sweep import plan, print_plan, run_jobs, summarize, write_experiment_file

    if args.list:
        _list_experiments()
        return 0
    if args.experiment is None:
        parser.error("name an EXPERIMENT (or pass --list)")
    try:
        exp = get_experiment(args.experiment)
        jobs = plan(exp, args.budget, args.out, args.task, args.seeds, args.steps)
    except ValueError as err:
        parser.error(str(err))
    if args.out.exists() and not args.out.is_dir():
        return _error("run", ValueError(f"--out {args.out} is a file, not a directory; choose a directory path"))
    if args.dry_run:
        print_plan(jobs)
        return 0
    write_experiment_file(exp, args.budget, jobs, args.out)
    where = args.out / exp.name
    print(f"ecorl run {exp.name} ({exp.paper}): {len(jobs)} runs, budget {args.budget}, executor {args.executor}, "
          f"results in {where}", file=sys.stderr)
    try:
        results = run_jobs(jobs, args.executor, args.jobs, args.address, args.progress)
    except KeyboardInterrupt:
        print(f"interrupted: running conditions saved a checkpoint; re-run the same command to resume "
              f"({where})", file=sys.stderr)
        return 130
    except RuntimeError as err:
        return _error("run", err)
    counts = summarize(results)
    print("runs: " + ", ".join(f"{n} {status}" for status, n in sorted(counts.items())), file=sys.stderr)
    if counts.get("failed") or counts.get("interrupted"):
        print("some runs did not finish; re-run the same command to retry/resume them", file=sys.stderr)
        return 1
    if args.report:
        from train.experiments.report.pages import make_report

        try:
            paths = make_report(where)
        except (FileNotFoundError, ValueError) as err:
            return _error("run", err)
        for path in paths:
            print(path)
    else:
        print(f"next: ecorl report {where}", file=sys.stderr)
    return 0


# ---- ecorl report --------------------------------------------------------------------------------------


def add_report_parser(subparsers) -> argparse.ArgumentParser:
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
    parser.set_defaults(handler=report_command)
    return parser


def report_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Write the report and print the paths written."""
    from train.experiments.report.pages import make_report

    try:
        paths = make_report(args.dir, args.videos)
    except (OSError, ValueError) as err:
        return _error("report", err)
    for path in paths:
        print(path)
    return 0


# ---- ecorl measure -------------------------------------------------------------------------------------


def add_measure_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl measure {hitting-time,entropy} --task T [--seeds N] [--steps N] [--out DIR]``."""
    from train.experiments.sweep import MEASUREMENTS

    parser = subparsers.add_parser(
        "measure", help="Table 1: a random policy's hitting time or view entropy",
        description="Measure what a uniform random policy experiences in the non-episodic training envs "
                    "(paper Table 1): the first-reward hitting time in static, dynamic and shaped worlds, or "
                    "the marginal entropy of its egocentric view as dynamism grows. Prints mean ± std over "
                    "seeds and writes DIR/MEASUREMENT_TASK.csv and .md.")
    parser.add_argument("measurement", choices=MEASUREMENTS)
    parser.add_argument("--task", required=True, choices=(*GRID_TASKS, "all"), help="grid task, or all of them")
    parser.add_argument("--seeds", type=_positive, default=25, help="worlds (seeds) per condition (default: 25)")
    parser.add_argument("--steps", type=_positive, default=50_000,
                        help="step budget per seed (hitting time is censored there; default: 50000)")
    parser.add_argument("--seed", type=int, default=0, help="first seed (default: 0)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT / "measure",
                        help="directory for the tables (default: results/measure)")
    parser.set_defaults(handler=measure_command)
    return parser


def measure_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Measure each requested task, print the table and write it."""
    from train.experiments.sweep import measure_rows, write_measure_table

    if args.out.exists() and not args.out.is_dir():
        return _error("measure", ValueError(f"--out {args.out} is a file, not a directory; choose a directory path"))
    tasks = GRID_TASKS if args.task == "all" else (args.task,)
    for task in tasks:
        rows = measure_rows(args.measurement, task, args.seeds, args.steps, args.seed)
        title = f"{args.measurement} ({task}, {args.seeds} seeds, {args.steps} steps, uniform random policy)"
        csv_path, md_path = write_measure_table(rows, args.out / f"{args.measurement}_{task}", title)
        print(title)
        for r in rows:
            censored = f"  ({r['censored']} censored)" if r["censored"] else ""
            print(f"  {r['condition']:>24s}: {r['mean']:9.2f} ± {r['std']:7.2f}  (n={r['seeds']}){censored}")
        print(f"  -> {csv_path}, {md_path}")
    return 0


# ---- ecorl video ---------------------------------------------------------------------------------------


def add_video_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl video TASK [--policy RUN_DIR_OR_FILE | --random] [--out FILE.mp4] ...``."""
    from train.tasks import TASKS

    parser = subparsers.add_parser(
        "video", help="an MP4 of a rollout (trained or random policy)",
        description="Render a rollout to an MP4, headless, in the task's test MDP (or its training env). "
                    "The acting policy is, in order: --policy (one seed of a run, or a policy file), --random, "
                    "or else the trained policy shipped for the task in assets/policies/ (random if none).")
    parser.add_argument("task", choices=tuple(TASKS), metavar="TASK", help=f"one of: {', '.join(TASKS)}")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--policy", type=Path, metavar="RUN_DIR_OR_FILE",
                        help="run directory, its checkpoint.npz, or a policy file (.npz) whose network acts")
    source.add_argument("--random", action="store_true", help="a uniform random policy")
    parser.add_argument("--out", type=Path, default=None,
                        help="output MP4 (default: RUN_DIR/video.mp4 for a run, else TASK-trained.mp4 or "
                             "TASK-random.mp4)")
    parser.add_argument("--episodes", type=_positive, default=3,
                        help="whole episodes to film, each at most the test horizon (default: 3)")
    parser.add_argument("--steps", type=_positive, default=None,
                        help="film exactly this many steps instead (new episodes after each end)")
    parser.add_argument("--seed", type=int, default=0, help="first layout and exploration seed (default: 0)")
    parser.add_argument("--agent", type=int, default=0, help="which of the run's seeds acts, by index (default: 0)")
    parser.add_argument("--epsilon", type=_probability, default=0.05,
                        help="exploration of the policy (default: 0.05)")
    parser.add_argument("--train-env", action="store_true",
                        help="film the run's training env (its knobs) instead of the test MDP")
    parser.set_defaults(handler=video_command)
    return parser


def _video_source(args: argparse.Namespace) -> tuple[Path | None, Path]:
    """The policy to film (None: random) and the default output path, from the parsed arguments."""
    from train.policy import POLICY_DIR, is_policy_file, resolve_run_dir, shipped_policy

    if args.random:
        return None, Path(f"{args.task}-random.mp4")
    if args.policy is None:
        shipped = shipped_policy(args.task)
        if shipped is None:
            print(f"ecorl video: no trained policy for {args.task} in {POLICY_DIR}; filming a random policy "
                  f"(pass --policy to film your own)", file=sys.stderr)
        return shipped, Path(f"{args.task}-{'trained' if shipped else 'random'}.mp4")
    if is_policy_file(args.policy):
        return args.policy, Path(f"{args.task}-trained.mp4")
    return args.policy, resolve_run_dir(args.policy) / "video.mp4"


def video_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Render the video and print its path."""
    from train.experiments.video import record_video

    try:
        policy, default_out = _video_source(args)
        video = record_video(args.task, args.out or default_out, policy_path=policy, steps=args.steps,
                             seed=args.seed, seed_index=args.agent, train_env=args.train_env, epsilon=args.epsilon,
                             episodes=args.episodes)
    except (ValueError, OSError, RunDirError) as err:
        return _error("video", err)
    print(video.summary(), file=sys.stderr)
    print(video.path)
    return 0


# ---- ecorl export --------------------------------------------------------------------------------------


def add_export_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl export RUN_DIR --out FILE.npz [--agent K]``."""
    parser = subparsers.add_parser(
        "export", help="save one seed's trained network as a small policy file",
        description="Write one seed's Q-network of a run (default: the seed with the best validation success "
                    "at the checkpoint's evaluation) with the run's configuration to a policy file (.npz, about "
                    "60 KB for a grid task) that 'ecorl video --policy' and 'ecorl evaluate' read.")
    parser.add_argument("run", type=Path, metavar="RUN_DIR", help="run directory (or its checkpoint.npz)")
    parser.add_argument("--out", type=Path, required=True, help="policy file to write (.npz)")
    parser.add_argument("--agent", type=int, default=None,
                        help="seed index to export (default: the best at the checkpoint's evaluation)")
    parser.set_defaults(handler=export_command)
    return parser


def export_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Export the policy and print what was written."""
    from train.policy import export_policy, load_policy_file

    try:
        path = export_policy(args.run, args.out, args.agent)
    except (ValueError, OSError, RunDirError) as err:
        return _error("export", err)
    meta = load_policy_file(path).meta
    success = meta.get("validation_success")
    shown = "n/a" if success is None else f"{100 * success:.0f} %"
    print(f"{path}: agent {meta['agent']} at step {meta['step']}, validation success {shown}")
    return 0


# ---- ecorl evaluate ------------------------------------------------------------------------------------


def add_evaluate_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl evaluate POLICY [--agent K] [--rollouts N] [--epsilon E]``."""
    parser = subparsers.add_parser(
        "evaluate", help="a policy's success on the validation layouts, beside a random policy's",
        description="Evaluate a trained policy (a policy file, or one seed of a run) by the paper's protocol: "
                    "epsilon-greedy rollouts of the test horizon on the fixed validation layouts of the test "
                    "MDP. A uniform random policy is evaluated on the same layouts for comparison.")
    parser.add_argument("policy", type=Path, metavar="POLICY", help="policy file (.npz), run directory or checkpoint")
    parser.add_argument("--agent", type=int, default=0, help="which of a run's seeds, by index (default: 0)")
    parser.add_argument("--rollouts", type=_positive, default=100, help="validation layouts (default: 100)")
    parser.add_argument("--epsilon", type=_probability, default=None,
                        help="exploration during evaluation (default: the run's, 0.1 in the paper)")
    parser.set_defaults(handler=evaluate_command)
    return parser


def evaluate_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Print the policy's and a random policy's success and mean return."""
    from train.policy import load_policy

    try:
        policy = load_policy(args.policy, args.agent)
        results = {"policy": policy.evaluate(args.rollouts, args.epsilon),
                   "random": policy.evaluate(args.rollouts, epsilon=1.0)}
    except (ValueError, OSError, RunDirError) as err:
        return _error("evaluate", err)
    eps = policy.cfg.eval.eval_epsilon if args.epsilon is None else args.epsilon
    print(f"{policy.task}, {args.rollouts} validation layouts of the test MDP:")
    for name, r in results.items():
        how = f"epsilon {eps:g}" if name == "policy" else "uniform random"
        print(f"  {name:>6s} ({how}): success {100 * r.success[0]:.0f} %, mean return {r.returns[0]:.1f}")
    return 0


SUBCOMMANDS = (add_run_parser, add_report_parser, add_measure_parser, add_video_parser, add_export_parser,
               add_evaluate_parser)
"""The subcommands of this module, in the order ``ecorl --help`` lists them."""


def main(argv: Sequence[str] | None = None) -> int:
    """These subcommands as a stand-alone program (``python -m train.cli.commands``)."""
    from train.cli import OneLineParser

    parser = OneLineParser(prog="ecorl", description="Ecological reinforcement learning: experiments.")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=OneLineParser)
    subs = {add.__name__: add(subparsers) for add in SUBCOMMANDS}
    args = parser.parse_args(argv)
    sub = next(p for p in subs.values() if p.prog.split()[-1] == args.command)
    return args.handler(args, sub)


if __name__ == "__main__":
    sys.exit(main())
