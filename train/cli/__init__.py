"""The ``ecorl`` command line: subcommands, ``train`` among them, with flags generated from the config.

Every field of the config sections (`train.config.SECTIONS`) becomes a ``--flag`` whose help text is the
field's docstring; ``task`` is the positional argument. Add a subcommand by writing an ``add_*_command``
function like `add_train_command` (its parser sets the default ``handler(args, parser) -> exit code``)
and listing it in `COMMANDS`.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from train.config import SECTIONS, TrainConfig, _jsonable, field_docs
from train.tasks import TASKS

SKIPPED_FIELDS = ("task",)
"""Config fields that are not flags (the task is the positional argument)."""


def _flag(name: str) -> str:
    """The command-line spelling of a field name."""
    return "--" + name.replace("_", "-")


def _parse_env_kwarg(text: str) -> tuple[str, Any]:
    """Parse KEY=VALUE, reading VALUE as JSON when it is valid JSON and as a string otherwise."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def _add_field(group, f: dataclasses.Field, hint: Any, doc: str) -> None:
    """Add the flag(s) of one config field to an argument group."""
    default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    help_text = f"{doc} (default: {default})" if default not in (None, {}) else doc
    common = {"dest": f.name, "default": argparse.SUPPRESS}
    origin = typing.get_origin(hint)
    if hint is bool and "negative" in f.metadata:
        pair = group.add_mutually_exclusive_group()
        pair.add_argument(_flag(f.name), action="store_true", help=help_text, **common)
        pair.add_argument(_flag(f.metadata["negative"]), action="store_false", help=f"the opposite of "
                          f"{_flag(f.name)}", **common)
    elif hint is bool:
        group.add_argument(_flag(f.name), action=argparse.BooleanOptionalAction, help=help_text, **common)
    elif origin is tuple:
        group.add_argument(_flag(f.name), type=typing.get_args(hint)[0], nargs="+", metavar="N",
                           help=help_text, **common)
    elif origin is dict:
        group.add_argument("--env-kwarg", type=_parse_env_kwarg, action="append", metavar="KEY=VALUE",
                           help=f"{doc} Repeatable.", **common)
    else:
        base = next((a for a in typing.get_args(hint) if a is not type(None)), hint)
        group.add_argument(_flag(f.name), type=base, choices=f.metadata.get("choices"), help=help_text,
                           metavar=None if "choices" in f.metadata else f.name.upper(), **common)


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """One argument group per config section, one flag per field, help from the field docstrings."""
    for name, section in SECTIONS.items():
        group = parser.add_argument_group(f"{name} options", (section.__doc__ or "").strip())
        hints = typing.get_type_hints(section)
        docs = field_docs(section)
        for f in dataclasses.fields(section):
            if f.name not in SKIPPED_FIELDS:
                _add_field(group, f, hints[f.name], docs.get(f.name, ""))


def given_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The config fields given on the command line (flags left out are absent), tuples for lists."""
    names = {f.name for s in SECTIONS.values() for f in dataclasses.fields(s)}
    given = {key: value for key, value in vars(args).items() if key in names}
    if "env_kwargs" in given:
        given["env_kwargs"] = dict(given["env_kwargs"])
    for key, value in given.items():
        if isinstance(value, list):
            given[key] = tuple(value)
    return given


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The TrainConfig given by parsed arguments (defaults for every flag not given)."""
    return TrainConfig().replace(**given_settings(args))


def resume_config(out: Path, task: str, given: dict[str, Any]) -> TrainConfig:
    """The configuration a resumed run continues with: the checkpoint's, with the given runtime settings.

    A given setting that would change the run's results and differs from the checkpoint's is refused, and so
    is a ``--steps`` below the step the run stands at (`RunDirError`, one line).
    """
    from train.rundir import RunDir, RunDirError

    saved, step = RunDir(out).saved_config()
    if task != saved.env.task:
        raise RunDirError(f"--out {out} holds a {saved.env.task} run, not {task}; name {saved.env.task} to resume it")
    identity = saved.identity()
    runtime = {f.name for sec in SECTIONS.values() for f in dataclasses.fields(sec) if f.metadata.get("runtime")}
    for key, value in given.items():
        if key not in runtime and _jsonable(value) != identity[key]:
            raise RunDirError(f"cannot resume {out} with {_flag(key)} {_shown(value)}: the run was made with "
                              f"{_shown(identity[key])} (see {out / 'config.json'}); leave {_flag(key)} out to keep "
                              f"it, or start a fresh run in another --out")
    if given.get("steps", step) < step:
        raise RunDirError(f"--steps {given['steps']} is below step {step}, where the run in {out} stands; give "
                          f"--steps >= {step} (or leave it out to keep {saved.run.steps})")
    return saved.replace(**{k: v for k, v in given.items() if k in runtime})


def _shown(value: Any) -> str:
    """A setting as the command line spells it."""
    if isinstance(value, (list, tuple)):
        return " ".join(map(str, value))
    if isinstance(value, dict):
        return " ".join(f"{k}={json.dumps(v)}" for k, v in value.items()) or "{}"
    return str(value)


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


def _task_name(text: str) -> str:
    """Validate the task argument with a message that lists the choices."""
    if text not in TASKS:
        raise argparse.ArgumentTypeError(f"unknown task {text!r}; choose one of: {', '.join(TASKS)}")
    return text


def add_train_command(subparsers) -> None:
    """``ecorl train TASK [flags]``."""
    parser = subparsers.add_parser(
        "train", help="train double DQN on a task (several seeds together in one process)",
        description="Train double DQN (the paper's trainer) on one condition, all its seeds in one "
                    "process; writes config.json, metrics.csv, visitation counts and a checkpoint to --out.")
    parser.add_argument("task", type=_task_name, metavar="TASK", help=f"one of: {', '.join(TASKS)}")
    parser.add_argument("--out", type=Path, default=None,
                        help="run directory (default: runs/<task>-<knobs>-<seeds>)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its checkpoint, keeping its settings (runtime ones "
                             "such as --steps, which may grow the run, can be given; others must match)")
    add_config_arguments(parser)
    parser.set_defaults(handler=run_train)


def _fail(err: BaseException) -> int:
    """Print a user error of ``ecorl train`` as one line; the exit status 2 (argparse's, for bad input)."""
    print(f"ecorl train: error: {' '.join(str(err).split())}", file=sys.stderr)
    return 2


def train_config(args: argparse.Namespace) -> tuple[TrainConfig, Path]:
    """The configuration and run directory ``ecorl train`` asks for (on --resume: the checkpoint's settings
    with the given ones); raises ValueError or `RunDirError` with a one-line reason."""
    cfg = config_from_args(args).replace(task=args.task)
    out = args.out or default_run_dir(cfg)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file, not a directory; choose a directory path")
    if args.resume:
        cfg = resume_config(out, args.task, {**given_settings(args), "task": args.task})
    return cfg, out


def run_train(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Build the config and the trainer, then train; print a one-line summary per evaluation at the end."""
    from train.rundir import RunDirError
    from train.trainer import Trainer

    try:
        cfg, out = train_config(args)
        trainer = Trainer(cfg, out, resume=args.resume)
    except (RunDirError, ValueError, TypeError, KeyError, OSError) as err:
        return _fail(err)
    run = trainer.cfg.run
    where = f"resuming at step {trainer.step} of" if args.resume else "training"
    print(f"ecorl train {cfg.env.task}: {where} {trainer.cfg.total_steps} steps, {run.seeds} seed(s), "
          f"torch threads {run.threads}, run directory {out}", file=sys.stderr)
    try:
        rows = trainer.run()
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
        print(f"step {last[0]['step']}: mean {key} over {len(last)} seed(s) = {mean:.3f}", file=sys.stderr)
    return 0


def _demo_command(subparsers) -> None:
    from train.experiments.demo import add_demo_command

    add_demo_command(subparsers)


def _experiment_commands(subparsers) -> None:
    from train.cli.commands import SUBCOMMANDS

    for add in SUBCOMMANDS:
        add(subparsers)


COMMANDS = (add_train_command, _experiment_commands, _demo_command)
"""Functions that each add one subcommand."""


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``PROG: error: MESSAGE``, exit status 2), no usage."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``ecorl`` parser with every subcommand."""
    parser = OneLineParser(prog="ecorl", description="Ecological reinforcement learning, reproduced.")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=OneLineParser)
    for add in COMMANDS:
        add(subparsers)
    for sub in subparsers.choices.values():  # each handler gets its own subcommand's parser
        sub.set_defaults(command_parser=sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ecorl`` console script."""
    args = build_parser().parse_args(argv)
    return args.handler(args, args.command_parser)


