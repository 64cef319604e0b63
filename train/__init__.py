"""The paper's trainer: double DQN (+ RND) for every ecorl task, several seeds of a condition in one process.

Modules: `train.config` (frozen settings, original defaults), `train.agent.network` (batched two-branch
Q-network with a hand-written backward pass), `train.agent.dqn` (double-DQN step, Adam, clipping), `train.agent.replay`
(compact replay), `train.agent.rnd`, `train.evaluate` (validation protocol), `train.rundir` (run directory and
checkpoints), `train.trainer` (the loop) and `train.cli` (``ecorl train``). Importing this package does not
import torch; ``from train.trainer import Trainer`` does.
"""

from train.config import DQNConfig, EnvConfig, EvalConfig, RNDConfig, RunConfig, TrainConfig
from train.tasks import TASKS

__all__ = ["TASKS", "DQNConfig", "EnvConfig", "EvalConfig", "RNDConfig", "RunConfig", "TrainConfig"]
