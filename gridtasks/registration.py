"""Gymnasium registration of the grid tasks, from one table."""

from __future__ import annotations

from functools import partial

import gymnasium as gym

from gridtasks.env import GridTaskEnv, GridTaskVectorEnv
from gridtasks.factory import FactoryEnv
from gridtasks.hunting import HuntingEnv
from gridtasks.salad import SaladEnv, WalledSaladEnv
from gridtasks.scavenging import ScavengingEnv

NAMESPACE = "gridtasks"
TASKS: dict[str, type[GridTaskEnv]] = {
    "salad": SaladEnv,
    "hunting": HuntingEnv,
    "scavenging": ScavengingEnv,
    "factory": FactoryEnv,
    "walled-salad": WalledSaladEnv,
}
"""Task name (as the CLI spells it) -> environment class."""
ENV_IDS = {
    "salad": "gridtasks/Salad-v0",
    "hunting": "gridtasks/Hunting-v0",
    "scavenging": "gridtasks/Scavenging-v0",
    "factory": "gridtasks/Factory-v0",
    "walled-salad": "gridtasks/WalledSalad-v0",
}
"""Task name -> Gymnasium id."""


def register_all() -> None:
    """Register every grid task (single and vector entry points); safe to call twice."""
    for name, env_class in TASKS.items():
        env_id = ENV_IDS[name]
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=env_class,
            vector_entry_point=partial(GridTaskVectorEnv, env_class),
            disable_env_checker=False,
        )
