"""Gymnasium registration of the grid tasks, from one table."""

from __future__ import annotations

from functools import partial

import gymnasium as gym

from gridtasks.env import GridTaskEnv
from gridtasks.factory import FactoryEnv
from gridtasks.hunting import HuntingEnv
from gridtasks.salad import SaladEnv, WalledSaladEnv
from gridtasks.scavenging import ScavengingEnv
from gridtasks.vector import GridTaskVectorEnv

NAMESPACE = "gridtasks"
TABLE: tuple[tuple[str, str, type[GridTaskEnv]], ...] = (
    ("salad", "Salad-v0", SaladEnv),
    ("hunting", "Hunting-v0", HuntingEnv),
    ("scavenging", "Scavenging-v0", ScavengingEnv),
    ("factory", "Factory-v0", FactoryEnv),
    ("walled-salad", "WalledSalad-v0", WalledSaladEnv),
)
"""The grid tasks, one row each: name (as the CLI spells it), Gymnasium id (in `NAMESPACE`), class."""
TASKS: dict[str, type[GridTaskEnv]] = {name: env_class for name, _, env_class in TABLE}
"""Task name -> environment class."""
ENV_IDS: dict[str, str] = {name: f"{NAMESPACE}/{env_id}" for name, env_id, _ in TABLE}
"""Task name -> Gymnasium id."""


VECTOR_PREFIX = "vector_"
"""``gridtasks.registration:vector_<task>`` (dashes as underscores) is a task's vector entry point."""


def __getattr__(name: str):
    """The vector entry points, by name, so that the registry holds strings (``EnvSpec.to_json`` works)."""
    task = name.removeprefix(VECTOR_PREFIX).replace("_", "-")
    if name.startswith(VECTOR_PREFIX) and task in TASKS:
        return partial(GridTaskVectorEnv, TASKS[task])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def register_all() -> None:
    """Register every grid task (single and vector entry points); safe to call twice."""
    for name, env_class in TASKS.items():
        env_id = ENV_IDS[name]
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=f"{env_class.__module__}:{env_class.__name__}",
            vector_entry_point=f"{__name__}:{VECTOR_PREFIX}{name.replace('-', '_')}",
            disable_env_checker=False,
        )
