"""Real learning (slow): a dynamic, episodic salad agent beats a random policy on the validation layouts.

The setting is the original code's salad dynamism experiment (dynamism 0.1, two of each ingredient,
episodes of 100 steps, subgoal reward); evaluation is the usual protocol on the sparse test MDP. With the
sparse training reward, whether a seed takes off by 300k steps is close to a coin flip, too slow for a test.
"""

from __future__ import annotations

import numpy as np
import pytest

from train.config import TrainConfig
from train.evaluation.protocol import Evaluator
from train.loop.trainer import Trainer


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_salad_dynamic_episodic_learns_beyond_random():
    cfg = TrainConfig().replace(task="salad", dynamism=0.1, reset_free=False, horizon=100, reward="subgoal",
                                seeds=3, steps=150_200, progress=False)
    trainer = Trainer(cfg)
    rows = trainer.run()
    # the uniformly random policy (epsilon 1) on the same 100 layouts of the test MDP, for the same seeds
    random_policy = Evaluator(trainer.task.env_id, trainer.info.test_kwargs, trainer.num_agents,
                              trainer.cfg.eval.eval_rollouts, 1.0, trainer.info.num_actions)
    random_rate = float(random_policy(trainer.agent, trainer.seeds, step=0).success.mean())
    steps = sorted({r["step"] for r in rows})
    curve = [np.mean([r["success"] for r in rows if r["step"] == s]) for s in steps]
    print(f"random policy {random_rate:.3f}; trained, mean over seeds per evaluation: "
          + " ".join(f"{s // 1000}k:{c:.2f}" for s, c in zip(steps, curve)))
    assert max(curve) >= max(0.06, 5 * random_rate + 0.03)
