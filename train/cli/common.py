"""What every ``ecorl`` subcommand shares: the one-line parser, the one error path, argument types.

A subcommand reports a user's mistake (bad input, a run directory that does not fit) by raising `UserError`,
or by running the code that may fail inside ``with user_errors(...)``; `train.cli.main` prints it as one line
``ecorl COMMAND: error: MESSAGE`` and exits with status 2. Mistakes argparse finds itself (and a handler's
``parser.error``) print the same line through `OneLineParser` and raise SystemExit(2).
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from train.config.checks import did_you_mean

DEFAULT_OUT = Path("results")
"""Where ``ecorl run`` and ``ecorl measure`` write unless told otherwise."""


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``PROG: error: MESSAGE``, exit status 2), no usage, and
    that takes no abbreviated flag (``--seed 3`` is refused with a hint, not read as ``--seeds 3``).
    """

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        """Exit with ``message`` on one line (argparse calls this for bad input), with the nearest valid name
        when a choice is misspelt.
        """
        message = " ".join(message.split())
        chosen = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if chosen:
            message += did_you_mean(chosen[1], re.findall(r"'([^']*)'", chosen[2]))
        self.exit(2, f"{self.prog}: error: {message}\n")

    def reject_unknown(self, extras: list[str]) -> None:
        """Exit naming the arguments this (sub)command does not take, with the nearest flag for a misspelt one."""
        flags = [flag for action in self._actions for flag in action.option_strings]
        hints = [did_you_mean(extra.split("=")[0], flags) for extra in extras if extra.startswith("--")]
        self.error(f"unrecognized arguments: {' '.join(extras)}{''.join(hints)}"
                   f"{'' if any(hints) else f' (see {self.prog} --help)'}")


class UserError(Exception):
    """A mistake of the user, reported as one line (see the module docstring)."""


@contextmanager
def user_errors(*kinds: type[BaseException]) -> Iterator[None]:
    """Inside the block, exceptions of ``kinds`` become `UserError` with their message on one line."""
    try:
        yield
    except kinds as err:
        if isinstance(err, BrokenPipeError):  # stdout's reader left: `train.cli.main` stops quietly
            raise
        raise UserError(_one_line(err)) from err


def _one_line(err: BaseException) -> str:
    """``err``'s message on one line (an operating-system error as `describe_os_error` puts it)."""
    if isinstance(err, OSError) and err.errno is not None:
        return describe_os_error(err)
    return " ".join(str(err).split())


def describe_os_error(err: OSError) -> str:
    """An operating-system error in one line: its path where it names one, its cause, and what to check."""
    what = f"cannot use {err.filename}: {err.strerror}" if err.filename is not None else " ".join(str(err).split())
    return f"{what}; check the path, its permissions and the free disk space, or choose another path"


def relative(path: Path) -> Path:
    """``path`` relative to the working directory when inside it (what a user can paste)."""
    try:
        return Path(path).relative_to(Path.cwd())
    except ValueError:
        return Path(path)


def check_out_dir(out: Path, named: Path | None = None) -> None:
    """Raise `UserError` when the directory ``out`` is, or would have to be made under, an existing file
    (``named``: the --out given, when ``out`` is the directory of the file it names).
    """
    named = named or out
    for path in (out, *out.parents):
        if path.exists():
            if path.is_dir():
                return
            if path == named:
                raise UserError(f"--out {named} is a file, not a directory; choose a directory path")
            raise UserError(f"--out {named} lies under {path}, a file, not a directory; choose another --out")


def check_out_file(out: Path, what: str, example: str) -> None:
    """Raise `UserError` when the file ``out`` (a ``what``, e.g. 'CSV file') cannot be written: it names a directory
    (the error suggests ``example`` inside it), or lies under an existing file.
    """
    if out.is_dir():
        raise UserError(f"--out {out} is a directory; give the {what} to write, e.g. --out {out / example}")
    check_out_dir(out.parent, out)


def _integer(text: str, what: str) -> int:
    """``text`` as an integer (``300000``, ``300_000``, or a whole number written ``3e5``), or an argparse error
    naming ``what`` was expected.
    """
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not value.is_integer():
        raise argparse.ArgumentTypeError(f"expected {what}, got {text}")
    return int(value)


def integer(text: str) -> int:
    """Any whole number, also written ``3e5`` (an argparse type; a config check bounds it later)."""
    return _integer(text, "an integer")


def positive(text: str) -> int:
    """An integer >= 1 (an argparse type)."""
    value = _integer(text, "a positive integer")
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text}")
    return value


def nonnegative(text: str) -> int:
    """An integer >= 0, e.g. a seed (an argparse type)."""
    value = _integer(text, "an integer >= 0")
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text}")
    return value


def probability(text: str) -> float:
    """A number in [0, 1] (an argparse type)."""
    value = float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1], got {text}")
    return value


def minutes(text: str) -> float:
    """A finite number of minutes > 0 (an argparse type)."""
    value = float(text)
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number of minutes > 0, got {text}")
    return value
