"""``ecorl train``'s flags, generated from the config: one per field of `train.config.SECTIONS`.

Each flag's help text is its field's docstring; ``task`` is the positional argument.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import typing
from typing import Any

from train.cli.common import integer
from train.config import SECTIONS, TrainConfig, field_docs, field_owners

SKIPPED_FIELDS = ("task",)
"""Config fields that are not flags (the task is the positional argument)."""


def flag(name: str) -> str:
    """The command-line spelling of a field name; a ``*_kwargs`` field (a dict) takes one KEY=VALUE a flag, so
    its flag is singular: env_kwargs -> --env-kwarg.
    """
    spelling = "--" + name.replace("_", "-")
    return spelling.removesuffix("s") if name.endswith("_kwargs") else spelling


def _parse_env_kwarg(text: str) -> tuple[str, Any]:
    """Parse KEY=VALUE, reading VALUE as JSON when it is valid JSON and as a string otherwise."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def _argument_type(hint: Any) -> Any:
    """The argparse type of a field of type ``hint``: integers also take ``3e5``, the rest parse as their type."""
    return integer if hint is int else hint


def _add_field(group, f: dataclasses.Field, hint: Any, doc: str) -> None:
    """Add the flag(s) of one config field to an argument group."""
    default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    help_text = f"{doc} (default: {default})" if default not in (None, {}) else doc
    common = {"dest": f.name, "default": argparse.SUPPRESS}
    origin = typing.get_origin(hint)
    if hint is bool and "negative" in f.metadata:
        pair = group.add_mutually_exclusive_group()
        pair.add_argument(flag(f.name), action="store_true", help=help_text, **common)
        pair.add_argument(flag(f.metadata["negative"]), action="store_false", help=f"the opposite of "
                          f"{flag(f.name)}", **common)
    elif hint is bool:
        group.add_argument(flag(f.name), action=argparse.BooleanOptionalAction, help=help_text, **common)
    elif origin is tuple:
        group.add_argument(flag(f.name), type=_argument_type(typing.get_args(hint)[0]), nargs="+", metavar="N",
                           help=help_text, **common)
    elif origin is dict:  # env_kwargs -> --env-kwarg, eval_env_kwargs -> --eval-env-kwarg
        group.add_argument(flag(f.name), type=_parse_env_kwarg, action="append",
                           metavar="KEY=VALUE", help=f"{doc} Repeatable.", **common)
    else:
        base = next((a for a in typing.get_args(hint) if a is not type(None)), hint)
        group.add_argument(flag(f.name), type=_argument_type(base), choices=f.metadata.get("choices"), help=help_text,
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
    given = {key: value for key, value in vars(args).items() if key in field_owners()}
    for name in ("env_kwargs", "eval_env_kwargs"):
        if name in given:
            given[name] = dict(given[name])
    for key, value in given.items():
        if isinstance(value, list):
            given[key] = tuple(value)
    return given


def in_flags(message: str) -> str:
    """A config check's message (``eval_every must be ...``) with its leading field name spelt as the flag
    (``--eval-every must be ...``), which is what the user typed.
    """
    name, sep, rest = message.partition(" ")
    return f"{flag(name)} {rest}" if sep and name in field_owners() and name not in SKIPPED_FIELDS else message


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The TrainConfig given by parsed arguments (defaults for every flag not given)."""
    return TrainConfig().replace(**given_settings(args))


def shown(value: Any) -> str:
    """A setting as the command line spells it."""
    if isinstance(value, (list, tuple)):
        return " ".join(map(str, value))
    if isinstance(value, dict):
        return " ".join(f"{k}={json.dumps(v)}" for k, v in value.items()) or "none"
    return str(value)
