"""Random network distillation (Burda et al., 2018) for K agents, as an intrinsic reward at sampling time.

A fixed, randomly initialised target MLP embeds each observation; a predictor MLP is trained to match it.
The bonus of a transition is the predictor's squared error on its next observation, divided by a running
standard deviation of those errors (per agent), times a weight. It is computed when a batch is sampled,
never written into the replay buffer, so stored rewards stay the environment's own.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from train.agent.dqn import FlatAdam
from train.agent.network import MLP
from train.config import RNDConfig

Tensor = torch.Tensor


class RunningMoments:
    """Per-agent running mean and variance of a stream of batches (Chan et al.'s parallel update)."""

    def __init__(self, num_agents: int, device: str | torch.device = "cpu") -> None:
        self.count = torch.zeros(num_agents, dtype=torch.float64, device=device)
        self.mean = torch.zeros(num_agents, dtype=torch.float64, device=device)
        self.m2 = torch.zeros(num_agents, dtype=torch.float64, device=device)

    def update(self, values: Tensor) -> None:
        """Fold in a batch ``values`` (K, N)."""
        v = values.double()
        n = v.shape[1]
        batch_mean = v.mean(1)
        batch_m2 = (v - batch_mean[:, None]).square().sum(1)
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean += delta * (n / total)
        self.m2 += batch_m2 + delta.square() * (self.count * n / total)
        self.count.copy_(total)  # in place, as every update here: a captured CUDA graph keeps its tensors

    @property
    def std(self) -> Tensor:
        """Per-agent standard deviation (K,), float32."""
        return (self.m2 / self.count.clamp(min=1)).sqrt().float()

    def state_dict(self) -> dict[str, Tensor]:
        """Counts and moments."""
        return {"count": self.count.clone(), "mean": self.mean.clone(), "m2": self.m2.clone()}

    def load_state_dict(self, state: dict[str, Tensor]) -> None:
        """Restore a `state_dict`."""
        for name in ("count", "mean", "m2"):
            getattr(self, name).copy_(state[name])


class RND:
    """Target and predictor networks of K agents, the predictor's optimiser and the error statistics."""

    def __init__(self, obs_dim: int, cfg: RNDConfig, rngs: Sequence[np.random.Generator],
                 device: str | torch.device = "cpu") -> None:
        self.cfg = cfg
        self.net = MLP((obs_dim, *cfg.rnd_layers))
        self.target = torch.from_numpy(np.stack([self.net.init(r, "torch") for r in rngs])).to(device)
        self.predictor = torch.from_numpy(np.stack([self.net.init(r, "torch") for r in rngs])).to(device)
        self.adam = FlatAdam(self.predictor, cfg.rnd_lr)
        self.moments = RunningMoments(len(rngs), device)
        self._target_views = self.net.bind(self.target)
        self._predictor_views = self.net.bind(self.predictor)

    def bonus(self, obs: Tensor) -> Tensor:
        """Weighted, normalised novelty (K, N) of observations (K, N, obs_dim); trains the predictor on them."""
        goal = self.net.forward(self._target_views, obs)[0]
        guess, cache = self.net.forward(self._predictor_views, obs)
        diff = guess - goal
        error = diff.square().mean(-1)
        self.moments.update(error)
        grad = self.net.backward(self._predictor_views, cache, diff * (2.0 / diff[0].numel()))
        self.adam.step(self.predictor, grad)
        return self.cfg.rnd_weight * error / (self.moments.std[:, None] + 1e-8)

    def state_dict(self) -> dict[str, Any]:
        """Networks, optimiser and statistics."""
        return {"target": self.target.clone(), "predictor": self.predictor.clone(),
                "adam": self.adam.state_dict(), "moments": self.moments.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict` in place."""
        self.target.copy_(state["target"])
        self.predictor.copy_(state["predictor"])
        self.adam.load_state_dict(state["adam"])
        self.moments.load_state_dict(state["moments"])
