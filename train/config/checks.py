"""Checks of configuration values: each raises a one-line ValueError that names the setting and what it must be."""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["MAX_EVAL_HORIZON", "MAX_EVAL_ROLLOUTS", "MAX_INT", "MAX_THREADS", "check_choices", "check_int",
           "check_kwargs", "check_layers", "check_number", "did_you_mean", "unknown_choice"]


def check_number(name: str, value: Any, low: float | None = None, high: float | None = None,
                 low_open: bool = False) -> None:
    """Raise ValueError unless ``value`` is a finite number in the range (``low_open``: low excluded)."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and (low is None or (value > low if low_open else value >= low)) and (high is None or value <= high)
    if not ok:
        lo = "" if low is None else (f"> {low:g}" if low_open else f">= {low:g}")
        span = f"in {'(' if low_open else '['}{low:g}, {high:g}]" if low is not None and high is not None else lo
        raise ValueError(f"{name} must be a finite number {span}, got {value!r}")


MAX_INT = 2**53
"""Largest integer setting (beyond it no count fits the engine's 64-bit counters with room to grow)."""
MAX_EVAL_HORIZON = 100_000
"""Longest validation rollout: 100 times the longest test horizon (the food collector's 1 000 decisions); a file
that asks for more would make an evaluation or a resume run for days."""
MAX_EVAL_ROLLOUTS = 10_000
"""Most validation rollouts per seed (100 times the protocol's 100 layouts)."""
MAX_THREADS = 256
"""Most threads a run may ask for (torch's and the grid stepper's); more than a machine has only slows it."""


def check_int(name: str, value: Any, low: int = 1, high: int = MAX_INT) -> None:
    """Raise ValueError unless ``value`` is an integer in [``low``, ``high``] (default: `MAX_INT`)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if value > high:
        raise ValueError(f"{name} must be at most {high:,}, got {value!r}")


def check_layers(name: str, value: Any, allow_empty: bool = False) -> None:
    """Raise ValueError unless ``value`` is a (non-empty) tuple of positive integer widths."""
    if not isinstance(value, tuple) or (not value and not allow_empty) or any(
            isinstance(w, bool) or not isinstance(w, int) or w < 1 for w in value):
        need = "one or more" if not allow_empty else "zero or more"
        raise ValueError(f"{name} must be {need} layer widths >= 1, got {value!r}")


def check_kwargs(name: str, kwargs: Any, owned: Mapping[str, str]) -> None:
    """Raise ValueError unless ``kwargs`` maps parameter names to values and names none of ``owned`` (the keys the
    config sets itself, each with how to set it instead).
    """
    if not isinstance(kwargs, dict) or not all(isinstance(k, str) and k for k in kwargs):
        raise ValueError(f"{name} must map parameter names to values, got {kwargs!r}")
    taken = sorted(set(kwargs) & set(owned))
    if taken:
        raise ValueError(f"{name} may not set {taken[0]!r}: the config owns it ({owned[taken[0]]})")


SPELLED_OTHERWISE = (("non-episodic", "reset-free"), ("nonepisodic", "reset-free"), ("non_episodic", "reset-free"),
                     ("resetfree", "reset-free"), ("reset_free", "reset-free"))
"""The paper's word for the conditions ecorl names ``*-reset-free``, and other spellings of it: read as ecorl's name
before the nearest is sought, so 'dynamic-non-episodic' suggests dynamic-reset-free and not its opposite."""


def did_you_mean(given: Any, valid: Iterable[str]) -> str:
    """``'; did you mean X?'`` for the valid name closest to ``given`` (the one it begins, where only one does),
    or '' when none is close or ``given`` is not a string. Case and the `SPELLED_OTHERWISE` words are ignored.
    """
    if not isinstance(given, str):
        return ""
    valid = list(valid)
    given = given.lower()
    for spelling, name in SPELLED_OTHERWISE:
        given = given.replace(spelling, name)
    begun = [name for name in valid if given and name.startswith(given)]
    close = begun if len(begun) == 1 else difflib.get_close_matches(given, valid, n=1, cutoff=0.7)
    return f"; did you mean {close[0]}?" if close else ""


def unknown_choice(kind: str, value: Any, choices: Iterable[str]) -> ValueError:
    """The one-line error for a ``kind`` (task, experiment, budget, ...) that is none of ``choices``: it names the
    nearest choice, then lists them all. ``value`` may be a list of several unknown names (the hint is for the first).
    """
    choices = list(choices)
    several = isinstance(value, list)
    named = ", ".join(map(repr, value)) if several else repr(value)
    kinds = f"{kind}s" if several and len(value) > 1 else kind
    hint = did_you_mean(value[0] if several and value else value, choices)
    return ValueError(f"unknown {kinds} {named}{hint} (choose one of {', '.join(choices)})" if hint
                      else f"unknown {kinds} {named}; choose one of {', '.join(choices)}")


def check_choices(section: Any) -> None:
    """Raise ValueError for a field whose value is not one of its declared ``choices``."""
    for f in dataclasses.fields(section):
        choices = f.metadata.get("choices")
        if choices and getattr(section, f.name) not in choices:
            value = getattr(section, f.name)
            raise ValueError(f"{f.name} must be one of {', '.join(choices)}, got {value!r}"
                             f"{did_you_mean(value, choices)}")
