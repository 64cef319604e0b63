"""``ecorl train TASK [flags]``: train double DQN on one condition, all its seeds in one process."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from train.cli.common import check_out_dir, user_errors
from train.cli.flags import add_config_arguments, flag, given_settings, in_flags, shown
from train.config import SECTIONS, TrainConfig, _jsonable
from train.experiments.choices import TUNED
from train.tasks import TASKS, get_task


def resume_config(out: Path, task: str, given: dict[str, Any]) -> TrainConfig:
    """The configuration a resumed run continues with: the checkpoint's, with the given runtime settings.

    A given setting that would change the run's results and differs from the checkpoint's is refused, and so
    is a ``--steps`` below the step the run stands at (`RunDirError`, one line).
    """
    from train.storage.rundir import RunDir, RunDirError

    saved, step = RunDir(out).saved_config()
    if task != saved.env.task:
        raise RunDirError(f"--out {out} holds a {saved.env.task} run, not {task}; name {saved.env.task} to resume it")
    identity = saved.identity()
    runtime = {f.name for sec in SECTIONS.values() for f in dataclasses.fields(sec) if f.metadata.get("runtime")}
    for key, value in given.items():
        if key not in runtime and _jsonable(value) != identity[key]:
            raise RunDirError(f"cannot resume {out} with {flag(key)} {shown(value)}: the run was made with "
                              f"{shown(identity[key])} (see {out / 'config.json'}); leave {flag(key)} out to keep "
                              f"it, or start a fresh run in another --out")
    resumed = saved.replace(**{k: v for k, v in given.items() if k in runtime})
    if resumed.total_steps < step:  # steps round up to whole epochs: --steps 20000 ends at step 20200
        raise RunDirError(f"--steps {given['steps']} is below step {step}, where the run in {out} stands; give "
                          f"--steps >= {step} (or leave it out to keep {saved.run.steps})")
    return resumed


def default_run_dir(cfg: TrainConfig) -> Path:
    """runs/<condition>: one directory per condition, named from its knobs and seeds."""
    env, run = cfg.env, cfg.run
    parts = [env.task, f"p{env.dynamism:g}", "s" + env.shaping.replace(":", "_"),
             "resetfree" if env.reset_free else f"episodic{env.horizon}", env.reward]
    parts += [f"{k}={v}" for k, v in sorted(env.env_kwargs.items())]
    if cfg.rnd.rnd:
        parts.append(f"rnd{cfg.rnd.rnd_weight:g}")
    parts.append(f"seeds{run.first_seed}-{run.first_seed + run.seeds - 1}")
    return Path("runs") / "-".join(parts)


def tuned_settings(task: str, given: dict[str, Any]) -> dict[str, Any]:
    """The task's tuned settings (`train.experiments.choices.TUNED`, which every experiment uses) that the
    command line does not override, e.g. ``{'lr': 3e-4}`` for salad unless ``--lr`` is given.
    """
    return {k: v for k, v in TUNED.get(task, {}).items() if k not in given}


def _task_name(text: str) -> str:
    """Validate the task argument with `get_task`'s message (the nearest task, then the choices)."""
    try:
        return get_task(text).name
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def add_parser(subparsers) -> argparse.ArgumentParser:
    """``ecorl train TASK [flags]``."""
    parser = subparsers.add_parser(
        "train", help="train double DQN on a task (several seeds together in one process)",
        description="Train double DQN (the paper's trainer) on one condition, all its seeds in one "
                    "process; writes config.json, metrics.csv, visitation counts and a checkpoint to --out. A task "
                    "with tuned settings (salad: --lr 3e-4) uses them unless the flag is given.")
    parser.add_argument("task", type=_task_name, metavar="TASK", help=f"one of: {', '.join(TASKS)}")
    parser.add_argument("--out", type=Path, default=None,
                        help="run directory (default: runs/<task>-<knobs>-<seeds>)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its checkpoint, keeping its settings (runtime ones "
                             "such as --steps, which may grow the run, can be given; others must match)")
    add_config_arguments(parser)
    parser.set_defaults(handler=handle)
    return parser


def train_config(args: argparse.Namespace) -> tuple[TrainConfig, Path]:
    """The configuration and run directory ``ecorl train`` asks for (on --resume: the checkpoint's settings
    with the given ones); raises ValueError or `RunDirError` with a one-line reason.
    """
    given = given_settings(args)
    try:
        cfg = TrainConfig().replace(**{**tuned_settings(args.task, given), **given, "task": args.task})
        out = args.out or default_run_dir(cfg)
        check_out_dir(out)
        if args.resume:
            cfg = resume_config(out, args.task, {**given, "task": args.task})
        cfg.check_trains()
    except ValueError as err:
        raise ValueError(in_flags(str(err))) from err
    return cfg, out


def handle(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Build the config and the trainer, then train; print a one-line summary per evaluation at the end."""
    from train.loop.runlog import Interrupted
    from train.loop.trainer import Trainer
    from train.storage.rundir import RunDirError

    with user_errors(RunDirError, ValueError, TypeError, KeyError, OSError):
        cfg, out = train_config(args)
        trainer = Trainer(cfg, out, resume=args.resume)
    run = trainer.cfg.run
    where = f"resuming at step {trainer.step} of" if args.resume else "training"
    print(f"ecorl train {cfg.env.task}: {where} {trainer.cfg.total_steps} steps, {run.seeds} seed(s), "
          f"torch threads {run.threads}, run directory {out}", file=sys.stderr)
    tuned = {} if args.resume else tuned_settings(cfg.env.task, given_settings(args))
    if tuned:
        shown_tuned = ", ".join(f"{flag(k)} {shown(v)}" for k, v in tuned.items())
        print(f"using {cfg.env.task}'s tuned settings, as the experiments do: {shown_tuned} (give the flag to "
              f"override)", file=sys.stderr)
    try:
        rows = trainer.run()
    except Interrupted as why:
        print(f"stopped by {why} at step {trainer.step}; the checkpoint of step {trainer.last_checkpoint} stands; "
              f"continue with: ecorl train {cfg.env.task} --resume --out {out}", file=sys.stderr)
        return 130
    finally:
        trainer.close()
    if trainer.epoch < trainer.cfg.num_epochs:
        print(f"stopped at step {trainer.step} with a checkpoint; continue with: ecorl train {cfg.env.task} "
              f"--resume --out {out}", file=sys.stderr)
        return 130
    if rows:
        last = [r for r in rows if r["step"] == rows[-1]["step"]]
        key = "success" if trainer.task.metric == "success" else "return"
        mean = sum(r[key] for r in last) / len(last)
        print(f"step {last[0]['step']}: mean {key} over {len(last)} seed(s) = {mean:.3f}")  # the result: stdout
    print(f"next: ecorl report {out} (curves per seed, heat-maps, a video of the best seed)", file=sys.stderr)
    return 0
