"""The evaluation protocol: every agent on the same fixed validation layouts of the test MDP.

All K agents x R validation rollouts run in one vector environment: world ``k * R + i`` is validation
layout ``i`` (seed ``ecology.validation_seeds()[i]``) played by agent ``k`` with its epsilon-greedy policy.
Each rollout is one episode of the test horizon. A rollout counts as solved if ``info["solved"]`` was true
at any of its steps. The exploration draws come from a generator seeded by (agent seed, step), so
evaluating never touches the training streams and a resumed run evaluates identically.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from ecology import validation_seeds
from train.agent.dqn import DoubleDQN
from train.runlog import Interrupted, stop_requested
from train.tasks import make_vector_env

STOP_GRACE_S = 1.0
"""After SIGINT/SIGTERM an evaluation may run this long to finish (the run then checkpoints); a longer one is
abandoned (`train.runlog.Interrupted`) and the run's last checkpoint stands."""
EVAL_STREAM = 0xE7A1
"""Spawn key that separates evaluation draws from every training stream of a seed."""


def evaluation_kwargs(test_kwargs: dict, eval_horizon: int | None) -> dict:
    """The test MDP's keyword arguments with each rollout ``eval_horizon`` long (None: the test horizon)."""
    return {**test_kwargs, "horizon": eval_horizon or test_kwargs["horizon"]}


@dataclass(frozen=True)
class EvalResult:
    """Per-agent evaluation results."""

    success: np.ndarray
    """(K,) fraction of rollouts solved."""
    returns: np.ndarray
    """(K,) mean undiscounted return per rollout."""


class Evaluator:
    """Runs the validation rollouts of every agent in one batched environment (built once, reused)."""

    def __init__(self, env_id: str, test_kwargs: dict, num_agents: int, rollouts: int, epsilon: float,
                 num_actions: int) -> None:
        self.num_agents, self.rollouts = num_agents, rollouts
        self.epsilon, self.num_actions = epsilon, num_actions
        self.horizon = int(test_kwargs["horizon"])
        self.layout_seeds = validation_seeds(rollouts) * num_agents
        self.env = make_vector_env(env_id, num_agents * rollouts, test_kwargs)

    def __call__(self, agent: DoubleDQN, agent_seeds: Sequence[int], step: int) -> EvalResult:
        """Evaluate every agent's current policy; ``step`` seeds the exploration draws."""
        k, r = self.num_agents, self.rollouts
        rngs = [np.random.default_rng(np.random.SeedSequence(s, spawn_key=(EVAL_STREAM, step)))
                for s in agent_seeds]
        obs, _ = self.env.reset(seed=self.layout_seeds)
        live = np.ones(k * r, dtype=bool)
        solved = np.zeros(k * r, dtype=bool)
        returns = np.zeros(k * r)
        signalled = None
        for _ in range(self.horizon):
            if stop_requested():  # finish within a second of a signal (then checkpoint), or give up
                signalled = signalled or time.monotonic()
                if time.monotonic() - signalled > STOP_GRACE_S:
                    raise Interrupted("a signal during a long evaluation")
            actions = self._actions(agent, obs, rngs)
            obs, reward, terminated, truncated, info = self.env.step(actions)
            returns += np.where(live, reward, 0.0)
            solved |= live & np.asarray(info.get("solved", np.zeros(k * r, dtype=bool)), dtype=bool)
            live &= ~(terminated | truncated)
            if not live.any():
                break
        return EvalResult(solved.reshape(k, r).mean(1), returns.reshape(k, r).mean(1))

    def _actions(self, agent: DoubleDQN, obs: np.ndarray, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """Epsilon-greedy actions of every world (agent k plays worlds k*R ... k*R + R - 1)."""
        k, r = self.num_agents, self.rollouts
        with torch.no_grad():
            greedy = agent.greedy(torch.from_numpy(np.asarray(obs, dtype=np.float32)).view(k, r, -1))
        draws = np.stack([rng.random((r, 2)) for rng in rngs])  # (K, R, [explore?, which action])
        random_actions = (draws[..., 1] * self.num_actions).astype(np.int64)
        return np.where(draws[..., 0] < self.epsilon, random_actions, greedy).reshape(-1)

    def close(self) -> None:
        """Release the environment."""
        self.env.close()
