"""The paper's trainer and research pipeline, in layers that import only downward.

* `train.config` (the frozen `TrainConfig`, original defaults) and `train.tasks` (the task table train uses,
  derived from the env packages' registrations, and the env contract it relies on);
* `train.agent`: the maths, no I/O: `network` (batched two-branch Q-network with a hand-written backward
  pass), `dqn` (double-DQN step, Adam, clipping), `replay` (compact replay), `rnd`;
* the training loop, in its own rooms: `train.loop` (`trainer`: K seeds of one condition, or several
  conditions packed, in one process; `parts`, `packing`, `memory` beside it; `runlog`: progress, metrics,
  TensorBoard, the stop signal), `train.evaluation` (the validation protocol, the evaluation grid) and
  `train.storage` (what a run keeps on disk: run directory, checkpoint, policy files, atomic writes and
  locks, reading untrusted files);
* `train.experiments`: the research pipeline: `catalog` (the paper's experiments as data), `sweep`, `jobs`
  and `executors` (running them, resumably, locally or on Ray), `table1` (Table 1), `report` (statistics,
  figures, pages), `video`, `demo`;
* `train.cli`: the ``ecorl`` command, one module per subcommand (``python -m train.cli``).

Importing this package does not import torch; ``from train.loop.trainer import Trainer`` does.
"""

from train.config import DQNConfig, EnvConfig, EvalConfig, RNDConfig, RunConfig, TrainConfig
from train.tasks import TASKS

__all__ = ["TASKS", "DQNConfig", "EnvConfig", "EvalConfig", "RNDConfig", "RunConfig", "TrainConfig"]
