"""Seeds trained together follow the same runs as when trained alone, and different seeds differ."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch

from train.config import TrainConfig
from train.loop.trainer import Trainer
from train.tasks import get_task, make_vector_env, step_worlds

TINY = dict(task="salad", dynamism=0.1, eps_start=0.3, warmup_steps=200, epoch_steps=100, updates_per_epoch=30,
            buffer_size=2_000, eval_rollouts=4, eval_horizon=20, progress=False)


def _trained(first_seed: int, seeds: int, epochs: int = 3, **extra) -> Trainer:
    trainer = Trainer(TrainConfig().replace(first_seed=first_seed, seeds=seeds, **TINY, **extra))
    for _ in range(epochs):
        trainer.train_epoch()
    return trainer


@pytest.mark.parametrize("extra", [{}, {"reset_free": True, "rnd": True}], ids=["episodic", "reset-free-rnd"])
def test_batched_seeds_match_seeds_trained_alone(extra):
    together = _trained(first_seed=3, seeds=3, **extra)
    for k, seed in enumerate(together.seeds):
        alone = _trained(first_seed=seed, seeds=1, **extra)
        assert np.array_equal(alone.replay.obs[0], together.replay.obs[k])  # same experience, exactly
        assert np.array_equal(alone.replay.action[0], together.replay.action[k])
        assert torch.equal(alone.agent.online[0], together.agent.online[k])  # bit for bit: parts of a
        assert torch.equal(alone.agent.target[0], together.agent.target[k])  # run's seeds can be merged
        assert torch.equal(alone.learner.loss_sum[0], together.learner.loss_sum[k])
        assert np.array_equal(alone.visits[0], together.visits[k])


def test_different_seeds_give_different_runs():
    trainer = _trained(first_seed=0, seeds=2)
    assert not np.array_equal(trainer.replay.obs[0], trainer.replay.obs[1])
    assert not torch.allclose(trainer.agent.online[0], trainer.agent.online[1])


def test_same_seed_reproduces_exactly():
    a, b = _trained(first_seed=5, seeds=1), _trained(first_seed=5, seeds=1)
    assert torch.equal(a.agent.online, b.agent.online)
    assert np.array_equal(a.replay.obs, b.replay.obs)


def test_evaluation_is_per_seed_and_repeatable():
    trainer = _trained(first_seed=0, seeds=2, epochs=1)
    first = trainer.evaluator(trainer.agent, trainer.seeds, trainer.step)
    again = trainer.evaluator(trainer.agent, trainer.seeds, trainer.step)
    assert np.array_equal(first.success, again.success) and np.array_equal(first.returns, again.returns)
    assert first.success.shape == (2,)


@pytest.mark.parametrize("task", ["salad", "foodcollector"])
def test_the_trainers_step_gives_what_gymnasiums_step_gives(task):
    env_id = get_task(task).env_id
    fast, slow = make_vector_env(env_id, 3, {}), make_vector_env(env_id, 3, {})
    fast.reset(seed=[4, 5, 6])
    slow.reset(seed=[4, 5, 6])
    actions = np.random.default_rng(0).integers(0, fast.single_action_space.n, (40, 3))
    for a in actions:
        obs, reward, terminated, truncated, pos = step_worlds(fast, a)
        expected = slow.step(a)
        for got, want in zip((obs, reward, terminated, truncated, pos), (*expected[:4], expected[4]["agent_pos"])):
            np.testing.assert_array_equal(got, want)
    fast.close()
    slow.close()


def test_the_trainers_step_never_returns_the_envs_own_buffers():
    env = gymnasium.make_vec(get_task("salad").env_id, num_envs=2, vectorization_mode="vector_entry_point", copy=False)
    env.reset(seed=[0, 1])
    first = step_worlds(env, np.array([1, 2]))
    kept = [a.copy() for a in first]
    step_worlds(env, np.array([3, 4]))
    for got, want in zip(first, kept):
        np.testing.assert_array_equal(got, want)
    env.close()
