"""Double DQN for K agents at once: one flat parameter row per agent, batched products throughout.

Every agent (seed) has its own parameters, optimiser moments, gradient clipping and random streams, so an
agent trained beside others follows the same trajectory as when trained alone (up to float rounding).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from train.agent.network import QNetwork
from train.config import DQNConfig

Tensor = torch.Tensor


def double_dqn_target(q_next_online: Tensor, q_next_target: Tensor, reward: Tensor, terminated: Tensor,
                      gamma: float) -> Tensor:
    """The target r + gamma * (1 - terminated) * Q_target(s', argmax_a Q_online(s', a)), elementwise.

    ``terminated`` marks true terminal states only: a time-limit truncation is not one, so its transition
    bootstraps from the next observation like any other.
    """
    best = q_next_online.argmax(-1, keepdim=True)
    next_value = q_next_target.gather(-1, best).squeeze(-1)
    return reward + gamma * (1.0 - terminated) * next_value


def clip_grad_norm_per_agent(grad: Tensor, max_norm: float) -> Tensor:
    """Scale each agent's gradient row (in place) to global norm at most ``max_norm``; return the norms."""
    norms = torch.linalg.vector_norm(grad, dim=1, keepdim=True)
    grad.mul_((max_norm / (norms + 1e-6)).clamp_(max=1.0))
    return norms.squeeze(1)


class FlatAdam:
    """Adam (PyTorch's update rule, no weight decay) on a flat (K, P) parameter buffer.

    Adam acts elementwise, so one buffer holding every agent is the same as one optimiser per agent.
    """

    PER_ROW: bool | None = None
    """Hand the fused kernel one tensor per agent row (True), one (K, P) tensor (False), or per row on the CPU
    only (None, the default: the CPU kernel's scalar tail needs it, the CUDA kernel does not; benchmarks flip it).
    """

    def __init__(self, params: Tensor, lr: float, eps: float = 1e-8, betas: tuple[float, float] = (0.9, 0.999),
                 fused: bool = True):
        self.lr, self.eps, self.betas = lr, eps, betas
        self.exp_avg = torch.zeros_like(params)
        self.exp_avg_sq = torch.zeros_like(params)
        self._step_tensor = torch.zeros((), dtype=torch.float32, device=params.device)
        # PyTorch's fused kernel (what torch.optim.Adam(fused=True) calls) does the whole update in one
        # pass, ~3x faster here than the six elementwise operations below, which remain the fallback.
        self.fused = fused and hasattr(torch, "_fused_adam_")
        self.per_row = params.device.type == "cpu" if self.PER_ROW is None else self.PER_ROW
        self._rows_key: tuple | None = None
        self._rows: list[list[Tensor]] = []

    @property
    def steps(self) -> int:
        """Updates taken so far."""
        return int(self._step_tensor.item())

    def step(self, params: Tensor, grad: Tensor) -> None:
        """Apply one Adam step to ``params`` in place."""
        beta1, beta2 = self.betas
        self._step_tensor += 1
        if self.fused:
            torch._fused_adam_(*self._agent_rows(params, grad), lr=self.lr, beta1=beta1, beta2=beta2,
                               weight_decay=0.0, eps=self.eps, amsgrad=False, maximize=False)
            return
        self.exp_avg.lerp_(grad, 1.0 - beta1)
        self.exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1.0 - beta2)
        steps = self.steps
        bias1 = 1.0 - beta1 ** steps
        bias2_sqrt = (1.0 - beta2 ** steps) ** 0.5
        denom = self.exp_avg_sq.sqrt().div_(bias2_sqrt).add_(self.eps)
        params.addcdiv_(self.exp_avg, denom, value=-self.lr / bias1)

    def _agent_rows(self, params: Tensor, grad: Tensor) -> list[list[Tensor]]:
        """The fused kernel's tensor lists (parameters, gradients, moments, none, step counts), made once per
        pair of buffers (making the K views at each step costs about what the kernel does).

        On the CPU one tensor per agent row, because the CPU kernel ends each tensor with a scalar loop that
        rounds differently from its vector body: on one (K, P) tensor the last agent's last entries would take
        it, so a seed's training would depend on how many seeds share its process (`ecorl run --first-seed`
        parts). The CUDA kernel does the same arithmetic for every element, so there one (K, P) tensor is
        exact and takes one launch instead of one per ~100 rows (a test on CUDA holds the two equal).
        """
        key = (params.data_ptr(), params.shape, params.stride(), grad.data_ptr(), grad.stride())
        if self._rows_key != key:
            tensors = (params, grad, self.exp_avg, self.exp_avg_sq)
            rows = [list(t.unbind(0)) if self.per_row else [t] for t in tensors]
            self._rows_key, self._rows = key, [*rows, [], [self._step_tensor] * len(rows[0])]
        return self._rows

    def state_dict(self) -> dict[str, Any]:
        """The optimiser state (moments and step count)."""
        return {"exp_avg": self.exp_avg.clone(), "exp_avg_sq": self.exp_avg_sq.clone(), "steps": self.steps}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict`."""
        self.exp_avg.copy_(state["exp_avg"])
        self.exp_avg_sq.copy_(state["exp_avg_sq"])
        self._step_tensor.fill_(state["steps"])


class RowGroupAdam:
    """Adam with one learning rate per agent row: one `FlatAdam` per run of equal rates, on views of the rows.

    Rows that share a rate form one contiguous group, so a single-rate buffer takes exactly the path of
    `FlatAdam`; the state is laid out as `FlatAdam`'s (moments (K, P) and one step count).
    """

    def __init__(self, params: Tensor, lrs: Sequence[float], eps: float = 1e-8):
        self.groups: list[tuple[slice, FlatAdam]] = []
        start = 0
        for end in range(1, len(lrs) + 1):
            if end == len(lrs) or lrs[end] != lrs[start]:
                self.groups.append((slice(start, end), FlatAdam(params[start:end], lrs[start], eps)))
                start = end

    @property
    def steps(self) -> int:
        """Updates taken so far."""
        return self.groups[0][1].steps

    def step(self, params: Tensor, grad: Tensor) -> None:
        """Apply one Adam step to every row group of ``params`` in place."""
        for rows, adam in self.groups:
            adam.step(params[rows], grad[rows])

    def state_dict(self) -> dict[str, Any]:
        """The optimiser state, as one `FlatAdam` of all rows would hold it."""
        parts = [adam.state_dict() for _, adam in self.groups]
        return {"exp_avg": torch.cat([p["exp_avg"] for p in parts]),
                "exp_avg_sq": torch.cat([p["exp_avg_sq"] for p in parts]), "steps": parts[0]["steps"]}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict`."""
        for rows, adam in self.groups:
            adam.load_state_dict({"exp_avg": state["exp_avg"][rows], "exp_avg_sq": state["exp_avg_sq"][rows],
                                  "steps": state["steps"]})


class DoubleDQN:
    """Online and target Q-networks of K agents, their optimiser, and the double-DQN gradient step."""

    def __init__(self, net: QNetwork, cfg: DQNConfig, init_rngs: Sequence[np.random.Generator],
                 lrs: Sequence[float] | None = None, device: str | torch.device = "cpu") -> None:
        """``lrs``: a learning rate per agent (default: ``cfg.lr`` for all); ``device``: where the weights,
        the optimiser state and every update live.
        """
        net = net.with_inventory_repeat(cfg.inventory_repeat)  # the configuration decides the input width
        self.net, self.cfg = net, cfg
        rows, target_rows = [], []
        for rng in init_rngs:  # per agent, online then target, so the draws do not depend on K
            rows.append(net.init(rng, cfg.init))
            target_rows.append(rows[-1] if cfg.target_init == "copy" else net.init(rng, cfg.init))
        self.online = torch.from_numpy(np.stack(rows)).to(device)
        self.target = torch.from_numpy(np.stack(target_rows)).to(device)
        self.adam = RowGroupAdam(self.online, list(lrs) if lrs is not None else [cfg.lr] * len(rows), cfg.adam_eps)
        self._online_views = net.bind(self.online)
        self._target_views = net.bind(self.target)

    @property
    def num_agents(self) -> int:
        """K, the number of agents trained together."""
        return self.online.shape[0]

    def q_values(self, obs: Tensor) -> Tensor:
        """Online Q-values (K, N, actions) of observations (K, N, obs_dim)."""
        return self.net.forward(self._online_views, obs)[0]

    def greedy(self, obs: Tensor) -> np.ndarray:
        """Greedy actions (K, N) of observations (K, N, obs_dim)."""
        return self.q_values(obs.to(self.online.device)).argmax(-1).cpu().numpy()

    def update(self, obs_pairs: Tensor, actions: Tensor, rewards: Tensor, terminated: Tensor) -> Tensor:
        """One double-DQN gradient step for every agent; return each agent's TD loss (K,).

        ``obs_pairs`` is (K, 2B, obs_dim): the B observations, then their B next observations;
        ``actions`` (K, B) int64, ``rewards`` and ``terminated`` (K, B) float32.
        """
        batch = actions.shape[1]
        index = self.net.view_index(obs_pairs)  # binary views: the first layer sums weight rows
        q, cache = self.net.forward(self._online_views, obs_pairs, index)
        next_index = None if index is None else index.tail(batch)
        q_next_target = self.net.forward(self._target_views, obs_pairs[:, batch:], next_index)[0]
        target = double_dqn_target(q[:, batch:], q_next_target, rewards, terminated, self.cfg.gamma)
        index = actions.unsqueeze(-1)
        td = q[:, :batch].gather(2, index).squeeze(-1) - target
        grad_q = torch.zeros_like(q[:, :batch]).scatter_(2, index, td.unsqueeze(-1) * (2.0 / batch))
        grad = self.net.backward(self._online_views, cache, grad_q)
        clip_grad_norm_per_agent(grad, self.cfg.grad_clip)
        self.adam.step(self.online, grad)
        self.target.lerp_(self.online, self.cfg.tau)
        return td.square().mean(1)

    @property
    def device(self) -> torch.device:
        """Where the weights live."""
        return self.online.device

    def state_dict(self) -> dict[str, Any]:
        """Networks and optimiser state."""
        return {"online": self.online.clone(), "target": self.target.clone(), "adam": self.adam.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a `state_dict` (in place, so the layer views stay valid)."""
        self.online.copy_(state["online"])
        self.target.copy_(state["target"])
        self.adam.load_state_dict(state["adam"])
