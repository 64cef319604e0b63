"""The four grid tasks of Ecological RL (salad, hunting, scavenging, factory) plus walled salad.

Importing the package registers ``gridtasks/Salad-v0``, ``gridtasks/Hunting-v0``,
``gridtasks/Scavenging-v0``, ``gridtasks/Factory-v0`` and ``gridtasks/WalledSalad-v0`` with Gymnasium.
"""

from gridtasks.codes import Code
from gridtasks.env import GridTaskEnv
from gridtasks.factory import FactoryEnv
from gridtasks.hunting import HuntingEnv
from gridtasks.records import check_worlds
from gridtasks.registration import ENV_IDS, TASKS, register_all
from gridtasks.salad import SaladEnv, WalledSaladEnv
from gridtasks.scavenging import ScavengingEnv
from gridtasks.validation import make_test_env, make_validation_envs, validation_layouts
from gridtasks.vector import GridTaskVectorEnv

register_all()

__all__ = [
    "check_worlds",
    "ENV_IDS",
    "TASKS",
    "Code",
    "FactoryEnv",
    "GridTaskEnv",
    "GridTaskVectorEnv",
    "HuntingEnv",
    "SaladEnv",
    "ScavengingEnv",
    "WalledSaladEnv",
    "make_test_env",
    "make_validation_envs",
    "validation_layouts",
]
