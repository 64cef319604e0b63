"""The ``ecorl`` command line: one module per subcommand, one convention, one error path.

Each subcommand module (`train.cli.train`, `run`, `report`, `measure`, `video`, `export`, `evaluate`, `demo`)
defines ``add_parser(subparsers)``, which adds its parser and sets ``handler=handle``, and
``handle(args, parser) -> exit status``. A user's mistake is raised as `train.cli.common.UserError`, which
`main` prints as one line (``ecorl COMMAND: error: MESSAGE``, exit status 2). Heavy modules (torch, the
trainer, the report) are imported inside the handlers, so ``ecorl --help`` stays quick.
Add a subcommand by writing such a module and listing it in `COMMANDS`.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from train.cli import demo, evaluate, export, measure, merge, report, run, video
from train.cli import train as train_command
from train.cli.common import OneLineParser, UserError, describe_os_error

COMMANDS = (train_command, run, report, measure, video, export, evaluate, merge, demo)
"""The subcommand modules, in the order ``ecorl --help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    """The ``ecorl`` parser with every subcommand."""
    parser = OneLineParser(prog="ecorl", description="Ecological reinforcement learning, reproduced.")
    parser.add_argument("--version", action="version", version=f"ecorl {_version()}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=OneLineParser)
    for command in COMMANDS:
        command.add_parser(subparsers)
    for sub in subparsers.choices.values():  # each handler gets its own subcommand's parser
        sub.set_defaults(command_parser=sub)
    return parser


def _version() -> str:
    """The installed package's version ('unknown' when run from a tree that is not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("ecorl")
    except PackageNotFoundError:
        return "unknown"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ecorl`` console script (and of ``python -m train.cli``)."""
    parser = build_parser()
    if not (sys.argv[1:] if argv is None else argv):  # a bare ``ecorl``: the overview, not an error
        parser.print_help()
        return 0
    args, extras = parser.parse_known_args(argv)
    if extras:  # named by the subcommand's parser, which knows its flags (the top level only knows --version)
        args.command_parser.reject_unknown(extras)
    try:
        return args.handler(args, args.command_parser)
    except UserError as err:
        print(f"ecorl {args.command}: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader of stdout left (``ecorl run --list | head``): stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so that exit's flush does not fail again
        return 141
    except KeyboardInterrupt:  # Ctrl-C where a command has no stop of its own (training checkpoints first)
        print(f"ecorl {args.command}: interrupted", file=sys.stderr)
        return 130
    except (OSError, MemoryError, *_file_errors()) as err:  # a file, a disk or a run directory, not a bug
        why = " ".join(str(err).split()) or type(err).__name__
        if isinstance(err, MemoryError):
            why = f"out of memory ({why}); ask for less (fewer seeds, a smaller buffer or horizon)"
        elif isinstance(err, OSError) and err.errno is not None:
            why = describe_os_error(err)
        print(f"ecorl {args.command}: error: {why}", file=sys.stderr)
        return 2


def _file_errors() -> tuple[type[BaseException], ...]:
    """The exception types that mean a crafted or unusable file (from the modules already imported)."""
    names = (("train.storage.safeio", "UnsafeFileError"), ("train.storage.rundir", "RunDirError"),
             ("train.storage.checkpoint", "CheckpointError"))
    return tuple(getattr(sys.modules[module], name) for module, name in names if module in sys.modules)
