"""The evaluation protocol: every agent on the same fixed validation layouts of the test MDP.

All K agents x R validation rollouts run in one vector environment: world ``k * R + i`` is validation
layout ``i`` (seed ``ecology.validation_seeds()[i]``) played by agent ``k`` with its epsilon-greedy policy.
Each rollout is one episode of the test horizon. A rollout counts as solved if ``info["solved"]`` was true
at any of its steps. The exploration draws come from a generator seeded by (agent seed, step), so
evaluating never touches the training streams and a resumed run evaluates identically.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch

from ecology import validation_seeds
from train.config import EvalConfig
from train.loop.runlog import Interrupted, stop_requested
from train.tasks import make_vector_env

STOP_GRACE_S = 1.0
"""After SIGINT/SIGTERM an evaluation may run this long to finish (the run then checkpoints); a longer one is
abandoned (`train.loop.runlog.Interrupted`) and the run's last checkpoint stands."""
EVAL_STREAM = 0xE7A1
"""Spawn key that separates evaluation draws from every training stream of a seed."""


def evaluation_kwargs(test_kwargs: dict, eval_horizon: int | None, eval_dynamism: float = 0.0,
                      eval_env_kwargs: dict | None = None) -> dict:
    """The test MDP's keyword arguments with each rollout ``eval_horizon`` long (None: the test horizon), at
    ``eval_dynamism`` (0: the paper's static test MDP) and with the task parameters ``eval_env_kwargs`` changed.
    """
    return {**test_kwargs, **(eval_env_kwargs or {}), "dynamism": eval_dynamism,
            "horizon": eval_horizon or test_kwargs["horizon"]}


def run_evaluation_kwargs(test_kwargs: dict, ev: EvalConfig) -> dict:
    """`evaluation_kwargs` under a run's evaluation settings ``ev``."""
    return evaluation_kwargs(test_kwargs, ev.eval_horizon, ev.eval_dynamism, ev.eval_env_kwargs)


class ActionValues(Protocol):
    """What evaluation needs of a policy: K agents' action values (a `Learner`, a `DoubleDQN` or a `Policy`)."""

    def q_values(self, obs: torch.Tensor) -> torch.Tensor:
        """Action values (K, N, actions) on the CPU of observations (K, N, obs_dim)."""


class UniformRandom:
    """K uniform random policies as `ActionValues`: every action value 0, so that with epsilon 1 each step is a
    uniform draw from that agent's own exploration stream.
    """

    def __init__(self, num_actions: int) -> None:
        self.num_actions = num_actions

    def q_values(self, obs: torch.Tensor) -> torch.Tensor:
        """Zeros (K, N, actions) for observations (K, N, obs_dim)."""
        return torch.zeros(obs.shape[0], obs.shape[1], self.num_actions)


@dataclass(frozen=True)
class EvalResult:
    """Per-agent evaluation results."""

    returns: np.ndarray
    """(K,) mean undiscounted return per rollout."""
    max_q: np.ndarray
    """(K,) largest |Q| of any action in any state the rollouts visited (NaN if a value is not finite): a
    divergence gauge, see `train.experiments.report.stats.diverged`."""
    steps_to_solve: np.ndarray
    """(K, R) environment steps each rollout took to solve its layout, -1 where it did not."""
    action_counts: np.ndarray
    """(K, actions) how often each action was the greedy one (argmax Q) at the rollouts' steps, whether or not
    epsilon then replaced it: the policy's own choices, for `collapse`."""
    made: np.ndarray
    """(K,) share of rollouts in which the task's product was made (factory: an axe; NaN for the food
    collector, which makes nothing)."""

    @property
    def solved(self) -> np.ndarray:
        """(K, R) whether each rollout was solved."""
        return self.steps_to_solve >= 0

    @property
    def success(self) -> np.ndarray:
        """(K,) fraction of rollouts solved."""
        return self.solved.mean(1)

    @property
    def top_action(self) -> np.ndarray:
        """(K,) each agent's most frequent greedy action."""
        return self.action_counts.argmax(1)

    @property
    def top_action_share(self) -> np.ndarray:
        """(K,) the share of the rollouts' steps at which that action was the greedy one (1 / actions if even)."""
        return self.action_counts.max(1) / np.maximum(self.action_counts.sum(1), 1)

    @property
    def median_steps_to_solve(self) -> np.ndarray:
        """(K,) median steps to solve over each agent's solved rollouts (NaN where none was solved)."""
        return np.array([np.median(row[row >= 0]) if (row >= 0).any() else np.nan for row in self.steps_to_solve],
                        dtype=np.float64)


class Evaluator:
    """Runs the validation rollouts of every agent in one batched environment (built once, reused)."""

    def __init__(self, env_id: str, test_kwargs: dict, num_agents: int, rollouts: int, epsilon: float,
                 num_actions: int, layout_seeds: Sequence[int] | None = None, threads: int = 1) -> None:
        """``layout_seeds``: the R layouts' reset seeds (default: the first ``rollouts`` validation layouts);
        ``threads``: threads stepping the grid worlds (same results for any count).
        """
        seeds = validation_seeds(rollouts) if layout_seeds is None else [int(s) for s in layout_seeds]
        if len(seeds) != rollouts:
            raise ValueError(f"{len(seeds)} layout seeds given for {rollouts} rollouts; give one per rollout")
        self.num_agents, self.rollouts = num_agents, rollouts
        self.epsilon, self.num_actions = epsilon, num_actions
        self.horizon = int(test_kwargs["horizon"])
        self.layout_seeds = seeds * num_agents
        self.env = make_vector_env(env_id, num_agents * rollouts, test_kwargs, threads)

    def __call__(self, agent: ActionValues, agent_seeds: Sequence[int], step: int) -> EvalResult:
        """Evaluate every agent's current policy; ``step`` seeds the exploration draws."""
        k, r = self.num_agents, self.rollouts
        rngs = [np.random.default_rng(np.random.SeedSequence(s, spawn_key=(EVAL_STREAM, step)))
                for s in agent_seeds]
        obs, _ = self.env.reset(seed=self.layout_seeds)
        live = np.ones(k * r, dtype=bool)
        steps_to_solve = np.full(k * r, -1)
        returns = np.zeros(k * r)
        made = np.zeros(k * r, dtype=bool)
        makes = True  # the environment reports products made (grid tasks)
        max_q = torch.zeros(k)
        counts = np.zeros(k * self.num_actions, dtype=np.int64)
        world_agent = np.repeat(np.arange(k), r) * self.num_actions  # each world's agent, as an offset into counts
        signalled = None
        for t in range(self.horizon):
            if stop_requested():  # finish within a second of a signal (then checkpoint), or give up
                signalled = signalled or time.monotonic()
                if time.monotonic() - signalled > STOP_GRACE_S:
                    raise Interrupted("a signal during a long evaluation")
            actions, greedy = self._actions(agent, obs, rngs, max_q)
            counts += np.bincount(world_agent[live] + greedy[live], minlength=counts.size)
            obs, reward, terminated, truncated, info = self.env.step(actions)
            returns += np.where(live, reward, 0.0)
            solved_now = np.asarray(info.get("solved", np.zeros(k * r, dtype=bool)), dtype=bool)
            makes = makes and "made" in info
            if makes:
                made |= live & (np.asarray(info["made"]) > 0)
            just_solved = live & (steps_to_solve < 0) & solved_now  # -1: not solved before
            steps_to_solve[just_solved] = t + 1
            live &= ~(terminated | truncated)
            if not live.any():
                break
        made_share = made.reshape(k, r).mean(1) if makes else np.full(k, np.nan)
        return EvalResult(returns.reshape(k, r).mean(1), max_q.numpy().astype(np.float64), steps_to_solve.reshape(k, r),
                          counts.reshape(k, self.num_actions), made_share)

    def _actions(self, agent: ActionValues, obs: np.ndarray, rngs: Sequence[np.random.Generator],
                 max_q: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        """Epsilon-greedy and greedy actions of every world (agent k plays worlds k*R ... k*R + R - 1); raises
        each agent's entry of ``max_q`` to the largest |Q| of this step (a non-finite value makes it NaN for good).
        """
        k, r = self.num_agents, self.rollouts
        with torch.no_grad():
            q = agent.q_values(torch.from_numpy(np.asarray(obs, dtype=np.float32)).view(k, r, -1))
            step_max = q.abs().amax(dim=(1, 2))
            max_q.copy_(torch.where(torch.isfinite(step_max) & torch.isfinite(max_q),
                                    torch.maximum(max_q, step_max), torch.full_like(max_q, math.nan)))
            greedy = q.argmax(-1).numpy()
        draws = np.stack([rng.random((r, 2)) for rng in rngs])  # (K, R, [explore?, which action])
        random_actions = (draws[..., 1] * self.num_actions).astype(np.int64)
        return np.where(draws[..., 0] < self.epsilon, random_actions, greedy).reshape(-1), greedy.reshape(-1)

    def close(self) -> None:
        """Release the environment."""
        self.env.close()
