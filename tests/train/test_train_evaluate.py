"""The evaluation protocol's divergence gauge: the largest |Q| of the rollouts, per agent."""

from __future__ import annotations

import math

import pytest
import torch

from train.config import TrainConfig
from train.evaluation.protocol import Evaluator
from train.tasks import get_task, probe


class ConstantQ:
    """A stand-in agent whose Q-values are fixed per agent: action 0 worth ``values[k]``, the rest 0."""

    def __init__(self, values: list[float], num_actions: int) -> None:
        self.values, self.num_actions = torch.tensor(values), num_actions

    def q_values(self, obs: torch.Tensor) -> torch.Tensor:
        q = torch.zeros(*obs.shape[:2], self.num_actions)
        q[..., 0] = self.values[:, None]
        return q


def _evaluator(num_agents: int) -> Evaluator:
    info = probe(get_task("salad"), TrainConfig().env)
    return Evaluator(get_task("salad").env_id, {**info.test_kwargs, "horizon": 5}, num_agents, 3, 0.0,
                     info.num_actions)


def test_max_q_is_the_largest_absolute_value_per_agent():
    evaluator = _evaluator(3)
    try:
        result = evaluator(ConstantQ([2.5, -40.0, 0.0], 5), [0, 1, 2], step=0)
    finally:
        evaluator.close()
    assert result.max_q.tolist() == [2.5, 40.0, 0.0]
    assert result.solved.shape == (3, 3) and result.success.shape == (3,)


def test_a_non_finite_q_value_reads_as_nan():
    evaluator = _evaluator(2)
    try:
        result = evaluator(ConstantQ([math.inf, 1.0], 5), [0, 1], step=0)
    finally:
        evaluator.close()
    assert math.isnan(result.max_q[0]) and result.max_q[1] == 1.0


def test_layouts_can_be_chosen():
    info = probe(get_task("salad"), TrainConfig().env)
    kwargs = {**info.test_kwargs, "horizon": 5}
    evaluator = Evaluator(get_task("salad").env_id, kwargs, 1, 2, 1.0, info.num_actions, layout_seeds=[7, 8])
    try:
        assert evaluator.layout_seeds == [7, 8]
    finally:
        evaluator.close()
    with pytest.raises(ValueError, match="one per rollout"):
        Evaluator(get_task("salad").env_id, kwargs, 1, 2, 1.0, info.num_actions, layout_seeds=[7])


def test_steps_to_solve_count_the_steps_a_greedy_rollout_takes():
    """A learned salad policy's steps to solve each validation layout equal those of the same policy stepped by
    hand in a single test-MDP env (greedy, so no exploration draw differs); unsolved layouts read -1.
    """
    import gymnasium as gym
    import numpy as np

    from ecology import validation_seeds
    from train.storage.policy import load_policy, shipped_policy

    policy = load_policy(shipped_policy("salad"))
    result = policy.evaluate(rollouts=12, epsilon=0.0)
    steps = result.steps_to_solve[0]
    assert steps.shape == (12,) and ((steps >= 1) == result.solved[0]).all() and (steps[~result.solved[0]] == -1).all()
    assert 0 < result.solved[0].sum() < 12  # both kinds of layout are checked
    for seed, expected in zip(validation_seeds(12), steps):
        env = gym.make(get_task("salad").env_id, **policy.test_kwargs).unwrapped
        obs, _ = env.reset(seed=int(seed))
        taken, done, info = 0, False, {}
        while not done:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            taken, done = taken + 1, terminated or truncated
        assert (taken if info.get("solved") else -1) == expected, seed
    assert result.median_steps_to_solve[0] == np.median(steps[steps >= 0])


def test_greedy_actions_are_counted_per_agent_over_the_live_steps():
    evaluator = _evaluator(2)
    try:  # agent 0 prefers action 0; agent 1's action 0 is worth less than the others' 0, so argmax picks 1
        result = evaluator(ConstantQ([1.0, -1.0], 7), [0, 1], step=0)
    finally:
        evaluator.close()
    assert result.action_counts.shape == (2, 7)
    assert result.action_counts.sum(1).tolist() == [15, 15]  # 3 rollouts x 5 steps each, none solved
    assert result.action_counts[0, 0] == 15 and result.action_counts[1, 1] == 15
    assert result.top_action.tolist() == [0, 1] and result.top_action_share.tolist() == [1.0, 1.0]


def test_the_evaluation_protocol_can_move_the_test_mdp_as_the_released_validation_did():
    from train.evaluation.protocol import evaluation_kwargs
    from train.loop.trainer import Trainer

    test = {"dynamism": 0.0, "horizon": 200, "deer_count": 2, "replenish": False}
    assert evaluation_kwargs(test, None) == test  # the paper's protocol: the test MDP as it is
    assert evaluation_kwargs(test, 100, 0.1, {"deer_count": 1}) == {**test, "dynamism": 0.1, "horizon": 100,
                                                                      "deer_count": 1}
    cfg = TrainConfig().replace(task="hunting", steps=400, eval_rollouts=2, eval_dynamism=0.2,
                                eval_env_kwargs={"axe_count": 1}, buffer_size=1_000, progress=False)
    trainer = Trainer(cfg)
    try:
        rules = trainer.evaluator.env.unwrapped.rules[0]
        assert rules["initial"].sum() == 3  # two deer (the training default), one axe
        assert trainer.evaluator.env.unwrapped.ecology.dynamism == 0.2
    finally:
        trainer.close()
    with pytest.raises(ValueError, match="use --eval-horizon"):
        TrainConfig().replace(eval_env_kwargs={"horizon": 50})
