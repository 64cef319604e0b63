"""``ecorl run EXPERIMENT``: run a named experiment of the paper (a resumable sweep)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from train.cli.common import DEFAULT_OUT, check_out_dir, minutes, nonnegative, positive, relative, user_errors
from train.experiments.catalog import BUDGETS, EXPERIMENTS, get_experiment
from train.experiments.executors import usable_cpus


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl run EXPERIMENT [--task T ...] [--budget B] [--executor local|ray] ...``."""
    width = max(map(len, EXPERIMENTS)) + 2
    listing = "\n".join(f"  {e.name:<{width}s}{e.paper}: {e.title}" for e in EXPERIMENTS.values())
    parser = subparsers.add_parser(
        "run", help="run a named experiment of the paper (resumable sweep)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run every condition of a named experiment, one process per condition (its seeds trained "
                    "together), locally or on Ray. Runs go to OUT/EXPERIMENT/TASK/CONDITION/. Re-running the "
                    "same command skips finished runs and resumes interrupted ones.\n\nexperiments:\n" + listing)
    parser.add_argument("experiment", nargs="*", metavar="EXPERIMENT",
                        help="experiment name (see --list); several run as one sweep")
    parser.add_argument("--all", action="store_true",
                        help="every experiment that trains, as one sweep: a configuration several of them name is "
                             "trained once and copied, and with --pack (or a GPU) a task's conditions share packs "
                             "across experiments")
    parser.add_argument("--list", action="store_true",
                        help="list the experiments (those named, or all) and their budgets, then exit")
    parser.add_argument("--task", nargs="+", action="extend", metavar="T", help="only these tasks of the experiment")
    parser.add_argument("--condition", nargs="+", action="extend", metavar="C",
                        help="only these conditions (e.g. to give each machine its own; see --dry-run for names)")
    parser.add_argument("--budget", choices=BUDGETS, default="quick",
                        help="smoke (seconds, for tests), quick (minutes on a laptop, default) or paper")
    parser.add_argument("--executor", choices=("local", "ray"), default="local",
                        help="local processes (default) or Ray tasks")
    parser.add_argument("--address", default=None,
                        help="Ray cluster address (e.g. 'auto' or HOST:PORT; default: start a local Ray). "
                             "Every node must see --out at the same path.")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"results directory (default: {DEFAULT_OUT})")
    parser.add_argument("--jobs", type=positive, default=None,
                        help="local processes running at once (default: the CPU cores this process may use)")
    parser.add_argument("--pack", action="store_true",
                        help="train the conditions of a task that share their settings (all but the env knobs, "
                             "learning rate, exploration and RND flag) packed: one batched update for many; on "
                             "the CPU one pack per --jobs process, on a GPU (--device cuda, where it is the "
                             "default) one pack per task; each condition keeps its own run directory")
    parser.add_argument("--device", default=None, metavar="D",
                        help="where the networks and updates run: cpu (default) or cuda[:N]")
    parser.add_argument("--seeds", type=positive, default=None, help="override the budget's seeds per condition")
    parser.add_argument("--first-seed", type=nonnegative, default=0, metavar="N",
                        help="train seeds N, N+1, ... (with --seeds: a part of each condition's seeds, on another "
                             "core or machine; join the finished parts with 'ecorl merge-seeds')")
    parser.add_argument("--steps", type=positive, default=None, help="override the budget's steps per seed")
    parser.add_argument("--minutes", type=minutes, default=None,
                        help="time budget: measure this machine's speed first, then size the steps per seed so that "
                             "every run and the report end within this many minutes (at most the budget's steps)")
    parser.add_argument("--restart", nargs="+", action="extend", metavar="C", default=[],
                        help="train these conditions again from scratch, deleting their results and checkpoint "
                             "(e.g. one that finished but lost its checkpoint)")
    parser.add_argument("--dry-run", action="store_true", help="print the runs (and their state), run nothing")
    parser.add_argument("--estimate", action="store_true",
                        help="as --dry-run, then measure this machine on each kind of run not yet done (a few "
                             "seconds each) and print how long they take, --jobs at a time, one per process")
    parser.add_argument("--report", action="store_true", help="write the report of OUT/EXPERIMENT afterwards")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    parser.set_defaults(handler=handle)
    return parser


def _list_experiments(names: list[str]) -> None:
    """Print the experiments named (every one when none is) with their tasks and budgets."""
    from train.config import TrainConfig
    from train.experiments.sweep import plan

    for exp in [get_experiment(name) for name in names] or EXPERIMENTS.values():
        print(f"{exp.name} ({exp.paper}): {exp.title}")
        print(f"    tasks: {', '.join(exp.tasks)}")
        for name in BUDGETS:
            b = exp.budget(name)
            jobs = plan(exp, name, "/nonexistent")
            trained = [TrainConfig.from_dict(j.config).total_steps for j in jobs if not j.is_measurement]
            steps = sorted(set(trained) or {b.steps_for(t) for t in exp.tasks})  # as trained: whole epochs
            print(f"    {name:<6s} {len(jobs)} runs x {b.seeds} seeds x {'/'.join(f'{s:,}' for s in steps)} steps")


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Plan the experiment's runs and execute those not done yet."""
    began = time.monotonic()
    if args.list:
        with user_errors(ValueError):
            _list_experiments(args.experiment)
        return 0
    if args.all and args.experiment:
        parser.error("--all runs every experiment that trains; drop the names, or drop --all")
    if args.address is not None and args.executor != "ray":
        parser.error("--address names a Ray cluster and applies only with --executor ray; add it, or drop --address")
    names = [e.name for e in EXPERIMENTS.values() if not e.is_measurement] if args.all else args.experiment
    if not names:
        parser.error("name an EXPERIMENT (or pass --all, or --list)")
    if len(names) > 1:
        return _handle_many(args, parser, names)
    try:
        exp = get_experiment(names[0])
    except ValueError as err:
        parser.error(str(err))
    from train.experiments.multi import fill_copies
    from train.experiments.sweep import plan, write_experiment_file  # torch: seconds to import

    try:
        jobs = plan(exp, args.budget, args.out, args.task, args.seeds, args.steps, args.condition, args.restart,
                    args.device, args.first_seed)
    except ValueError as err:
        parser.error(str(err))
    _check_out_and_device(args)
    if args.minutes is not None:
        from train.experiments.timebox import timebox

        jobs = timebox(jobs, args.minutes * 60 - (time.monotonic() - began), args.jobs or usable_cpus(),
                       lambda line: print(line, file=sys.stderr), asked_seconds=args.minutes * 60)
    train, copies = _twins(exp, jobs, args)
    if args.dry_run or args.estimate:
        status = _print_dry_run(train, args)
        for copy, original in copies:
            print(_copy_line(copy, original))
        return status
    with user_errors(ValueError, OSError):
        write_experiment_file(exp, args.budget, jobs, args.out)
    where = args.out / exp.name
    print(f"ecorl run {exp.name} ({exp.paper}): {len(jobs)} runs, budget {args.budget}, executor {args.executor}, "
          f"results in {where}", file=sys.stderr)
    with user_errors(OSError):
        for line in fill_copies(copies):
            print(line, file=sys.stderr)
    results = _execute(train, args, where)
    if results is None:
        return 130
    if not _all_finished(results):
        return _unfinished_code(results)
    return _finish(where, args.report)


def _twins(exp, jobs: list, args: argparse.Namespace) -> tuple[list, list]:
    """(the jobs to train, (copy, original) pairs): a job that another experiment's finished run in --out already
    made, the same settings, is copied from it (`train.experiments.multi.finished_twins`).
    """
    from train.experiments.multi import finished_twins

    if args.first_seed or args.minutes is not None:  # parts of seeds, or steps sized to this machine: no twin
        return jobs, []
    others = [e for e in EXPERIMENTS.values() if e.name != exp.name and not e.is_measurement]
    with user_errors(ValueError, OSError):
        return finished_twins(jobs, others, args.budget, args.out, args.seeds, args.steps)


def _check_out_and_device(args: argparse.Namespace) -> None:
    """Refuse (one line) an --out that is, or lies under, a file and a --device torch cannot use here."""
    check_out_dir(args.out)
    if args.device is not None:
        from train.loop.packing import check_device

        with user_errors(ValueError):
            check_device(args.device)


def _packing(args: argparse.Namespace) -> int:
    """How `run_jobs` packs: 0 not at all, else into up to this many processes (one on a GPU)."""
    gpu = (args.device or "cpu").startswith("cuda")
    return 1 if gpu else (args.jobs or usable_cpus()) if args.pack else 0


def _print_dry_run(jobs: list, args: argparse.Namespace) -> int:
    """The plan, the packs it would train and, with --estimate, how long the runs not yet done take here; returns
    the exit status: 1 where a run will fail (its line says why), else 0.
    """
    from train.experiments.sweep import print_packs, print_plan

    failing = print_plan(jobs)
    if pack := _packing(args):
        print_packs(jobs, pack)
    if args.estimate:
        from train.experiments.jobs import job_is_done
        from train.experiments.timebox import estimate

        with user_errors(ValueError, OSError):
            todo = [j for j in jobs if not job_is_done(j)]
            estimate(todo, args.jobs or usable_cpus(), print)
        if pack:
            print("(estimated for one run per process: packed, as this command would train them, they take less; "
                  "benchmarks/bench_paper.py times packs)")
    if failing:
        print(f"{failing} run(s) will fail as things stand: their lines say why and what to do", file=sys.stderr)
    return 1 if failing else 0


def _execute(jobs: list, args: argparse.Namespace, where: Path) -> list | None:
    """Run the jobs (packed on a GPU or with --pack); their results, or None after Ctrl-C (said on stderr)."""
    from train.experiments.sweep import run_jobs

    try:
        with user_errors(RuntimeError):
            return run_jobs(jobs, args.executor, args.jobs, args.address, args.progress, _packing(args))
    except KeyboardInterrupt:
        print(f"interrupted: running conditions saved a checkpoint; re-run the same command to resume "
              f"({where})", file=sys.stderr)
        return None


def _handle_many(args: argparse.Namespace, parser: argparse.ArgumentParser, names: list[str]) -> int:
    """Several experiments as one sweep (`train.experiments.multi`)."""
    from train.experiments.multi import fill_copies, plan_many, split_copies
    from train.experiments.sweep import write_experiment_file

    for flag, value in (("--minutes", args.minutes), ("--restart", args.restart), ("--first-seed", args.first_seed)):
        if value:
            parser.error(f"{flag} applies to one experiment; run that experiment alone with {flag}")
    try:
        exps = [get_experiment(name) for name in dict.fromkeys(names)]
        jobs = plan_many(exps, args.budget, args.out, args.task, args.condition, args.seeds, args.steps, args.device)
    except ValueError as err:
        parser.error(str(err))
    _check_out_and_device(args)
    train, copies = split_copies(jobs)
    if args.dry_run or args.estimate:
        status = _print_dry_run(train, args)
        for copy, original in copies:
            print(_copy_line(copy, original))
        return status
    ran = sorted({job.experiment for job in jobs}, key=[e.name for e in exps].index)
    with user_errors(ValueError, OSError):
        for exp in exps:
            if exp.name in ran:
                write_experiment_file(exp, args.budget, [j for j in jobs if j.experiment == exp.name], args.out)
    print(f"ecorl run {', '.join(ran)}: {len(train)} runs and {len(copies)} copies of them, budget {args.budget}, "
          f"executor {args.executor}, results in {args.out}", file=sys.stderr)
    results = _execute(train, args, args.out)
    if results is None:
        return 130
    with user_errors(OSError):
        for line in fill_copies(copies):
            print(line, file=sys.stderr)
    if not _all_finished(results):
        return _unfinished_code(results)
    for name in ran:
        _finish(args.out / name, args.report)
    return 0


def _copy_line(copy, original) -> str:
    """The dry run's line for a condition that is another's copy: done, copied at once, or once it finishes."""
    from train.experiments.jobs import job_is_done

    if job_is_done(copy):
        return f"[  done] {copy.name}: the same run as {original.name}, copied"
    when = "finished: copied by this command" if job_is_done(original) else "copied when it finishes"
    return f"[  copy] {copy.name}: the same run as {original.name}, {when}"


def _all_finished(results: list) -> bool:
    """Print the count of runs by outcome and, unless all finished, what did not and what to do; True if all did."""
    from train.experiments.sweep import summarize

    counts = summarize(results)
    print("runs: " + ", ".join(f"{n} {status}" for status, n in sorted(counts.items())), file=sys.stderr)
    if counts.get("kept"):
        print("some conditions hold results without a checkpoint and were kept as they are (see KEPT above); "
              "re-run with --restart CONDITION to train them again from scratch", file=sys.stderr)
        return False
    unfinished = [r for r in results if r.status in ("failed", "interrupted")]
    if unfinished:
        print(_unfinished_message(unfinished), file=sys.stderr)
        return False
    return True


def _unfinished_code(results: list) -> int:
    """The exit status of a sweep that did not finish: 130, as after Ctrl-C, when every run it left unfinished
    was stopped by a signal at a checkpoint (the workers can take a Ctrl-C that the sweep's own process does not
    see as one), else 1.
    """
    unfinished = {r.status for r in results} - {"done", "skipped"}
    return 130 if unfinished == {"interrupted"} else 1


def _unfinished_message(unfinished: list) -> str:
    """One line naming the runs this command did not finish and why, and what to do next."""
    busy = [r.job for r in unfinished if r.status == "failed" and "in use by another ecorl process" in (r.error or "")]
    stopped = [r.job for r in unfinished if r.status == "interrupted"]
    broken = [r.job for r in unfinished if r.job not in busy and r.job not in stopped]
    parts = [f"{len(broken)} failed ({', '.join(broken)}; their errors are above)"] if broken else []
    if stopped:
        parts.append(f"{len(stopped)} stopped at a checkpoint ({', '.join(stopped)})")
    if busy:
        parts.append(f"{len(busy)} trained by another ecorl process ({', '.join(busy)}; it may finish them)")
    return f"not finished by this command: {'; '.join(parts)}; re-run the same command to resume or check them"


def _finish(where: Path, report: bool) -> int:
    """Write the report when asked, then sum up the results and say what to open."""
    from train.experiments.report.lead import run_summary

    page = None
    if report:
        from train.experiments.report import make_report

        print(f"writing the report of {where} (figures, the shipped panels, videos) ...", file=sys.stderr)
        with user_errors(FileNotFoundError, ValueError):
            paths = make_report(where)
        for path in paths:
            print(relative(path))
        page = relative(paths[-1])
    with user_errors(FileNotFoundError, ValueError):
        print("\n".join(run_summary(where)))  # the results: stdout, so that `> log.txt` keeps them
    if page is not None:
        print(f"open {page} in a browser (report.md beside it)", file=sys.stderr)
    else:
        print(f"next: ecorl report {where}", file=sys.stderr)
    return 0
